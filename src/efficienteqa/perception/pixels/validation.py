"""Whole-frame figures of the pixel network on the validation houses' frames.

Scored once, at the end of training, and written into the weights' record. Kept apart from the
training loop (``train``): it reads frames and a network only, not the training's state.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from efficienteqa.envs.synthetic.vocabulary import SMALL_CATEGORIES
from efficienteqa.perception.pixels.net import IGNORE, VOID, WALL, PixelNet, Vocabulary, to_input
from efficienteqa.perception.pixels.segment import FLOOR_PREFIX


def evaluate(net: PixelNet, frames: dict[str, np.ndarray], vocab: Vocabulary,
             batch: int = 4, device: torch.device | None = None) -> dict[str, Any]:
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
            cat_t, col_t_l, st_t_l = net(x.to(device or "cpu"))
            cat_l, col_l, st_l = cat_t.cpu(), col_t_l.cpu(), st_t_l.cpu()
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

