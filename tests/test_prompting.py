"""Visual prompting: candidate floor points, floor projection and the drawn circles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from efficienteqa.explore.prompting import (
    PAPER_PROMPTS,
    PROMPT_CONFIGS,
    PromptConfig,
    candidate_points,
    project_floor_points,
    prompt_points,
)
from efficienteqa.geometry import CameraSpec, Pose2D, camera_to_world
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.navgrid import OccupancyGrid
from efficienteqa.mapping.state import MapState
from efficienteqa.observation import PromptPoint
from efficienteqa.perception.image import CIRCLE_FILL, draw_prompts

CAMERA = CameraSpec()  # 640 x 480, 120 deg, 1.5 m, pitched 30 deg down
GRID = GridSpec((0.0, 0.0), 0.1, (80, 120))  # 12 m x 8 m
ROBOT = Pose2D(1.0, 4.0, 0.0)  # facing +x


def _state(free: np.ndarray, robot: Pose2D = ROBOT) -> MapState:
    return MapState(GRID, free, ~free, np.zeros_like(free), free.copy(), (robot.x, robot.y))


def _room() -> np.ndarray:
    free = np.zeros(GRID.shape, dtype=bool)
    free[1:-1, 1:-1] = True
    return free


def _candidates(state: MapState, robot: Pose2D = ROBOT, seed: int = 0) -> list[PromptPoint]:
    return candidate_points(state, camera_to_world(robot, CAMERA), CAMERA.intrinsics,
                            (CAMERA.width, CAMERA.height), seed)


def test_projection_of_known_floor_points():
    cam = camera_to_world(ROBOT, CAMERA)
    d = 1.5 / math.tan(math.radians(30))  # the optical axis meets the floor here
    uv, front = project_floor_points(np.array([[1.0 + d, 4.0], [1.0 + d, 3.0], [-3.0, 4.0]]),
                                     cam, CAMERA.intrinsics)
    assert front.tolist() == [True, True, False]
    np.testing.assert_allclose(uv[0], [320.0, 240.0], atol=1e-9)
    # 1 m to the robot's right (-y) at camera depth d*cos30 + 1.5*sin30 = 3 m, same image row
    np.testing.assert_allclose(uv[1], [320.0 + CAMERA.fx / 3.0, 240.0], atol=1e-9)
    assert np.isnan(uv[2]).all()


def _check(points: list[PromptPoint], state: MapState) -> None:
    assert 2 <= len(points) <= 3
    assert [p.letter for p in points] == list("ABC"[: len(points)])
    us = [p.pixel[0] for p in points]
    assert us == sorted(us)  # "A" is the leftmost
    free_grid, island = OccupancyGrid(GRID, state.free), OccupancyGrid(GRID, state.island)
    robot = np.array(state.robot_xy)
    for p in points:
        assert 2.0 <= np.linalg.norm(np.array(p.xy) - robot) <= 10.0
        assert 20 <= p.pixel[0] <= 620 and 20 <= p.pixel[1] <= 460
        uv, front = project_floor_points(np.array([p.xy]), camera_to_world(ROBOT, CAMERA),
                                         CAMERA.intrinsics)
        assert front[0] and np.allclose(uv[0], p.pixel)
        assert island.is_navigable(*p.xy, radius_m=0.2)
        assert free_grid.line_of_sight(robot, p.xy)
    for a in points:
        for b in points:
            if a is not b:
                assert np.linalg.norm(np.array(a.xy) - np.array(b.xy)) >= 1.0


@pytest.mark.parametrize("seed", range(5))
def test_candidates_in_an_open_room(seed):
    state = _state(_room())
    points = _candidates(state, seed=seed)
    _check(points, state)
    assert len(points) == 3
    assert points == _candidates(state, seed=seed)  # deterministic for a seed


@pytest.mark.parametrize("seed", range(8))
def test_no_candidate_behind_a_wall(seed):
    free = _room()
    free[25:56, 40:43] = False  # wall x in [4.0, 4.3], y in [2.5, 5.6]; the room goes around it
    state = _state(free)
    points = _candidates(state, seed=seed)
    _check(points, state)
    for p in points:
        # a point beyond the wall is hidden when the sight line crosses x = 4 within the wall
        if p.xy[0] > 4.0:
            y_at_wall = 4.0 + (p.xy[1] - 4.0) * (4.0 - 1.0) / (p.xy[0] - 1.0)
            assert not 2.5 <= y_at_wall <= 5.6


def test_fewer_than_two_candidates_give_nothing():
    corridor = np.zeros(GRID.shape, dtype=bool)
    corridor[36:44, 5:33] = True  # x in [0.5, 3.3], y in [3.6, 4.4]: too small for two points
    assert _candidates(_state(corridor)) == []
    small_room = np.zeros(GRID.shape, dtype=bool)
    small_room[30:50, 1:25] = True  # a 2.4 m x 2 m box: nothing 2 m away
    assert _candidates(_state(small_room)) == []
    off_island = _state(_room(), Pose2D(-5.0, -5.0, 0.0))
    assert _candidates(off_island, Pose2D(-5.0, -5.0, 0.0)) == []


def test_draw_prompts_marks_each_point_and_nothing_far_away():
    rgb = np.full((480, 640, 3), 30, dtype=np.uint8)
    points = [PromptPoint("A", (0.0, 0.0), (100.5, 200.5)), PromptPoint("B", (0.0, 0.0),
                                                                          (400.5, 300.5))]
    out = draw_prompts(rgb, points)
    assert out.shape == rgb.shape and out.dtype == np.uint8
    assert (rgb == 30).all()  # input untouched
    vv, uu = np.mgrid[0:480, 0:640] + 0.5
    for p in points:
        r = np.hypot(uu - p.pixel[0], vv - p.pixel[1])
        ring = (r >= 11) & (r <= 15)
        assert (out[ring] == CIRCLE_FILL).all(axis=1).mean() > 0.9
        assert (out[(r >= 17) & (r <= 18)].sum(axis=1) < 90).mean() > 0.5  # black outline
        assert (out[r < 8] == 0).all(axis=1).any()  # the letter, in black
    near = np.zeros((480, 640), dtype=bool)
    for p in points:
        near |= np.hypot(uu - p.pixel[0], vv - p.pixel[1]) <= 21
    assert (out[~near] == 30).all()


def test_unexplored_candidates_are_preferred():
    free = _room()
    state = _state(free)
    # Everything up to 5 m ahead of the robot explored: the prompts go beyond it.
    xs, _ = state.spec.centres()
    state.explored = free & (xs < ROBOT.x + 5.0)
    points = _candidates(state)
    assert len(points) >= 2
    for p in points:
        i, j = state.spec.world_to_cell(p.xy)
        assert not state.explored[i, j]
    # With everything explored the usual candidates come back.
    state.explored = free.copy()
    assert len(_candidates(state)) >= 2


def test_default_prompts_ask_where_no_point_is_2_m_away():
    """A small room (no floor 2 m from the robot): the paper's 2-10 m (DESIGN 3.3) finds no point to ask
    about; the default PromptConfig asks about points from 1 m, 0.75 m apart."""
    free = np.zeros(GRID.shape, dtype=bool)
    (i0, j0), (i1, j1) = (GRID.world_to_cell((ROBOT.x + dx, ROBOT.y + dy))
                          for dx, dy in ((-0.5, -1.0), (1.6, 1.0)))
    free[i0:i1 + 1, j0:j1 + 1] = True  # rows along y, columns along x
    state = _state(free)
    args = (state, camera_to_world(ROBOT, CAMERA), CAMERA.intrinsics,
            (CAMERA.width, CAMERA.height), 0)
    assert prompt_points(*args, PAPER_PROMPTS) == []
    points = prompt_points(*args, PromptConfig())
    assert len(points) >= 2
    robot = np.array(state.robot_xy)
    for p in points:
        assert 1.0 <= np.linalg.norm(np.array(p.xy) - robot) < 2.0
    for a in points:
        for b in points:
            if a is not b:
                assert np.linalg.norm(np.array(a.xy) - np.array(b.xy)) >= 0.75


def test_the_paper_prompts_are_spec_3_3():
    paper = PAPER_PROMPTS
    assert (paper.min_m, paper.max_m, paper.merge_m, paper.n) == (2.0, 10.0, 1.0, 3)
    assert PROMPT_CONFIGS["paper"] is PAPER_PROMPTS and PROMPT_CONFIGS["default"] == PromptConfig()


@pytest.mark.parametrize("name", ["default", "paper"])
def test_circles_of_points_in_one_line_of_sight_do_not_overlap(name):
    """A corridor straight ahead: floor points metres apart in the world project
    to nearly the same pixel column, and the far ones to nearly the same row (6 m and 10 m
    ahead are 17 px apart). Every pair of chosen circles must stay apart in pixels, for both
    prompt sets; an overlapping point is not asked about."""
    from efficienteqa.explore.prompting import MIN_CIRCLE_GAP_PX
    from efficienteqa.perception.image import CIRCLE_RADIUS_PX

    corridor = np.zeros(GRID.shape, dtype=bool)
    corridor[36:44, 5:118] = True  # x in [0.5, 11.8], y in [3.6, 4.4]; the robot at (1, 4)
    state = _state(corridor)
    config = PROMPT_CONFIGS[name]
    assert config.min_px == MIN_CIRCLE_GAP_PX >= 2 * CIRCLE_RADIUS_PX
    for seed in range(6):
        points = prompt_points(state, camera_to_world(ROBOT, CAMERA), CAMERA.intrinsics,
                               (CAMERA.width, CAMERA.height), seed, config)
        assert len(points) >= 2
        for i, a in enumerate(points):
            for b in points[i + 1:]:
                assert math.dist(a.pixel, b.pixel) >= 2 * CIRCLE_RADIUS_PX, (seed, points)
                assert math.dist(a.xy, b.xy) >= config.merge_m
        # the circles drawn do not touch: each letter's disk is whole
        out = draw_prompts(np.full((480, 640, 3), 30, dtype=np.uint8), points)
        vv, uu = np.mgrid[0:480, 0:640] + 0.5
        for p in points:
            r = np.hypot(uu - p.pixel[0], vv - p.pixel[1])
            assert (out[(r >= 11) & (r <= 15)] == CIRCLE_FILL).all(axis=1).mean() > 0.9
