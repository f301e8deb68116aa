"""Frontier explorer (SFE / frontier-only) and the random baseline on hand-made maps."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.frontiers import extract_frontiers, frontier_weights
from efficienteqa.explore.random_walk import RandomExplorer
from efficienteqa.explore.registry import make_explorer
from efficienteqa.explore.settings import PAPER_SFE, SFEConfig
from efficienteqa.explore.sfe import FrontierExplorer, cut_path, sample_index
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.navgrid import OccupancyGrid, path_length
from efficienteqa.mapping.state import MapState

RES = 0.1


def make_state(free: np.ndarray, explored: np.ndarray, robot_xy: tuple[float, float]) -> MapState:
    """The island is the 8-connected free component holding the robot."""
    spec = GridSpec((0.0, 0.0), RES, free.shape)
    labels, _ = ndimage.label(free, structure=np.ones((3, 3)))
    i, j = spec.world_to_cell(robot_xy)
    return MapState(spec, free, ~free, explored, labels == labels[i, j], robot_xy)


def house() -> np.ndarray:
    """13 x 9 m: outer walls, a wall at x = 6 m with a door, a wall at y = 4.5 m with two doors,
    a 1 x 1 m table."""
    free = np.ones((90, 130), dtype=bool)
    free[:2], free[-2:], free[:, :2], free[:, -2:] = False, False, False, False
    free[:, 60:62] = False
    free[40:52, 60:62] = True
    free[45:47, :] = False
    free[45:47, 20:32] = True
    free[45:47, 90:102] = True
    free[10:20, 20:30] = False
    return free


def disk(shape: tuple[int, int], xy: np.ndarray, radius_m: float) -> np.ndarray:
    ii, jj = np.indices(shape)
    return np.hypot((jj + 0.5) * RES - xy[0], (ii + 0.5) * RES - xy[1]) <= radius_m


def corridor(explored_cols: slice = slice(10, 110)) -> MapState:
    """A 12 x 2 m corridor explored between x = 1 and 11 m: frontiers at both ends, their
    standing points 3.45 m from (6, 1)."""
    free = np.zeros((20, 120), dtype=bool)
    free[1:-1, 1:-1] = True
    explored = np.zeros_like(free)
    explored[:, explored_cols] = True
    return make_state(free, explored, (6.0, 1.0))


def assert_path_on_navigable(state: MapState, path: np.ndarray, radius_m: float = 0.2) -> None:
    nav = OccupancyGrid(state.spec, state.island).navigable(radius_m)
    for a, b in zip(path[:-1], path[1:]):
        t = np.linspace(0.0, 1.0, max(2, int(np.linalg.norm(b - a) / (RES / 4)) + 2))
        i, j = state.spec.world_to_cell(a + t[:, None] * (b - a))
        assert nav[i, j].all() and state.island[i, j].all()


def test_sfe_names_and_registry():
    assert make_explorer("sfe").name == "sfe"
    assert make_explorer("frontier-only").name == "frontier-only"
    assert FrontierExplorer(SFEConfig(use_values=False)).name == "frontier-only"
    assert make_explorer("random", max_step_m=2.0).config.max_step_m == 2.0
    with pytest.raises(EfficientEQAError):
        make_explorer("greedy")


def test_done_when_nothing_is_unexplored():
    free = house()
    state = make_state(free, np.ones_like(free), (3.0, 3.0))
    pose = Pose2D(3.0, 3.0, 0.4)
    d = make_explorer("sfe").decide(state, pose, None, 5)
    assert d.done and d.reason == "no frontier" and d.pose == pose and d.frontiers == []


def test_backoff_stands_behind_the_frontier_facing_it():
    state = corridor()
    explorer = FrontierExplorer()
    explorer.reset(0)
    d = explorer.decide(state, Pose2D(6.0, 1.0, 0.0), None, 1)
    f = d.frontier
    assert abs(f.normal[0]) == pytest.approx(1.0)
    expected = np.array(f.xy) - 1.5 * np.array(f.normal)
    assert d.target_xy == pytest.approx(tuple(expected))
    assert d.reason == "new frontier" and not d.done
    assert path_length(d.path) <= 3.0 + 1e-9 and d.path[0] == pytest.approx([6.0, 1.0])
    yaw_to_frontier = math.atan2(f.xy[1] - d.pose.y, f.xy[0] - d.pose.x)
    assert d.pose.yaw == pytest.approx(yaw_to_frontier)


def test_backoff_blocked_moves_to_nearest_reachable_cell():
    state = corridor()
    f = next(f for f in extract_frontiers(state) if f.normal[0] > 0)
    behind = np.array(f.xy) - 1.5 * np.array(f.normal)
    i, j = state.spec.world_to_cell(behind)
    state.island[i - 3:i + 4, j - 2:j + 3] = False  # a pillar on the standing point
    state.free[i - 3:i + 4, j - 2:j + 3] = False
    explorer = FrontierExplorer()
    for seed in range(20):  # find a draw that picks this frontier
        explorer.reset(seed)
        d = explorer.decide(state, Pose2D(6.0, 1.0, 0.0), None, 1)
        if d.frontier.normal[0] > 0:
            break
    grid = OccupancyGrid(state.spec, state.island)
    reachable = grid.navigable(0.2) & np.isfinite(grid.distance_field((6.0, 1.0), 0.2))
    centres = state.spec.cell_to_world(np.argwhere(reachable))
    nearest = np.linalg.norm(centres - behind, axis=1).min()
    assert np.linalg.norm(np.array(d.target_xy) - behind) == pytest.approx(nearest)
    ti, tj = state.spec.world_to_cell(d.target_xy)
    assert reachable[ti, tj]


@pytest.mark.parametrize("name", ["sfe", "frontier-only", "random"])
def test_paths_stay_on_navigable_island_cells_and_moves_are_short(name):
    free = house()
    explored = disk(free.shape, np.array([3.0, 3.0]), 1.0)
    pose = Pose2D(3.0, 3.0, 0.0)
    rng = np.random.default_rng(0)
    values = ndimage.gaussian_filter(rng.random(free.shape), 5)
    explorer = make_explorer(name)
    explorer.reset(7)
    for step in range(1, 25):
        state = make_state(free, explored, (pose.x, pose.y))
        d = explorer.decide(state, pose, values, step)
        if d.done:
            break
        assert d.path[0] == pytest.approx(pose.xy) and d.path[-1] == pytest.approx(d.pose.xy)
        assert path_length(d.path) <= 3.0 + 1e-9
        # a frontier reachable only at the tight radius (SFEConfig.tight_radius_m) is planned there
        target = getattr(explorer, "_target", None)
        assert_path_on_navigable(state, d.path, min(0.2, target.radius_m if target else 0.2))
        pose = d.pose
        ahead = np.array([pose.x + math.cos(pose.yaw), pose.y + math.sin(pose.yaw)])
        explored |= disk(free.shape, pose.xy, 0.8) | disk(free.shape, ahead, 0.8)
    assert step > 5


def test_committed_target_persists_until_reached():
    state = corridor()
    explorer = FrontierExplorer()
    explorer.reset(3)
    pose = Pose2D(6.0, 1.0, 0.0)
    first = explorer.decide(state, pose, None, 1)
    reasons, current = [first.reason], first
    pose = first.pose
    for step in range(2, 8):
        d = explorer.decide(state, pose, None, step)
        reasons.append(d.reason)
        if d.reason == "committed":
            assert d.target_xy == current.target_xy and d.frontier == current.frontier
        else:
            current = d
        pose = d.pose
    # 3.45 m from the robot to either standing point: 2 steps to get there, then a new choice
    assert reasons[:3] == ["new frontier", "committed", "new frontier"]


def test_committed_target_dropped_when_its_frontier_vanishes_or_is_cut_off():
    state = corridor()
    explorer = FrontierExplorer()
    explorer.reset(3)
    first = explorer.decide(state, Pose2D(6.0, 1.0, 0.0), None, 1)
    side = np.sign(first.frontier.normal[0])
    explored = state.explored.copy()
    explored[:, 110:] = side > 0
    explored[:, :10] = side < 0  # the chosen end is now explored, the other one not
    vanished = make_state(state.free, explored, first.pose.xy)
    d = explorer.decide(vanished, first.pose, None, 2)
    assert d.reason == "new frontier" and np.sign(d.frontier.normal[0]) == -side

    explorer.reset(3)
    pose = Pose2D(6.0, 1.0, 0.0)
    first = explorer.decide(state, pose, None, 1)
    blocked = make_state(state.free, state.explored, (6.0, 1.0))
    col = int(first.target_xy[0] / RES)
    blocked.island[:, col - 9:col + 10] = False  # 1.9 m of wall around the standing point
    d = explorer.decide(blocked, pose, None, 2)
    assert d.reason == "new frontier" and np.sign(d.frontier.normal[0]) == -side


def test_seeded_sampling_is_deterministic_and_follows_weights():
    weights = np.array([1.0, 3.0, 0.0, 6.0])
    draws = [sample_index(np.random.default_rng(s), weights) for s in range(1000)]
    freq = np.bincount(draws, minlength=4) / 1000
    assert freq[2] == 0
    assert freq == pytest.approx(weights / weights.sum(), abs=0.05)  # > 3 sigma
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    assert [sample_index(rng_a, weights) for _ in range(50)] == [
        sample_index(rng_b, weights) for _ in range(50)]


def test_explorer_choice_follows_weights_and_seed():
    state = corridor()
    pose = Pose2D(6.0, 1.0, 0.0)
    values = np.zeros(state.spec.shape)
    values[:, :11] = 0.25  # the -x end: V = v_dir = 0.25, weight x e
    frontiers = extract_frontiers(state)
    w = frontier_weights(state, frontiers, pose, values, 3)
    p_minus = w[[f.normal[0] < 0 for f in frontiers]].sum() / w.sum()
    assert p_minus == pytest.approx(math.e / (1 + math.e), abs=0.02)
    explorer = FrontierExplorer()
    picks = []
    for seed in range(300):
        explorer.reset(seed)
        picks.append(explorer.decide(state, pose, values, 3).frontier.normal[0] < 0)
    assert np.mean(picks) == pytest.approx(p_minus, abs=0.08)  # 3 sigma for 300 draws
    again = []
    for seed in range(30):
        explorer.reset(seed)
        again.append(explorer.decide(state, pose, values, 3).frontier.normal[0] < 0)
    assert again == picks[:30]
    explorer = make_explorer("frontier-only")  # ignores the values: about even
    picks = []
    for seed in range(300):
        explorer.reset(seed)
        picks.append(explorer.decide(state, pose, values, 3).frontier.normal[0] < 0)
    assert np.mean(picks) == pytest.approx(0.5, abs=0.09)


def test_robot_off_navigable_cells_still_plans():
    state = corridor()
    d = FrontierExplorer().decide(state, Pose2D(6.0, 0.15, 0.0), None, 1)  # 0.05 m from a wall
    assert not d.done and path_length(d.path) > 0
    narrow = np.zeros((5, 120), dtype=bool)  # 0.3 m wide: nothing navigable at 0.2 m
    narrow[1:-1, 1:-1] = True
    explored = np.zeros_like(narrow)
    explored[:, 10:110] = True
    d = FrontierExplorer().decide(make_state(narrow, explored, (6.0, 0.25)), Pose2D(6.0, 0.25, 0),
                                  None, 1)
    assert not d.done and path_length(d.path) == pytest.approx(3.0)


def test_cut_path():
    path = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]])
    assert cut_path(path, 3.0) == pytest.approx(np.array([[0, 0], [2, 0], [2, 1.0]]))
    assert cut_path(path, 5.0) == pytest.approx(path)


def test_random_explorer_stays_on_island_within_3m():
    free = house()
    explored = disk(free.shape, np.array([3.0, 3.0]), 1.0)
    pose = Pose2D(3.0, 3.0, 0.0)
    explorer = RandomExplorer()
    explorer.reset(1)
    trace = []
    for step in range(1, 30):
        state = make_state(free, explored, (pose.x, pose.y))
        d = explorer.decide(state, pose, None, step)
        assert not d.done
        assert path_length(d.path) <= 3.0 + 1e-9
        # a frontier reachable only at the tight radius (SFEConfig.tight_radius_m) is planned there
        target = getattr(explorer, "_target", None)
        assert_path_on_navigable(state, d.path, min(0.2, target.radius_m if target else 0.2))
        pose = d.pose
        trace.append(pose)
    explorer.reset(1)
    pose = Pose2D(3.0, 3.0, 0.0)
    replay = []
    for step in range(1, 30):
        pose = explorer.decide(make_state(free, explored, (pose.x, pose.y)), pose, None, step).pose
        replay.append(pose)
    assert replay == trace
    assert len({(round(p.x, 3), round(p.y, 3)) for p in trace}) > 20


def test_second_looks_go_up_close_at_the_tight_radius_then_frontiers_are_dropped():
    state = corridor()
    explorer = FrontierExplorer(SFEConfig(**PAPER_SFE))  # approach_unreachable would go on
    explorer.reset(0)
    pose = Pose2D(6.0, 1.0, 0.0)
    first = explorer.decide(state, pose, None, 1)
    for f in first.frontiers:  # both ends looked at once from their back-off points
        explorer._record_look(f.xy)
    explorer._target = None
    d = explorer.decide(state, pose, None, 2)
    assert d.reason == "new frontier"
    assert explorer._target.radius_m == explorer.config.tight_radius_m
    assert np.linalg.norm(np.subtract(d.target_xy, d.frontier.xy)) < 0.5  # no back-off
    for f in first.frontiers:  # looked at twice: never again
        explorer._record_look(f.xy)
    explorer._target = None
    assert explorer.decide(state, pose, None, 3).reason == "no reachable frontier"
