"""A regular 2-D grid on the floor: the one cell convention of every map in the project.

Canonical frame (see ``efficienteqa.geometry``): x, y on the floor, metres. A grid cell
``(i, j)`` is row ``i`` along **y** and column ``j`` along **x**; ``GridSpec.origin_xy`` is the
world position of the lower-left corner of cell ``(0, 0)``, so cell ``(i, j)`` spans
``[ox + j*res, ox + (j+1)*res) x [oy + i*res, oy + (i+1)*res)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

CellsLike = np.ndarray | Sequence | tuple[np.ndarray, np.ndarray]



@dataclass(frozen=True)
class GridSpec:
    """A regular grid on the floor: origin (m, lower-left corner), cell size (m), (rows, cols)."""

    origin_xy: tuple[float, float]
    resolution_m: float
    shape: tuple[int, int]

    @classmethod
    def covering(cls, x0: float, y0: float, x1: float, y1: float, resolution_m: float = 0.05,
                 margin_m: float = 0.2) -> GridSpec:
        """The grid covering the box [x0, x1] x [y0, y1] (metres) plus a margin on every side."""
        ox, oy = x0 - margin_m, y0 - margin_m
        cols = math.ceil((x1 + margin_m - ox) / resolution_m)
        rows = math.ceil((y1 + margin_m - oy) / resolution_m)
        return cls((ox, oy), resolution_m, (rows, cols))

    def world_to_cell(self, xy: np.ndarray | Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """(i, j) int arrays (row along y, column along x) of points xy (..., 2) in metres."""
        p = np.asarray(xy, dtype=float)
        j = np.floor((p[..., 0] - self.origin_xy[0]) / self.resolution_m).astype(np.int64)
        i = np.floor((p[..., 1] - self.origin_xy[1]) / self.resolution_m).astype(np.int64)
        return i, j

    def cell_to_world(self, ij: CellsLike) -> np.ndarray:
        """World xy (..., 2) in metres of the centres of cells ij: (..., 2) rows of (i, j)."""
        c = _as_ij(ij)
        x = self.origin_xy[0] + (c[..., 1] + 0.5) * self.resolution_m
        y = self.origin_xy[1] + (c[..., 0] + 0.5) * self.resolution_m
        return np.stack([x, y], axis=-1)

    def contains(self, ij: CellsLike) -> np.ndarray:
        """Whether cells ij ((..., 2) rows of (i, j), or an (i, j) tuple) lie inside the grid."""
        c = _as_ij(ij)
        return (c[..., 0] >= 0) & (c[..., 0] < self.shape[0]) & (c[..., 1] >= 0) & (
            c[..., 1] < self.shape[1])

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """(X, Y) arrays of shape ``shape``: world coordinates (m) of every cell centre."""
        xs = self.origin_xy[0] + (np.arange(self.shape[1]) + 0.5) * self.resolution_m
        ys = self.origin_xy[1] + (np.arange(self.shape[0]) + 0.5) * self.resolution_m
        return np.meshgrid(xs, ys)


def _as_ij(ij: CellsLike) -> np.ndarray:
    if isinstance(ij, tuple) and len(ij) == 2:
        return np.stack(np.broadcast_arrays(np.asarray(ij[0]), np.asarray(ij[1])), axis=-1)
    return np.asarray(ij)
