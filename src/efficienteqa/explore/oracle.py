"""Ground-truth semantic values, for benchmarks that isolate exploration from the model.

LSV = 1 on the prompted point closest (by path) to the question's evidence, 0 on the others.
P(worth exploring) answers the GSV question "is any direction in this view worth exploring?":
1 when the evidence is in view or a prompted direction leads at least ``gain_m`` closer to it
(by path) than the robot stands, else 0. What a perfect scorer could give SFE; never used to
answer questions.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from efficienteqa.explore.module import SemanticScore
from efficienteqa.mapping.navgrid import OccupancyGrid
from efficienteqa.observation import Observation, PromptPoint


class OracleScorer:
    """``distance_m(xy)`` is the path distance from a floor point to the evidence (inf when
    unreachable); ``visible(instance)`` says whether the evidence is in view in a frame."""

    def __init__(self, distance_m: Callable[[Sequence[float]], float],
                 visible: Callable[[np.ndarray], bool], gain_m: float = 1.0) -> None:
        self.distance_m, self.visible, self.gain_m = distance_m, visible, gain_m

    def score(self, obs: Observation, prompts: list[PromptPoint], question: str) -> SemanticScore:
        distances = [self.distance_m(p.xy) for p in prompts]
        best = int(np.argmin(distances))
        letters = {p.letter: float(i == best) for i, p in enumerate(prompts)}
        in_view = obs.instance is not None and self.visible(obs.instance)
        closer = distances[best] < self.distance_m((obs.pose.x, obs.pose.y)) - self.gain_m
        return SemanticScore(letters, 1.0 if in_view or closer else 0.0,
                             {"distances_m": distances})


def evidence_distance_field(grid: OccupancyGrid, centre_xy: Sequence[float], radius_m: float,
                            rooms: Sequence[tuple[float, float, float, float]] = (),
                            reach_m: float = 2.0) -> np.ndarray:
    """Path metres from every cell centre to the evidence at ``centre_xy`` (inf: unreachable).

    The walk ends on a navigable cell within ``reach_m`` of the evidence *inside one of its
    rooms* (x0, y0, x1, y1) and goes straight on from there: the distance is the least
    (path to such a cell + straight line from it to the centre). Snapping to the nearest
    navigable cell instead crosses walls: a TV on a bedroom wall was "0.5 m away" from the
    hallway behind that wall, and the oracle steered the robot there. Without rooms, or when
    no navigable cell of the rooms lies within ``reach_m``, any navigable cell within
    ``reach_m`` qualifies.
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
    seeds = near & inside if (near & inside).any() else near
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
