"""Objects fused over the views of an episode (DESIGN 9, learned perception).

One frame's region may be too unsure to describe (its confidence under its category's
threshold) although the same place was seen as the same category from other poses. The pixel
perception therefore keeps, for an episode, per map cell of FUSION_CELL_M (in 3-D: a cup on a
table is not the table) and per category, the evidence of the views that saw it: each view adds
its best region confidence there once. A region of the current frame whose cells hold, on
average, at least FUSED_MIN of evidence of its category is described even when the frame alone
would drop it: an object seen uncertainly in three views counts once, sure. The frame still has
to show it, so what the describer lists is always in view. Pure numpy.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

FUSION_CELL_M = 0.25  # about the size of the smallest objects the network names
FUSED_MIN = 1.2  # summed view confidences a place needs (chosen on validation walks, see DESIGN)
_OFFSET = 1 << 15  # keeps cell indices non-negative for the packed key


def cell_keys(points_xyz: np.ndarray, category: int) -> np.ndarray:
    """Packed (cell, category) keys of world points (N, 3), unique."""
    cells = np.floor(points_xyz / FUSION_CELL_M).astype(np.int64) + _OFFSET
    keys = (((cells[:, 0] << 16) | cells[:, 1]) << 16 | cells[:, 2]) << 8 | int(category)
    return np.unique(keys)


class ObjectEvidence:
    """Per (cell, category): the summed best confidence of every view that saw it there."""

    def __init__(self) -> None:
        self._total: dict[int, float] = {}

    def __len__(self) -> int:
        return len(self._total)

    def add_view(self, regions: Sequence[tuple[np.ndarray, float]]) -> None:
        """One view's regions as (cell keys, confidence); a place counts once per view."""
        best: dict[int, float] = {}
        for keys, sure in regions:
            for k in keys.tolist():
                if sure > best.get(k, 0.0):
                    best[k] = sure
        for k, sure in best.items():
            self._total[k] = self._total.get(k, 0.0) + sure

    def support(self, keys: np.ndarray) -> float:
        """Mean evidence over a region's cells (0 for none)."""
        if not len(keys):
            return 0.0
        return float(np.mean([self._total.get(k, 0.0) for k in keys.tolist()]))
