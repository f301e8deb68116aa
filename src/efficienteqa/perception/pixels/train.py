"""Fit the pixel network on rendered frames (``dataset``) and write its weights.

Training houses are every house of the data folder outside VALIDATION_SEEDS; validation houses
those inside it (scored once, at the end, on whole frames). Each step draws ``batch`` random
crops (half of them centred on a small object, so that cups and lamps are not drowned by
walls), flips half of them left-right, and minimises cross-entropy on the category (class
weights 1/sqrt(frequency), capped), colour and state maps, with AdamW on a one-cycle schedule of
a fixed number of steps: the command states the steps, so the result is reproducible from it
(``minutes`` only guards against a slow machine and is recorded when it cuts training short).
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from efficienteqa.envs.synthetic.vocabulary import SMALL_CATEGORIES
from efficienteqa.errors import EfficientEQAError
from efficienteqa.perception.pixels.dataset import VALIDATION_SEEDS, code_version, load_shards
from efficienteqa.perception.pixels.net import (
    DEFAULT_WIDTHS,
    IGNORE,
    VOID,
    WALL,
    PixelNet,
    Vocabulary,
    save_weights,
    to_input,
)
from efficienteqa.perception.pixels.segment import FLOOR_PREFIX

MAX_CLASS_WEIGHT = 10.0  # category weights are 1/sqrt(frequency), mean pixel weight 1, capped
SMALL_SHARE = 0.5  # share of crops centred on a small object
STATE_LOSS_WEIGHT = 0.5
THREADS = 2  # the machine's cores; 1 does better when others load them


@dataclass(frozen=True)
class TrainConfig:
    steps: int = 4000
    seed: int = 0
    batch: int = 8
    crop: tuple[int, int] = (128, 160)  # (height, width) at the network's (half) resolution
    lr: float = 4e-3
    weight_decay: float = 1e-4
    widths: tuple[int, ...] = DEFAULT_WIDTHS
    minutes: float = 90.0
    threads: int = THREADS


def check_data(data: Path) -> dict[str, Any]:
    """The data folder's metadata; one-line errors for a missing or empty folder."""
    data = Path(data)
    fix = "render frames first: efficienteqa perception dataset --seeds 3000-3199 --out DIR"
    meta_path = data / "meta.json"
    if not data.is_dir():
        raise EfficientEQAError(f"no data folder {data}", fix=fix)
    if not meta_path.is_file() or not any(data.glob("houses-*.npz")):
        raise EfficientEQAError(f"{data} holds no rendered frames (meta.json and houses-*.npz)",
                                fix=fix)
    try:
        meta: dict[str, Any] = json.loads(meta_path.read_text())
        Vocabulary.from_json(meta["vocabulary"])
    except (ValueError, KeyError, TypeError) as exc:
        raise EfficientEQAError(f"unreadable {meta_path}: {exc}", fix=fix) from None
    if not [h for h in meta.get("houses", []) if h not in VALIDATION_SEEDS]:
        raise EfficientEQAError(f"{data} holds validation houses only", fix=fix)
    return meta


def check_writable(out: Path) -> None:
    """A one-line error when ``out`` (a file to be) cannot be written."""
    out = Path(out)
    parent = out.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if out.is_dir() or not os.access(parent, os.W_OK) or (out.exists() and not os.access(out, os.W_OK)):
        raise EfficientEQAError(f"cannot write the weights to {out}",
                                fix="give a writable file path ending in .pt")


def class_weights(category: np.ndarray, n: int) -> torch.Tensor:
    """1/sqrt(frequency) per category, scaled to a mean pixel weight of 1, capped."""
    counts = np.bincount(category[category != IGNORE].ravel(), minlength=n)[:n].astype(np.float64)
    freq = counts / max(counts.sum(), 1.0)
    w = np.where(counts > 0, 1.0 / np.sqrt(np.maximum(freq, 1e-12)), 0.0)
    w /= max(float((freq * w).sum()), 1e-12)
    w = np.minimum(w, MAX_CLASS_WEIGHT)
    w[counts == 0] = MAX_CLASS_WEIGHT
    return torch.tensor(w, dtype=torch.float32)


class CropSampler:
    """Random crops of the training frames; a share centred on small-object pixels."""

    def __init__(self, frames: dict[str, np.ndarray], vocab: Vocabulary, crop: tuple[int, int],
                 rng: np.random.Generator) -> None:
        self.f, self.crop, self.rng = frames, crop, rng
        n, h, w = frames["category"].shape
        if crop[0] > h or crop[1] > w:
            raise EfficientEQAError(f"crop {crop} is larger than the frames ({h}x{w})")
        small = np.array([vocab.index(c) for c in sorted(SMALL_CATEGORIES)
                          if vocab.index(c) is not None], np.uint8)
        self.small_pixels: list[np.ndarray] = []  # per frame: (k, 2) small-object pixels
        for i in range(n):
            ys, xs = np.nonzero(np.isin(frames["category"][i, ::2, ::2], small))
            self.small_pixels.append(np.stack([ys * 2, xs * 2], 1))
        self.small_frames = np.array([i for i, p in enumerate(self.small_pixels) if len(p)], int)

    def batch(self, size: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        ch, cw = self.crop
        n, h, w = self.f["category"].shape
        rgb: list[np.ndarray] = []
        depth: list[np.ndarray] = []
        cat: list[np.ndarray] = []
        col: list[np.ndarray] = []
        st: list[np.ndarray] = []
        for _ in range(size):
            if len(self.small_frames) and self.rng.random() < SMALL_SHARE:
                i = int(self.small_frames[self.rng.integers(len(self.small_frames))])
                py, px = self.small_pixels[i][self.rng.integers(len(self.small_pixels[i]))]
                y0 = int(np.clip(py - ch // 2 + self.rng.integers(-ch // 4, ch // 4 + 1), 0, h - ch))
                x0 = int(np.clip(px - cw // 2 + self.rng.integers(-cw // 4, cw // 4 + 1), 0, w - cw))
            else:
                i = int(self.rng.integers(n))
                y0, x0 = int(self.rng.integers(h - ch + 1)), int(self.rng.integers(w - cw + 1))
            sl = (i, slice(y0, y0 + ch), slice(x0, x0 + cw))
            flip = self.rng.random() < 0.5
            for store, key in ((rgb, "rgb"), (depth, "depth"), (cat, "category"),
                               (col, "colour"), (st, "state")):
                a = self.f[key][sl]
                store.append(a[:, ::-1] if flip else a)
        x = to_input(np.stack(rgb), np.stack(depth).astype(np.float32))
        labels = [torch.from_numpy(np.stack(v).astype(np.int64)) for v in (cat, col, st)]
        return x, labels[0], labels[1], labels[2]


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


def evaluate(net: PixelNet, frames: dict[str, np.ndarray], vocab: Vocabulary,
             batch: int = 4) -> dict[str, Any]:
    """Whole-frame figures: pixel accuracy, mean IoU over the categories present, colour and
    state accuracy on object pixels, the floor's room type, and recall of small objects and of
    other objects (the category of each labelled object pixel)."""
    n_cat = len(vocab.categories)
    confusion = np.zeros((n_cat, n_cat), np.int64)
    col_ok = col_n = st_ok = st_n = 0
    net.eval()
    with torch.inference_mode():
        for s in range(0, len(frames["category"]), batch):
            x = to_input(frames["rgb"][s:s + batch], frames["depth"][s:s + batch].astype(np.float32))
            cat_l, col_l, st_l = net(x)
            pred = cat_l.argmax(1).numpy()
            truth = frames["category"][s:s + batch]
            keep = truth != IGNORE
            confusion += np.bincount(truth[keep].astype(np.int64) * n_cat + pred[keep],
                                     minlength=n_cat * n_cat).reshape(n_cat, n_cat)
            col_t, st_t = frames["colour"][s:s + batch], frames["state"][s:s + batch]
            col_ok += int((col_l.argmax(1).numpy() == col_t)[col_t != IGNORE].sum())
            col_n += int((col_t != IGNORE).sum())
            st_ok += int((st_l.argmax(1).numpy() == st_t)[st_t != IGNORE].sum())
            st_n += int((st_t != IGNORE).sum())
    net.train()
    tp = np.diag(confusion).astype(np.float64)
    truth_n, pred_n = confusion.sum(1), confusion.sum(0)
    present = truth_n > 0
    iou = tp[present] / (truth_n[present] + pred_n[present] - tp[present])

    def recall(indices: Sequence[int]) -> float | None:
        idx = [i for i in indices if truth_n[i] > 0]
        return round(float(tp[idx].sum() / truth_n[idx].sum()), 4) if idx else None

    floors = [i for i, c in enumerate(vocab.categories) if c.startswith(FLOOR_PREFIX)]
    small = {vocab.index(c) for c in SMALL_CATEGORIES} - {None}
    objects = range(floors[-1] + 1, n_cat)  # doors and objects
    return {
        "frames": int(len(frames["category"])),
        "pixel_accuracy": round(float(tp.sum() / max(confusion.sum(), 1)), 4),
        "mean_iou": round(float(iou.mean()), 4) if len(iou) else None,
        "categories_present": int(present.sum()),
        "floor_room_type_accuracy": recall(floors),
        "small_object_pixel_recall": recall([i for i in objects if i in small]),
        "other_object_pixel_recall": recall([i for i in objects if i not in small]),
        "structure_accuracy": recall([VOID, WALL]),
        "colour_accuracy": round(col_ok / col_n, 4) if col_n else None,
        "state_accuracy": round(st_ok / st_n, 4) if st_n else None,
        "iou_per_category": {vocab.categories[i]: round(float(v), 4)
                             for i, v in zip(np.nonzero(present)[0].tolist(), iou.tolist())},
    }


def train(data: Path, out: Path, config: TrainConfig = TrainConfig(), command: str = "",
          log: Any = sys.stderr) -> dict[str, Any]:
    """Train on ``data``, evaluate on its validation houses, write ``out`` (+ .json); returns
    the metadata written."""
    meta = check_data(data)
    check_writable(out)
    torch.manual_seed(config.seed)
    torch.set_num_threads(config.threads)
    torch.use_deterministic_algorithms(True, warn_only=True)
    rng = np.random.default_rng(config.seed)
    vocab = Vocabulary.from_json(meta["vocabulary"])
    houses = sorted(meta["houses"])
    train_houses = [h for h in houses if h not in VALIDATION_SEEDS]
    val_houses = [h for h in houses if h in VALIDATION_SEEDS]
    frames = load_shards(data, train_houses)
    if not frames:
        raise EfficientEQAError(f"{data} holds no frames of its training houses")
    sampler = CropSampler(frames, vocab, config.crop, rng)
    weights = class_weights(frames["category"], len(vocab.categories))
    net = PixelNet(vocab, config.widths)
    net.train()
    opt = torch.optim.AdamW(net.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=config.lr, total_steps=config.steps,
                                                pct_start=0.1)
    start = time.perf_counter()
    every = max(1, min(50, config.steps // 20))
    running: dict[str, float] = {}
    history: list[dict[str, float]] = []
    done = 0
    for step in range(config.steps):
        if (time.perf_counter() - start) / 60 > config.minutes:
            print(f"stopping at step {step}: --minutes {config.minutes} reached", file=log,
                  flush=True)
            break
        x, cat, col, st = sampler.batch(config.batch)
        loss, parts = losses(net, x, cat, col, st, weights)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        done = step + 1
        for k, v in {"loss": float(loss.detach()), **parts}.items():
            running[k] = running.get(k, 0.0) + v
        if done % every == 0 or done == config.steps:
            avg = {k: v / every for k, v in running.items()}
            running = {}
            history.append({"step": done, **{k: round(v, 4) for k, v in avg.items()}})
            elapsed = time.perf_counter() - start
            rate = done / elapsed
            print(f"step {done}/{config.steps} loss {avg['loss']:.3f} (category "
                  f"{avg['category']:.3f}, colour {avg['colour']:.3f}, state {avg['state']:.3f}) "
                  f"{rate:.2f} steps/s, {elapsed / 60:.1f} min, eta "
                  f"{(config.steps - done) / max(rate, 1e-9) / 60:.1f} min", file=log, flush=True)
    minutes = (time.perf_counter() - start) / 60
    del sampler, frames
    validation: dict[str, Any] | None = None
    if val_houses:
        val = load_shards(data, val_houses)
        validation = evaluate(net, val, vocab)
        brief = {k: v for k, v in validation.items() if k != "iou_per_category"}
        print(f"validation: {json.dumps(brief)}", file=log, flush=True)
    record = {
        "command": command, "seed": config.seed, "steps": config.steps, "steps_done": done,
        "batch": config.batch, "crop": list(config.crop), "lr": config.lr,
        "weight_decay": config.weight_decay, "minutes": round(minutes, 2),
        "minutes_guard": config.minutes, "threads": config.threads, "torch": torch.__version__,
        "code_version": code_version(),
        "data": {"houses": [houses[0], houses[-1]] if houses else [],
                 "train_houses": len(train_houses), "validation_houses": val_houses,
                 "frames_per_house": meta.get("frames_per_house"),
                 "render_seed": meta.get("seed"), "assets": meta.get("assets"),
                 "train_seed_range": meta.get("train_seeds"),
                 "validation_seed_range": meta.get("validation_seeds")},
        "validation": validation, "loss_history": history[-5:],
        "final_loss": history[-1]["loss"] if history else math.nan,
    }
    save_weights(out, net, vocab, record)
    return record
