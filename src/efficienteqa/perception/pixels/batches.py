"""What one training step of the pixel network sees and is scored on: crops, class weights, loss.

Each step draws ``batch`` crops: RARITY_SHARE of them centred on a pixel of a category drawn
uniformly among the categories present (inverse pixel frequency: sinks and cups as often as
walls), the rest anywhere; crops are large (``train.CROP``, two thirds of a half-size frame) so
the context branch sees a room as it does at inference. Half are flipped left-right. The loss is
cross-entropy on the category (class weights 1/sqrt(frequency in the crops drawn), capped),
colour and state maps.

Kept apart from the training loop (``train``): experiments time a step without the training.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from efficienteqa.errors import EfficientEQAError
from efficienteqa.perception.pixels.net import IGNORE, PixelNet, Vocabulary, to_input

MAX_CLASS_WEIGHT = 10.0  # category weights are 1/sqrt(frequency), mean pixel weight 1, capped
# Share of crops centred by rarity; the rest keep the frames' own statistics (walls are 55% of
# pixels). Three quarters: chosen, not tuned.
RARITY_SHARE = 0.75
RARITY_STRIDE = 4  # candidate centres: every 4th pixel of each axis (memory; crops are large)
WEIGHT_CROPS = 512  # crops drawn (then put back) to measure the category frequency the loss sees
STATE_LOSS_WEIGHT = 0.5


def class_weights(category: np.ndarray, n: int) -> torch.Tensor:
    """1/sqrt(frequency) per category, scaled to a mean pixel weight of 1, capped."""
    return weights_of_counts(np.bincount(category[category != IGNORE].ravel(), minlength=n)[:n])


def weights_of_counts(counts_in: np.ndarray) -> torch.Tensor:
    """``class_weights`` of per-category pixel counts."""
    counts = np.asarray(counts_in, np.float64)
    freq = counts / max(counts.sum(), 1.0)
    w = np.where(counts > 0, 1.0 / np.sqrt(np.maximum(freq, 1e-12)), 0.0)
    w /= max(float((freq * w).sum()), 1e-12)
    w = np.minimum(w, MAX_CLASS_WEIGHT)
    w[counts == 0] = MAX_CLASS_WEIGHT
    return torch.tensor(w, dtype=torch.float32)


class CropSampler:
    """Crops of the training frames: RARITY_SHARE centred on a pixel of a category drawn
    uniformly among those present, the rest anywhere. ``rng`` holds all its randomness."""

    def __init__(self, frames: dict[str, np.ndarray], vocab: Vocabulary, crop: tuple[int, int],
                 rng: np.random.Generator, rarity_share: float = RARITY_SHARE) -> None:
        self.f, self.crop, self.rng, self.rarity_share = frames, crop, rng, rarity_share
        n, h, w = frames["category"].shape
        if crop[0] > h or crop[1] > w:
            raise EfficientEQAError(f"crop {crop} is larger than the frames ({h}x{w})")
        # candidate centres per category, as flat indices into the strided category array
        k = RARITY_STRIDE
        strided = frames["category"][:, k // 2::k, k // 2::k]
        self._grid = strided.shape[1:]
        flat = strided.reshape(-1)
        order = np.argsort(flat, kind="stable")
        counts = np.bincount(flat, minlength=256)
        bounds = np.concatenate([[0], np.cumsum(counts)])
        self.centres = {c: order[bounds[c]:bounds[c + 1]] for c in range(len(vocab.categories))
                        if counts[c] > 0}
        self.classes = np.array(sorted(self.centres), int)

    def _origin(self) -> tuple[int, int, int]:
        ch, cw = self.crop
        n, h, w = self.f["category"].shape
        if len(self.classes) and self.rng.random() < self.rarity_share:
            c = int(self.classes[self.rng.integers(len(self.classes))])
            flat = int(self.centres[c][self.rng.integers(len(self.centres[c]))])
            gh, gw = self._grid
            i, rest = divmod(flat, gh * gw)
            k = RARITY_STRIDE
            py, px = (rest // gw) * k + k // 2, (rest % gw) * k + k // 2
            y0 = int(np.clip(py - ch // 2 + self.rng.integers(-ch // 4, ch // 4 + 1), 0, h - ch))
            x0 = int(np.clip(px - cw // 2 + self.rng.integers(-cw // 4, cw // 4 + 1), 0, w - cw))
            return i, y0, x0
        i = int(self.rng.integers(n))
        return i, int(self.rng.integers(h - ch + 1)), int(self.rng.integers(w - cw + 1))

    def batch(self, size: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        ch, cw = self.crop
        rgb: list[np.ndarray] = []
        depth: list[np.ndarray] = []
        cat: list[np.ndarray] = []
        col: list[np.ndarray] = []
        st: list[np.ndarray] = []
        for _ in range(size):
            i, y0, x0 = self._origin()
            sl = (i, slice(y0, y0 + ch), slice(x0, x0 + cw))
            flip = self.rng.random() < 0.5
            for store, key in ((rgb, "rgb"), (depth, "depth"), (cat, "category"),
                               (col, "colour"), (st, "state")):
                a = self.f[key][sl]
                store.append(a[:, ::-1] if flip else a)
        x = to_input(np.stack(rgb), np.stack(depth).astype(np.float32))
        labels = [torch.from_numpy(np.stack(v).astype(np.int64)) for v in (cat, col, st)]
        return x, labels[0], labels[1], labels[2]

    def crop_counts(self, crops: int, n: int) -> np.ndarray:
        """Category pixel counts of ``crops`` crops drawn as training draws them, with a copy of
        the generator (the training draws are not disturbed)."""
        saved = self.rng.bit_generator.state
        ch, cw = self.crop
        counts = np.zeros(n, np.int64)
        for _ in range(crops):
            i, y0, x0 = self._origin()
            labels = self.f["category"][i, y0:y0 + ch:2, x0:x0 + cw:2]
            counts += np.bincount(labels[labels != IGNORE].ravel(), minlength=n)[:n]
        self.rng.bit_generator.state = saved
        return counts


def losses(net: PixelNet, x: torch.Tensor, cat: torch.Tensor, col: torch.Tensor,
           state: torch.Tensor, weights: torch.Tensor) -> tuple[torch.Tensor, dict[str, float]]:
    # the loss is taken at the heads' own (half) resolution, on every other label pixel: the
    # full-size category logits would be the largest tensor of the step by far
    cat_logits, col_logits, state_logits = net.half_logits(x)
    h, w = cat_logits.shape[-2:]
    cat, col, state = (t[:, ::2, ::2][:, :h, :w] for t in (cat, col, state))
    parts = {
        "category": F.cross_entropy(cat_logits, cat, weight=weights, ignore_index=IGNORE),
        "colour": _masked_ce(col_logits, col),
        "state": _masked_ce(state_logits, state),
    }
    total = parts["category"] + parts["colour"] + STATE_LOSS_WEIGHT * parts["state"]
    return total, {k: float(v.detach()) for k, v in parts.items()}


def _masked_ce(logits: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    if not bool((target != IGNORE).any()):
        return logits.sum() * 0.0
    return F.cross_entropy(logits, target, ignore_index=IGNORE)

