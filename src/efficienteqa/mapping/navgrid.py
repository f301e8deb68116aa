"""Planning on a 2-D free mask: navigability for a disk robot, geodesic distances, paths.

Cells follow ``efficienteqa.mapping.grid``. Planning is 8-connected without corner cutting: a
diagonal step needs both orthogonal neighbours navigable. Connected components use exactly this
connectivity, so "same component" always means "a path exists".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

from efficienteqa.mapping.grid import GridSpec

_EPS = 1e-6  # in cells: tolerance of the conservative segment test
_OFFSETS = ((0, 1), (1, 0), (1, 1), (1, -1))  # the four undirected 8-neighbour directions


@dataclass
class OccupancyGrid:
    """Free floor cells (``free[i, j]``, row along y) and planning on them; radii in metres."""

    spec: GridSpec
    free: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    # ----- masks ---------------------------------------------------------------------------
    def clearance(self) -> np.ndarray:
        """Metres from each cell centre to the nearest occupied cell's edge (grid edge = wall)."""
        if "clearance" not in self._cache:
            edt = ndimage.distance_transform_edt(np.pad(self.free, 1))[1:-1, 1:-1]
            self._cache["clearance"] = np.where(self.free, (edt - 0.5) * self.spec.resolution_m,
                                                0.0)
        return self._cache["clearance"]

    def navigable(self, radius_m: float) -> np.ndarray:
        """Cells where a disk robot of radius_m fits: free with clearance >= radius (memoised)."""
        key = ("nav", round(radius_m, 6))
        if key not in self._cache:
            nav = self.free.copy() if radius_m <= 0 else self.clearance() >= radius_m - 1e-9
            self._cache[key] = nav & self.free
        return self._cache[key]

    def is_navigable(self, x: float, y: float, radius_m: float = 0.2) -> bool:
        """Whether the cell containing (x, y) metres is navigable; False outside the grid."""
        i, j = self.spec.world_to_cell((x, y))
        return bool(self.spec.contains((i, j))) and bool(self.navigable(radius_m)[i, j])

    def area_m2(self) -> float:
        """Free floor area in square metres."""
        return float(self.free.sum()) * self.spec.resolution_m ** 2

    def _graph(self, radius_m: float) -> tuple[csr_matrix, np.ndarray]:
        """Undirected grid graph of navigable cells (weights in metres) and the cell->node map."""
        key = ("graph", round(radius_m, 6))
        if key not in self._cache:
            nav = self.navigable(radius_m)
            node = np.full(nav.shape, -1, dtype=np.int64)
            node[nav] = np.arange(int(nav.sum()))
            h, w = nav.shape
            rows, cols, weights = [], [], []
            for di, dj in _OFFSETS:
                a = np.zeros_like(nav)
                a_src = (slice(0, h - di), slice(max(0, -dj), w - max(0, dj)))
                b_src = (slice(di, h), slice(max(0, dj), w - max(0, -dj)))
                a[a_src] = nav[a_src] & nav[b_src]
                if di and dj:  # no corner cutting: both orthogonal neighbours navigable
                    a[a_src] &= nav[(slice(di, h), a_src[1])] & nav[(a_src[0], b_src[1])]
                ii, jj = np.nonzero(a)
                rows.append(node[ii, jj])
                cols.append(node[ii + di, jj + dj])
                weights.append(np.full(ii.size, math.hypot(di, dj) * self.spec.resolution_m))
            n = int(nav.sum())
            graph = coo_matrix((np.concatenate(weights), (np.concatenate(rows),
                                                          np.concatenate(cols))), shape=(n, n))
            self._cache[key] = (graph.tocsr(), node)
        return self._cache[key]

    def components(self, radius_m: float) -> tuple[np.ndarray, int]:
        """(labels, count): labels 1..count by decreasing size on navigable cells, 0 elsewhere."""
        key = ("comp", round(radius_m, 6))
        if key not in self._cache:
            graph, node = self._graph(radius_m)
            count, lab = connected_components(graph, directed=False)
            labels = np.zeros(node.shape, dtype=np.int64)
            if lab.size:
                rank = np.empty(count, dtype=np.int64)
                rank[np.argsort(-np.bincount(lab, minlength=count), kind="stable")] = np.arange(
                    1, count + 1)
                labels[node >= 0] = rank[lab]
            self._cache[key] = (labels, count if lab.size else 0)
        return self._cache[key]

    def label_at(self, xy: Sequence[float], radius_m: float) -> int:
        """Component label (see ``components``) of the cell containing xy; 0 if not navigable."""
        i, j = self.spec.world_to_cell(xy)
        return int(self.components(radius_m)[0][i, j]) if self.spec.contains((i, j)) else 0

    # ----- distances and paths -------------------------------------------------------------
    def snap(self, xy: Sequence[float], radius_m: float, snap_m: float = 0.5
             ) -> tuple[int, int] | None:
        """The navigable cell holding xy, else the nearest within snap_m metres, else None."""
        nav = self.navigable(radius_m)
        if not nav.any():
            return None
        key = ("near", round(radius_m, 6))
        if key not in self._cache:
            _, idx = ndimage.distance_transform_edt(~nav, return_indices=True)
            self._cache[key] = idx
        ci, cj = self.spec.world_to_cell(xy)
        i, j = int(np.clip(ci, 0, nav.shape[0] - 1)), int(np.clip(cj, 0, nav.shape[1] - 1))
        cell = (int(self._cache[key][0][i, j]), int(self._cache[key][1][i, j]))
        dist = float(np.hypot(*(self.spec.cell_to_world(cell) - np.asarray(xy, dtype=float))))
        return cell if dist <= max(snap_m, self.spec.resolution_m * math.sqrt(0.5)) else None

    def _dijkstra(self, cell: tuple[int, int], radius_m: float) -> tuple[np.ndarray, np.ndarray]:
        key = ("dij", round(radius_m, 6), cell)
        if key not in self._cache:
            graph, node = self._graph(radius_m)
            dist, pred = dijkstra(graph, directed=False, indices=int(node[cell]),
                                  return_predecessors=True)
            if len([k for k in self._cache if k[0] == "dij"]) >= 32:
                self._cache = {k: v for k, v in self._cache.items() if k[0] != "dij"}
            self._cache[key] = (dist, pred)
        return self._cache[key]

    def distance_field(self, start_xy: Sequence[float], radius_m: float,
                       snap_m: float = 0.5) -> np.ndarray:
        """Geodesic metres from start to every cell centre (8-connected, diagonals sqrt(2)*res).

        inf where unreachable or not navigable; all inf if no navigable cell lies within snap_m
        of start. Distances are measured from the centre of start's (snapped) cell.
        """
        field_m = np.full(self.spec.shape, np.inf)
        cell = self.snap(start_xy, radius_m, snap_m)
        if cell is None:
            return field_m
        dist, _ = self._dijkstra(cell, radius_m)
        node = self._graph(radius_m)[1]
        field_m[node >= 0] = dist
        return field_m

    def shortest_path(self, start_xy: Sequence[float], goal_xy: Sequence[float],
                      radius_m: float, snap_m: float = 0.5) -> np.ndarray | None:
        """Collision-free waypoints (K, 2) metres from start to goal, or None if unreachable.

        The grid path is shortened by line of sight on the navigable cells (every segment
        touches navigable cells only). Start and goal are kept exactly when their cells are
        navigable, otherwise replaced by the centres of the snapped cells.
        """
        s_cell = self.snap(start_xy, radius_m, snap_m)
        g_cell = self.snap(goal_xy, radius_m, snap_m)
        if s_cell is None or g_cell is None:
            return None
        dist, pred = self._dijkstra(s_cell, radius_m)
        node = self._graph(radius_m)[1]
        g = int(node[g_cell])
        if not np.isfinite(dist[g]):
            return None
        chain = [g]
        while chain[-1] != node[s_cell]:
            chain.append(int(pred[chain[-1]]))
        ii, jj = np.nonzero(node >= 0)
        order = np.array(chain[::-1])
        pts = self.spec.cell_to_world(np.stack([ii[order], jj[order]], axis=-1))
        if len(pts) == 1:
            pts = np.vstack([pts, pts])
        for k, xy, cell in ((0, start_xy, s_cell), (-1, goal_xy, g_cell)):
            if tuple(int(v) for v in self.spec.world_to_cell(xy)) == cell:
                pts[k] = np.asarray(xy, dtype=float)
        return self._smooth(pts, radius_m)

    def _smooth(self, pts: np.ndarray, radius_m: float) -> np.ndarray:
        """Greedy string pulling: skip waypoints while the segment stays navigable."""
        out, anchor, k = [pts[0]], 0, 1
        while k < len(pts) - 1:
            if self.line_of_sight(pts[anchor], pts[k + 1], radius_m):
                k += 1
            else:
                out.append(pts[k])
                anchor, k = k, k + 1
        out.append(pts[-1])
        return np.array(out)

    def line_of_sight(self, a_xy: Sequence[float], b_xy: Sequence[float],
                      radius_m: float = 0.0) -> bool:
        """Whether every cell the segment a-b (metres) touches, edges included, is navigable.

        radius_m = 0 tests the free cells. Conservative: a segment through a cell corner needs
        all four cells around it.
        """
        mask = self.navigable(radius_m)
        res, o = self.spec.resolution_m, np.asarray(self.spec.origin_xy)
        a = (np.asarray(a_xy, dtype=float) - o) / res
        b = (np.asarray(b_xy, dtype=float) - o) / res
        ts = [np.array([0.0, 1.0])]
        for ax in (0, 1):
            lo, hi = sorted((a[ax], b[ax]))
            if b[ax] != a[ax]:
                ks = np.arange(math.ceil(lo), math.floor(hi) + 1)
                ts.append((ks - a[ax]) / (b[ax] - a[ax]))
        t = np.unique(np.clip(np.concatenate(ts), 0.0, 1.0))
        t = np.concatenate([t, (t[:-1] + t[1:]) / 2])
        p = a + t[:, None] * (b - a)
        d = np.array([[_EPS, _EPS], [_EPS, -_EPS], [-_EPS, _EPS], [-_EPS, -_EPS]])
        c = np.floor(p[None, :, :] + d[:, None, :]).astype(np.int64).reshape(-1, 2)
        j, i = c[:, 0], c[:, 1]
        if not self.spec.contains((i, j)).all():
            return False
        return bool(mask[i, j].all())

    def ray_length(self, xy: Sequence[float], yaws_rad: np.ndarray,
                   max_m: float = 10.0) -> np.ndarray:
        """Metres travelled on free cells from xy along each yaw (sampled every res/2)."""
        res = self.spec.resolution_m
        steps = np.arange(1, int(max_m / (res / 2)) + 1) * (res / 2)
        dirs = np.stack([np.cos(yaws_rad), np.sin(yaws_rad)], axis=-1)
        pts = np.asarray(xy, dtype=float) + dirs[:, None, :] * steps[None, :, None]
        i, j = self.spec.world_to_cell(pts)
        ok = self.spec.contains((i, j))
        ok[ok] = self.free[i[ok], j[ok]]
        first_bad = np.where(ok.all(axis=1), len(steps), np.argmin(ok, axis=1))
        return np.concatenate([[0.0], steps])[first_bad]


def path_length(path: np.ndarray) -> float:
    """Length in metres of a polyline (K, 2)."""
    return float(np.linalg.norm(np.diff(np.asarray(path, dtype=float), axis=0), axis=1).sum())


def truncate_path(path: np.ndarray, max_m: float = 3.0) -> np.ndarray:
    """The point at most max_m metres along the polyline (its end if it is shorter)."""
    p = np.asarray(path, dtype=float)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if cum[-1] <= max_m:
        return p[-1].copy()
    k = int(np.searchsorted(cum, max_m, side="right")) - 1
    return p[k] + (p[k + 1] - p[k]) * ((max_m - cum[k]) / seg[k])
