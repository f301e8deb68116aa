"""The semantic value map (DESIGN 3.2-3.3): per-point values SV = LSV * GSV painted on the floor.

Pure numbers in, arrays out; the VLM that produces the confidences lives elsewhere.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy import ndimage

from efficienteqa.mapping.grid import GridSpec


class SemanticValueMap:
    """A per-cell running average of painted semantic values on ``spec`` (rows along y).

    ``paint`` adds each point's value to every cell whose centre lies within ``radius_m`` metres;
    a cell's value is the mean of all values painted on it (0 where never painted).
    """

    def __init__(self, spec: GridSpec, radius_m: float = 1.0, sigma_cells: float = 5.0) -> None:
        self.spec = spec
        self.radius_m = radius_m
        self.sigma_cells = sigma_cells
        self._sum = np.zeros(spec.shape)
        self._count = np.zeros(spec.shape, dtype=np.int64)
        self._smoothed: np.ndarray | None = None

    def paint(self, points_xy: np.ndarray | Sequence[Sequence[float]],
              values: np.ndarray | Sequence[float]) -> None:
        """Paint value k on the disk of radius ``radius_m`` around point k (world xy, metres)."""
        pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        vals = np.asarray(values, dtype=float).reshape(-1)
        if len(pts) != len(vals):
            raise ValueError(f"{len(pts)} points but {len(vals)} values")
        res, (ox, oy) = self.spec.resolution_m, self.spec.origin_xy
        rows, cols = self.spec.shape
        reach = int(math.ceil(self.radius_m / res)) + 1
        for (x, y), value in zip(pts, vals):
            ci, cj = self.spec.world_to_cell((x, y))
            i0, i1 = max(int(ci) - reach, 0), min(int(ci) + reach + 1, rows)
            j0, j1 = max(int(cj) - reach, 0), min(int(cj) + reach + 1, cols)
            if i0 >= i1 or j0 >= j1:
                continue  # the disk misses the grid
            cy = oy + (np.arange(i0, i1) + 0.5) * res
            cx = ox + (np.arange(j0, j1) + 0.5) * res
            disk = (cy[:, None] - y) ** 2 + (cx[None, :] - x) ** 2 <= self.radius_m ** 2 + 1e-12
            self._sum[i0:i1, j0:j1][disk] += value
            self._count[i0:i1, j0:j1][disk] += 1
        self._smoothed = None

    @property
    def count(self) -> np.ndarray:
        """How many values each cell has received."""
        return self._count.copy()

    @property
    def raw(self) -> np.ndarray:
        """The averaged map (0 where never painted)."""
        return np.divide(self._sum, self._count, out=np.zeros(self.spec.shape),
                         where=self._count > 0)

    def smoothed(self) -> np.ndarray:
        """``raw`` smoothed by a Gaussian of ``sigma_cells`` cells (memoised until next paint).

        Borders reflect, so smoothing keeps the map's total value.
        """
        if self._smoothed is None:
            self._smoothed = ndimage.gaussian_filter(self.raw, self.sigma_cells, mode="reflect")
        return self._smoothed.copy()


def lsv_from_confidences(per_letter: Mapping[str, float], letters: Sequence[str],
                         max_points: int = 3) -> dict[str, float]:
    """Local semantic values of the prompted ``letters`` (DESIGN 3.3).

    Confidences of the prompted letters are normalised to sum to 1 (missing, negative or
    non-finite ones count as 0; all zero -> uniform), then scaled by len(letters) / max_points
    so that fewer prompted points carry less total value.
    """
    if not letters:
        return {}
    raw = [float(per_letter.get(k, 0.0)) for k in letters]
    conf = np.array([c if math.isfinite(c) and c > 0 else 0.0 for c in raw])
    total = conf.sum()
    share = conf / total if total > 0 else np.full(len(letters), 1.0 / len(letters))
    scale = len(letters) / max_points
    return {k: float(s * scale) for k, s in zip(letters, share)}


def gsv_from_yes(p_yes: float, temperature: float = 0.5) -> float:
    """Global semantic value ``exp(P_yes / temperature) / 3`` (DESIGN 3.3); P_yes clamped to
    [0, 1] (NaN counts as 0)."""
    p = 0.0 if math.isnan(p_yes) else min(max(p_yes, 0.0), 1.0)
    return math.exp(p / temperature) / 3.0
