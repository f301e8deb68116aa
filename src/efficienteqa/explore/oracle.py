"""Ground-truth semantic values, for benchmarks that isolate exploration from the model.

LSV = 1 on the prompted point closest (by path) to the question's evidence, 0 on the others.
P(worth exploring) answers the GSV question "is any direction in this view worth exploring?":
1 when the evidence is in view or a prompted direction leads at least ``gain_m`` closer to it
(by path) than the robot stands, else 0. What a perfect scorer could give SFE; never used to
answer questions.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from efficienteqa.explore.module import SemanticScore
from efficienteqa.mapping.navgrid import OccupancyGrid
from efficienteqa.observation import Observation, PromptPoint

UNREACHABLE = "no prompted point leads to a view of the evidence reachable from the start"


class OracleScorer:
    """``distance_m(xy)`` is the path distance from a floor point to the evidence (inf when
    unreachable); ``visible(instance)`` says whether the evidence is in view in a frame.

    When no prompted point has a finite distance (the evidence has no view reachable from the
    start, or every point lies off the reachable floor), the scorer knows nothing: the letters
    share the confidence equally and ``info["unreachable"]`` says why. Ties share the best
    letter's confidence; the first letter never wins by default.
    """

    def __init__(self, distance_m: Callable[[Sequence[float]], float],
                 visible: Callable[[np.ndarray], bool], gain_m: float = 1.0) -> None:
        self.distance_m, self.visible, self.gain_m = distance_m, visible, gain_m

    def score(self, obs: Observation, prompts: list[PromptPoint], question: str) -> SemanticScore:
        distances = np.array([self.distance_m(p.xy) for p in prompts], float)
        in_view = obs.instance is not None and self.visible(obs.instance)
        info: dict = {"distances_m": distances.tolist()}
        if not np.isfinite(distances).any():
            info["unreachable"] = UNREACHABLE
            share = 1.0 / len(prompts) if prompts else 0.0
            return SemanticScore({p.letter: share for p in prompts}, 1.0 if in_view else 0.0, info)
        best = distances == distances.min()
        letters = {p.letter: float(b) / int(best.sum()) for p, b in zip(prompts, best)}
        closer = distances.min() < self.distance_m((obs.pose.x, obs.pose.y)) - self.gain_m
        return SemanticScore(letters, 1.0 if in_view or closer else 0.0, info)


class EvidenceDistance:
    """Path metres from any floor point to the evidence, read off ``evidence_distance_field``.

    A point off the navigable floor (a prompt point free on the robot's map may not be
    navigable on the true grid: next to furniture, in a doorway) is measured from the nearest
    navigable cell, within ``snap_m``, plus the straight line to it; farther from every
    navigable cell it is unreachable (inf). ``reachable`` is False when no cell reaches the
    evidence: the question has no view reachable from the start.
    """

    def __init__(self, grid: OccupancyGrid, field_m: np.ndarray, radius_m: float,
                 snap_m: float = 0.75) -> None:
        self.spec, self.field_m, self.snap_m = grid.spec, field_m, snap_m
        nav = grid.navigable(radius_m)
        self._nearest = ndimage.distance_transform_edt(~nav, return_indices=True)[1] if nav.any() \
            else None

    @property
    def reachable(self) -> bool:
        return bool(np.isfinite(self.field_m).any())

    def __call__(self, xy: Sequence[float]) -> float:
        if self._nearest is None:
            return math.inf
        p = np.asarray(xy, dtype=float)[:2]
        ci, cj = self.spec.world_to_cell(p)
        i = int(np.clip(ci, 0, self.spec.shape[0] - 1))
        j = int(np.clip(cj, 0, self.spec.shape[1] - 1))
        cell = (int(self._nearest[0][i, j]), int(self._nearest[1][i, j]))
        if cell == (int(ci), int(cj)):  # on a navigable cell
            return float(self.field_m[cell])
        gap = float(np.hypot(*(self.spec.cell_to_world(cell) - p)))
        return float(self.field_m[cell]) + gap if gap <= self.snap_m else math.inf


def evidence_distance_field(grid: OccupancyGrid, centre_xy: Sequence[float], radius_m: float,
                            rooms: Sequence[tuple[float, float, float, float]] = (),
                            reach_m: float = 2.0, start_xy: Sequence[float] | None = None,
                            views: Sequence[Sequence[float]] = ()) -> np.ndarray:
    """Path metres from every cell centre to the evidence at ``centre_xy`` (inf: unreachable).

    The walk ends at an *evidence view* and goes straight on from there: the distance is the
    least (path to a view + straight line from it to the centre). Views are the navigable cells
    within ``reach_m`` of the evidence *inside one of its rooms* (x0, y0, x1, y1), and the
    positions ``views`` (x, y) from which the evidence is known to be seen (the oracle's pose).
    Snapping to the nearest navigable cell instead crosses walls: a TV on a bedroom wall was
    "0.5 m away" from the hallway behind that wall, and the oracle steered the robot there.
    Without rooms, or when no navigable cell of the rooms lies within ``reach_m``, any
    navigable cell within ``reach_m`` is a view.

    With ``start_xy``, only views reachable from the start count: a wardrobe whose nearby floor
    is a closed pocket is reached through a known view or not at all, and the field is inf
    everywhere when it has no reachable view (``EvidenceDistance.reachable``).
    """
    spec = grid.spec
    nav = grid.navigable(radius_m)
    xs, ys = spec.centres()
    cx, cy = float(centre_xy[0]), float(centre_xy[1])
    gap = np.hypot(xs - cx, ys - cy)
    near = nav & (gap <= reach_m)
    inside = np.zeros_like(near)
    for x0, y0, x1, y1 in rooms:
        inside |= (xs >= x0) & (xs <= x1) & (ys >= y0) & (ys <= y1)
    seeds = (near & inside) if (near & inside).any() else near.copy()
    for vx, vy in ((float(v[0]), float(v[1])) for v in views):
        vi, vj = spec.world_to_cell((vx, vy))
        if spec.contains((vi, vj)) and nav[vi, vj]:
            seeds[vi, vj] = True
    if start_xy is not None:
        seeds &= np.isfinite(grid.distance_field(start_xy, radius_m))
    field_m = np.full(spec.shape, np.inf)
    if not seeds.any():
        return field_m
    graph, node = grid._graph(radius_m)
    n = graph.shape[0]
    si, sj = np.nonzero(seeds)
    # One extra node (the evidence) joined to every seed by the straight-line remainder.
    extra = coo_matrix((gap[si, sj] + 1e-9, (np.full(len(si), n), node[si, sj])),
                       shape=(n + 1, n + 1))
    g = graph.tocoo()
    full = coo_matrix((np.concatenate([g.data, extra.data]),
                       (np.concatenate([g.row, extra.row]), np.concatenate([g.col, extra.col]))),
                      shape=(n + 1, n + 1)).tocsr()
    dist = dijkstra(full, directed=False, indices=n)
    field_m[node >= 0] = dist[node[node >= 0]]
    return field_m
