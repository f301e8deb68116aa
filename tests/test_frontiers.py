"""Frontier detection, clustering, normals and weights on hand-made grids with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from efficienteqa.explore.frontiers import (
    boundary_groups,
    close_and_facing,
    cluster,
    extract_frontiers,
    frontier_cells,
    frontier_weight,
    frontier_weights,
    outward_normal,
    representative,
)
from efficienteqa.explore.settings import FrontierConfig
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.state import MapState

RES = 0.1


def walled_state(ny: int, nx: int, explored: np.ndarray, free: np.ndarray | None = None,
                 robot_xy: tuple[float, float] = (0.25, 0.25)) -> MapState:
    """A room: one-cell walls around an interior island (= free interior cells)."""
    inner = np.zeros((ny, nx), dtype=bool)
    inner[1:-1, 1:-1] = True
    free = inner if free is None else free & inner
    return MapState(GridSpec((0.0, 0.0), RES, (ny, nx)), free, ~free, explored, free.copy(),
                    robot_xy)


def test_frontier_cells_island_next_to_unexplored_strip():
    explored = np.zeros((10, 14), dtype=bool)
    explored[:6] = True  # rows 0-5 explored (walls included), rows 6-9 not
    s = walled_state(10, 14, explored)
    cells = frontier_cells(s.island, s.unexplored)
    assert sorted(map(tuple, cells)) == [(5, j) for j in range(1, 13)]
    (f,) = extract_frontiers(s)  # 12 cells > 10: one DBSCAN cluster
    assert f.size == 12 and f.cell[0] == 5 and f.normal == pytest.approx((0.0, 1.0))


def test_cells_outside_the_grid_count_as_unexplored():
    island = np.ones((4, 5), dtype=bool)
    cells = frontier_cells(island, np.zeros((4, 5), dtype=bool))
    # edge cells see 3 outside neighbours; corners see 5 and are no frontier
    expected = {(i, j) for i in range(4) for j in range(5) if (i in (0, 3)) != (j in (0, 4))}
    assert set(map(tuple, cells)) == expected


def test_few_cells_are_each_a_frontier():
    explored = np.zeros((10, 8), dtype=bool)
    explored[:6] = True
    s = walled_state(10, 8, explored)
    frontiers = extract_frontiers(s)
    assert len(frontiers) == 6 and all(f.size == 1 for f in frontiers)


def brute_force_dbscan(points: np.ndarray, eps: float = 1.0, min_samples: int = 2) -> set:
    """Textbook DBSCAN; returns the clusters as a set of frozensets of point indices."""
    d = np.linalg.norm(points[:, None, :] - points[None, :, :], axis=-1)
    neighbours = [np.flatnonzero(row <= eps) for row in d]
    core = [len(nb) >= min_samples for nb in neighbours]
    label = [-1] * len(points)
    clusters = []
    for p in range(len(points)):
        if not core[p] or label[p] >= 0:
            continue
        label[p], members, queue = len(clusters), {p}, [p]
        while queue:
            q = queue.pop()
            for r in neighbours[q]:
                if label[r] < 0:
                    label[r] = label[p]
                    members.add(int(r))
                    if core[r]:
                        queue.append(int(r))
        clusters.append(frozenset(members))
    return set(clusters)


@pytest.mark.parametrize("eps", [1.0, 1.5])
@pytest.mark.parametrize("seed", range(40))
def test_clustering_equals_brute_force_dbscan(seed, eps):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(11, 70))
    flat = rng.choice(144, size=n, replace=False)
    cells = np.stack([flat // 12, flat % 12], axis=-1)
    groups = cluster(cells, FrontierConfig(cluster_eps_cells=eps))
    expected = brute_force_dbscan(cells.astype(float), eps=eps)
    assert {frozenset(g.tolist()) for g in groups} == expected
    assert sum(len(g) for g in groups) == len(set().union(*expected))


def test_a_diagonal_frontier_survives_clustering():
    cells = np.array([[k, k] for k in range(12)])  # a staircase boundary: corner to corner
    assert cluster(cells, FrontierConfig(cluster_eps_cells=1.0)) == []  # ExploreEQA's eps: all noise
    (group,) = cluster(cells)  # the default eps keeps it as one frontier
    assert len(group) == 12


def test_isolated_cells_are_dropped_only_when_clustering():
    cells = np.array([[0, 0], [0, 1], [5, 5], [9, 9]] + [[2, j] for j in range(8)])
    groups = cluster(cells)
    assert sorted(len(g) for g in groups) == [2, 8]
    assert len(cluster(cells[:10], FrontierConfig(cluster_above_cells=10))) == 10


def test_representative_is_nearest_to_mean():
    assert representative(np.array([[0, j] for j in range(5)])) == 2
    # L-shape, mean (0.6, 1.4): (0, 1) and (1, 2) tie at 0.52, the first wins
    assert representative(np.array([[0, 0], [0, 1], [0, 2], [1, 2], [2, 2]])) == 1
    rng = np.random.default_rng(1)
    cells = rng.integers(0, 20, size=(30, 2))
    d = ((cells - cells.mean(axis=0)) ** 2).sum(axis=1)
    assert d[representative(cells)] == d.min()


@pytest.mark.parametrize("side, normal", [("+y", (0, 1)), ("-y", (0, -1)), ("+x", (1, 0)),
                                          ("-x", (-1, 0))])
def test_outward_normal_points_into_unexplored_side(side, normal):
    explored = np.zeros((14, 14), dtype=bool)
    half = {"+y": np.s_[:7, :], "-y": np.s_[7:, :], "+x": np.s_[:, :7], "-x": np.s_[:, 7:]}[side]
    explored[half] = True
    (f,) = extract_frontiers(walled_state(14, 14, explored))
    assert f.normal == pytest.approx(normal, abs=1e-12)
    n = outward_normal(np.array([f.cell]), ~explored, window_cells=3)[0]
    assert n == pytest.approx(normal, abs=1e-12)


def test_outward_normal_is_zero_safe():
    unexplored = np.zeros((7, 7), dtype=bool)
    assert outward_normal(np.array([[3, 3]]), unexplored).tolist() == [[0.0, 0.0]]
    unexplored[3, 1] = unexplored[3, 5] = True  # symmetric
    assert outward_normal(np.array([[3, 3]]), unexplored).tolist() == [[0.0, 0.0]]


def test_frontier_weight_formula():
    w = frontier_weight(np.array([0.5]), np.array([0.4]), np.array([0.3]), np.array([0.2]),
                        np.array([2.0]), np.array([False]))
    assert w[0] == pytest.approx(math.exp(0.5 / 0.2 + 0.4 / 2 + 0.3 / 0.5 + 0.2 / 0.5 - 2 / 10))
    p = frontier_weight(np.array([0.5]), np.array([0.4]), np.array([0.3]), np.array([0.2]),
                        np.array([2.0]), np.array([True]))
    assert p[0] == pytest.approx(w[0] * 1e-3)


def ray_state() -> MapState:
    """A frontier on row 10 facing +y; along its normal (rows 11-40): rows 11-14 free, rows
    26-30 explored, values 0.6 on rows 11-15 and 0.3 at the frontier row."""
    ny, nx = 50, 20
    explored = np.zeros((ny, nx), dtype=bool)
    explored[:11] = True
    explored[26:31, 1:-1] = True
    free = np.zeros((ny, nx), dtype=bool)
    free[:15] = True
    return walled_state(ny, nx, explored, free)


def test_frontier_weights_hand_computation():
    s = ray_state()
    f = next(f for f in extract_frontiers(s) if f.cell[0] == 10)
    assert f.normal == pytest.approx((0.0, 1.0))
    values = np.zeros(s.spec.shape)
    values[10] = 0.3
    values[11:16] = 0.6
    pose = Pose2D(f.xy[0], f.xy[1] - 2.0, 0.0)  # 2 m away, looking along +x
    r_u, r_f = 25 / 30, 4 / 10
    base = r_u / 0.2 + r_f / 2.0 - 2.0 / 10
    on = frontier_weights(s, [f], pose, values, step=3)
    assert on[0] == pytest.approx(math.exp(base + 0.3 / 0.5 + 0.6 / 0.5))
    for step in (1, 2):  # value terms off for the first two steps
        assert frontier_weights(s, [f], pose, values, step)[0] == pytest.approx(math.exp(base))
    assert frontier_weights(s, [f], pose, None, step=9)[0] == pytest.approx(math.exp(base))


def test_close_and_facing_penalty_uses_metres_and_wrapped_angles():
    up = np.array([[0.0, 1.0]])
    facing = Pose2D(0.0, 0.0, math.pi / 2)
    assert close_and_facing(np.array([[0.0, 0.4]]), up, facing)[0]
    assert not close_and_facing(np.array([[0.0, 0.6]]), up, facing)[0]
    assert not close_and_facing(np.array([[0.0, 5.0]]), up, facing)[0]
    assert not close_and_facing(np.array([[0.0, 0.4]]), up, Pose2D(0.0, 0.0, 0.0))[0]
    # yaw 179 deg vs normal -179 deg: 2 deg apart once wrapped
    normal = np.array([[math.cos(math.radians(-179)), math.sin(math.radians(-179))]])
    assert close_and_facing(np.array([[-0.3, 0.0]]), normal, Pose2D(0, 0, math.radians(179)))[0]
    assert not close_and_facing(np.array([[-0.3, 0.0]]), normal, Pose2D(0, 0, math.radians(100)))[0]


def test_penalty_applies_in_frontier_weights():
    s = ray_state()
    f = next(f for f in extract_frontiers(s) if f.cell[0] == 10)
    near = Pose2D(f.xy[0], f.xy[1] - 0.4, math.pi / 2)
    far = Pose2D(f.xy[0], f.xy[1] - 0.6, math.pi / 2)
    w_near, w_far = frontier_weights(s, [f], near, None, 1), frontier_weights(s, [f], far, None, 1)
    assert w_near[0] / w_far[0] == pytest.approx(1e-3 * math.exp(0.2 / 10))


def slanted_state() -> MapState:
    """A room whose unexplored part lies above a boundary of slope 1/3 (one row up per three
    columns), with an explored cell off the island where each stair step starts, as the edge
    of a view wedge leaves it: only the first cell of each step has 3 unexplored neighbours."""
    ny, nx = 20, 60
    i, j = np.mgrid[:ny, :nx]
    return walled_state(ny, nx, j >= 3 * i - 1, free=j >= 3 * i)


def test_a_slanted_boundary_is_one_frontier_not_noise():
    """The explorer reported "no frontier left" with rooms unexplored (houses
    19 and 2000 of the exploration benchmark), since every frontier cell of such a boundary
    is isolated and DBSCAN dropped them all."""
    s = slanted_state()
    cells = frontier_cells(s.island, s.unexplored)
    assert sorted(map(tuple, cells)) == [(k, 3 * k) for k in range(1, 19)]  # 3 columns apart
    assert cluster(cells) == []  # all noise for DBSCAN
    assert extract_frontiers(s, FrontierConfig(isolated_along_boundary=False)) == []  # as ExploreEQA
    (f,) = extract_frontiers(s)
    assert f.size == 18
    assert f.normal[0] < 0 < f.normal[1]  # up and to the left: the unexplored side


def test_a_cell_alone_on_its_stretch_of_boundary_stays_noise():
    explored = np.ones((12, 20), dtype=bool)
    explored[10, 1:15] = False  # a strip along the top wall: 12 frontier cells below it
    explored[1, 16:19] = False  # a 3-cell notch against the bottom wall: one frontier cell
    s = walled_state(12, 20, explored)
    cells = frontier_cells(s.island, s.unexplored)
    assert (2, 17) in set(map(tuple, cells)) and len(cells) == 13
    (f,) = extract_frontiers(s)
    assert f.size == 12 and f.cell[0] == 9


def test_boundary_groups_follow_the_boundary_not_the_distance():
    s = slanted_state()
    cells = np.array([[1, 3], [18, 54], [5, 40]])  # two far apart on the boundary, one inside
    (group,) = boundary_groups(cells, s.island, s.unexplored)
    assert group.tolist() == [0, 1]
    assert boundary_groups(cells, s.island, s.unexplored, members=np.array([0, 2])) == []
