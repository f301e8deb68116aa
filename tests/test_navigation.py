"""Ground-truth occupancy grid and planning on small hand-made floors with known answers."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from efficienteqa.envs.synthetic.navigation import oracle_moves, rasterise, sample_start_pose
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.navgrid import OccupancyGrid, path_length, truncate_path

RES = 0.05
T = 0.1  # wall thickness
OUTER = [(0, 0, 8, 0, T), (8, 0, 8, 3, T), (8, 3, 0, 3, T), (0, 3, 0, 0, T)]
ROOMS = [(0, 0, 4, 3), (4, 0, 8, 3)]


def two_rooms(door_open: bool = True) -> OccupancyGrid:
    """Rooms [0,4]x[0,3] and [4,8]x[0,3]; the wall x=4 runs y 0..2, the door is y 2..3."""
    walls = [*OUTER, (4, 0, 4, 2, T)] + ([] if door_open else [(4, 2, 4, 3, T)])
    return rasterise(GridSpec.covering(0, 0, 8, 3, RES, 0.2), ROOMS, walls, [])


def octile(a, b) -> float:
    dx, dy = abs(a[0] - b[0]), abs(a[1] - b[1])
    return max(dx, dy) + (math.sqrt(2) - 1) * min(dx, dy)


def assert_path_navigable(grid: OccupancyGrid, path: np.ndarray, radius: float) -> None:
    nav = grid.navigable(radius)
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = max(2, int(np.linalg.norm(b - a) / (RES / 10)) + 2)
        pts = a + np.linspace(0, 1, n)[:, None] * (b - a)
        i, j = grid.spec.world_to_cell(pts)
        assert grid.spec.contains((i, j)).all()
        assert nav[i, j].all(), f"segment {a} -> {b} leaves the navigable cells"


def test_gridspec_round_trip_and_axes():
    spec = GridSpec((-1.0, 2.0), 0.5, (4, 6))  # 4 rows along y, 6 columns along x
    i, j = spec.world_to_cell((0.2, 2.7))
    assert (int(i), int(j)) == (1, 2)  # row from y, column from x
    np.testing.assert_allclose(spec.cell_to_world((1, 2)), [0.25, 2.75])
    np.testing.assert_allclose(spec.cell_to_world(np.array([[0, 0], [3, 5]])),
                               [[-0.75, 2.25], [1.75, 3.75]])
    assert spec.contains((np.array([0, 3, 4, -1]), np.array([5, 0, 0, 0]))).tolist() == [
        True, True, False, False]


def test_free_cells_walls_and_floor():
    g = two_rooms()
    assert g.free.shape == (68, 168)
    assert g.is_navigable(1.0, 1.0, 0.0) and g.is_navigable(6.0, 1.5, 0.0)
    assert not g.is_navigable(4.0, 1.0, 0.0)  # interior wall
    assert not g.is_navigable(0.0, 1.0, 0.0)  # outer wall
    assert not g.is_navigable(-0.15, 1.0, 0.0) and not g.is_navigable(8.15, 1.0, 0.0)  # no floor
    assert not g.is_navigable(50.0, 1.0, 0.0)  # outside the grid
    assert g.is_navigable(4.0, 2.5, 0.0) and g.is_navigable(4.0, 2.5, 0.2)  # the door
    # Floor 8 x 3 m minus the walls' share inside it (perimeter half-walls, the 2 m wall).
    expected = 8 * 3 - (2 * 8 + 2 * 3) * 0.05 + 4 * 0.05**2 - 2 * 0.1 + 0.05 * 0.05
    assert g.area_m2() == pytest.approx(expected, abs=2 * RES**2 * 10)


def test_walls_block_line_of_sight_and_door_passes():
    g = two_rooms()
    assert not g.line_of_sight((2, 1), (6, 1))
    assert g.line_of_sight((2, 2.5), (6, 2.5))
    assert g.line_of_sight((1, 1), (3, 2))


def test_door_connects_rooms_and_closing_it_splits_them():
    for radius in (0.0, 0.2):
        g = two_rooms(door_open=True)
        labels, count = g.components(radius)
        assert count == 1
        assert g.label_at((1, 1), radius) == g.label_at((7, 1), radius) == 1
        g = two_rooms(door_open=False)
        labels, count = g.components(radius)
        assert count == 2
        assert {g.label_at((1, 1), radius), g.label_at((7, 1), radius)} == {1, 2}
        assert labels[~g.navigable(radius)].max() == 0


def test_distance_field_is_the_l_shaped_geodesic():
    g = two_rooms()
    start, goal = (3.01, 0.51), (5.01, 0.51)  # inside cells, not on their edges
    field = g.distance_field(start, 0.0)
    # Straight along the row of the start: exactly |dx| between cell centres.
    s_c = g.spec.cell_to_world(g.spec.world_to_cell(start))
    for x in (1.01, 2.01, 3.51):
        c = g.spec.cell_to_world(g.spec.world_to_cell((x, 0.51)))
        assert field[g.spec.world_to_cell((x, 0.51))] == pytest.approx(abs(c[0] - s_c[0]))
    # Up to the cell left of the wall's top, over it (through the door), and down again:
    # the 8-connected metric is octile distance on each leg.
    g_c = g.spec.cell_to_world(g.spec.world_to_cell(goal))
    left, right = (3.925, 1.975), (4.075, 1.975)  # free cells beside the wall's top end
    expected = octile(s_c, left) + (0.05 + 0.15 + 0.05) + octile(right, g_c)
    d = field[g.spec.world_to_cell(goal)]
    assert d == pytest.approx(expected, abs=RES)
    euclid = math.hypot(3.95 - 3.0, 2.0 - 0.5) + 0.1 + math.hypot(5.0 - 4.05, 2.0 - 0.5)
    assert euclid < d < euclid * 1.0824 + RES
    assert np.isinf(field[g.spec.world_to_cell((4.0, 1.0))])  # inside the wall
    closed = two_rooms(door_open=False).distance_field(start, 0.0)
    assert np.isinf(closed[g.spec.world_to_cell(goal)])


def test_shortest_path_stays_navigable():
    g = two_rooms()
    for radius in (0.0, 0.2, 0.3):
        path = g.shortest_path((1.0, 0.5), (7.0, 0.5), radius)
        assert path is not None
        np.testing.assert_allclose(path[0], [1.0, 0.5])
        np.testing.assert_allclose(path[-1], [7.0, 0.5])
        assert_path_navigable(g, path, radius)
        geodesic = g.distance_field((1.0, 0.5), radius)[g.spec.world_to_cell((7.0, 0.5))]
        assert path_length(path) <= geodesic + 2 * RES
        assert path_length(path) > 2 * math.hypot(3.0, 1.5)  # must climb to the door


def test_shortest_path_unreachable_is_none():
    g = two_rooms(door_open=False)
    assert g.shortest_path((1.0, 0.5), (7.0, 0.5), 0.2) is None
    assert g.shortest_path((1.0, 0.5), (30.0, 0.5), 0.2) is None


def test_truncate_path():
    path = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 5.0]])
    np.testing.assert_allclose(truncate_path(path, 3.0), [2.0, 1.0])
    np.testing.assert_allclose(truncate_path(path, 100.0), [2.0, 5.0])
    np.testing.assert_allclose(truncate_path(path, 0.0), [0.0, 0.0])
    g = two_rooms()
    plan = g.shortest_path((1.0, 0.5), (7.0, 0.5), 0.2)
    end = truncate_path(plan, 3.0)
    k = int(np.searchsorted(np.cumsum(np.linalg.norm(np.diff(plan, axis=0), axis=1)), 3.0))
    assert path_length(np.vstack([plan[: k + 1], end])) == pytest.approx(3.0)
    assert g.is_navigable(*end, radius_m=0.2)


def test_rotated_footprint_blocks_a_diamond():
    spec = GridSpec.covering(0, 0, 4, 4, RES, 0.0)
    g = rasterise(spec, [(0, 0, 4, 4)], [], [(2.0, 2.0, 1.0, 1.0, math.pi / 4)])
    assert not g.is_navigable(2.0, 2.0, 0.0)
    assert not g.is_navigable(2.6, 2.0, 0.0)  # a diamond tip reaches 0.707 m along x
    assert not g.is_navigable(2.0, 1.4, 0.0)
    assert g.is_navigable(2.42, 2.42, 0.0)  # an axis-aligned square would cover this corner
    assert g.is_navigable(1.58, 2.42, 0.0)
    blocked = (~g.free).sum() * RES**2
    assert blocked == pytest.approx(1.0, abs=0.08)  # centre sampling of the edges
    square = rasterise(spec, [(0, 0, 4, 4)], [], [(2.0, 2.0, 1.0, 1.0, 0.0)])
    assert not square.is_navigable(2.42, 2.42, 0.0) and square.is_navigable(2.6, 2.0, 0.0)


def test_erosion_narrows_a_corridor():
    # Two rooms joined by a 0.6 m wide, 2 m long corridor (floor edges are the obstacles).
    floor = [(0, 0, 2, 2), (2, 0.7, 4, 1.3), (4, 0, 6, 2)]
    g = rasterise(GridSpec.covering(0, 0, 6, 2, RES, 0.2), floor, [], [])
    assert g.is_navigable(3.0, 1.0, 0.2) and not g.is_navigable(3.0, 1.0, 0.35)
    assert g.label_at((1, 1), 0.2) == g.label_at((5, 1), 0.2) == 1
    assert g.label_at((1, 1), 0.35) != g.label_at((5, 1), 0.35)
    assert g.shortest_path((1, 1), (5, 1), 0.35) is None
    assert_path_navigable(g, g.shortest_path((1, 1), (5, 1), 0.2), 0.2)
    assert g.navigable(0.2) is g.navigable(0.2)  # memoised
    # Cells 0.2 m or more from the floor edge remain: 0.6 - 2 * 0.2 = 0.2 m -> 4 rows of 5 cm.
    col = g.navigable(0.2)[:, g.spec.world_to_cell((3.01, 1.0))[1]]
    assert col.sum() == 4


def test_sample_start_pose_deterministic_with_clearance():
    g = rasterise(GridSpec.covering(0, 0, 10, 2.4, RES, 0.2), [(0, 0, 10, 2.4)], [], [])
    a = sample_start_pose(g, np.random.default_rng(7), 0.2, clearance_m=1.0)
    b = sample_start_pose(g, np.random.default_rng(7), 0.2, clearance_m=1.0)
    assert a == b and isinstance(a, Pose2D)
    occupied = g.spec.cell_to_world(np.argwhere(~g.free))
    for seed in range(5):
        p = sample_start_pose(g, np.random.default_rng(seed), 0.2, clearance_m=1.0)
        assert np.min(np.linalg.norm(occupied - p.xy, axis=1)) >= 1.0 + RES / 2 - 1e-9
        assert math.cos(p.yaw) * (5.0 - p.x) > 0  # faces the long open side of the room
    best = sample_start_pose(g, np.random.default_rng(3), 0.2, 1.0, score=lambda q: -q.x,
                             tries=50)
    assert best.x < 1.5
    with pytest.raises(EfficientEQAError, match="clearance"):
        sample_start_pose(g, np.random.default_rng(0), 0.2, clearance_m=1.5)


def test_sample_start_pose_uses_the_largest_component():
    floor = [(0, 0, 6, 6), (8, 0, 10, 2.5)]  # big room and a separate small room
    g = rasterise(GridSpec.covering(0, 0, 10, 6, RES, 0.2), floor, [], [])
    for seed in range(5):
        assert sample_start_pose(g, np.random.default_rng(seed), 0.2, 1.0).x < 6


def test_oracle_moves_on_a_straight_corridor():
    g = rasterise(GridSpec.covering(0, 0, 10, 1, RES, 0.2), [(0, 0, 10, 1)], [], [])
    start = (0.51, 0.51)
    assert oracle_moves(g, start, [(9.51, 0.51)], 0.2) == 3  # exactly 9 m
    assert oracle_moves(g, start, [(9.61, 0.51)], 0.2) == 4
    assert oracle_moves(g, start, [(9.61, 0.51), (3.41, 0.51)], 0.2) == 1
    assert oracle_moves(g, start, [(0.52, 0.53)], 0.2) == 0  # the start cell
    assert oracle_moves(g, start, [(9.51, 0.51)], 0.2, step_m=1.0) == 9


def test_oracle_moves_unreachable_is_none():
    g = two_rooms(door_open=False)
    assert oracle_moves(g, (1.0, 1.0), [(7.0, 1.0)], 0.2) is None
    assert oracle_moves(g, (1.0, 1.0), [(40.0, 1.0)], 0.2) is None
    assert oracle_moves(g, (1.0, 1.0), [(7.0, 1.0), (3.0, 1.0)], 0.2) == 1


def test_planning_speed_on_a_200_by_150_grid():
    spec = GridSpec((0.0, 0.0), RES, (200, 150))  # 7.5 m x 10 m
    walls = [(0, 5, 6, 5, T), (3, 0, 3, 4, T), (1.5, 7, 7.5, 7, T)]
    g = rasterise(spec, [(0, 0, 7.5, 10)], walls, [(5.0, 2.0, 1.0, 0.6, 0.3)])
    t0 = time.perf_counter()
    field = g.distance_field((0.3, 0.3), 0.2)
    path = g.shortest_path((0.3, 0.3), (7.2, 9.7), 0.2)
    assert time.perf_counter() - t0 < 0.5
    assert path is not None and np.isfinite(field).sum() > 20000
    assert_path_navigable(g, path, 0.2)


@pytest.mark.parametrize("seed", range(4))
def test_paths_among_random_furniture_stay_navigable(seed):
    rng = np.random.default_rng(seed)
    feet = [(*rng.uniform(0, 8, 2), *rng.uniform(0.3, 1.2, 2), rng.uniform(0, math.pi))
            for _ in range(15)]
    walls = [(0, 4, 5, 4, T), (5.5, 4, 8, 4, T), (4, 0, 4, 3, T)]
    g = rasterise(GridSpec.covering(0, 0, 8, 8, RES, 0.2), [(0, 0, 8, 8)], walls, feet)
    labels, _ = g.components(0.25)
    cells = np.argwhere(labels == 1)
    for _ in range(5):
        a, b = g.spec.cell_to_world(cells[rng.choice(len(cells), 2)])
        path = g.shortest_path(a, b, 0.25)
        assert path is not None
        assert_path_navigable(g, path, 0.25)
        assert g.is_navigable(*truncate_path(path, 3.0), radius_m=0.25)
        assert path_length(path) <= g.distance_field(a, 0.25)[g.spec.world_to_cell(b)] + 1e-9


def test_thin_slanted_wall_does_not_leak():
    spec = GridSpec.covering(0, 0, 4, 4, RES, 0.0)
    g = rasterise(spec, [(0, 0, 4, 4)], [(-1, -1, 5, 5, 0.01), (-1, 4.5, 4.5, -1, 0.01)], [])
    assert g.components(0.0)[1] == 4
    assert not g.line_of_sight((3.0, 1.0), (1.0, 3.0))
