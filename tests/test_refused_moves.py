"""Refused moves: the planner stops where the map leaves room, and a move the environment
refuses is re-planned within the same step instead of spending a step and a model call."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agent_stubs import MentionScorer, seeking_model
from conftest import needs_egl
from efficienteqa.agent import AgentConfig
from efficienteqa.ask import ask
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.explore.base import Decision
from efficienteqa.explore.module import move
from efficienteqa.explore.settings import REFUSAL_RETRIES, SFEConfig
from efficienteqa.explore.sfe import FrontierExplorer, settle
from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.navgrid import OccupancyGrid, path_length
from efficienteqa.mapping.state import MapState
from efficienteqa.scenes import Scene, synthetic_questions
from efficienteqa.stack import Stack

RES = 0.1


def _hall() -> OccupancyGrid:
    """A 10 x 4 m hall (walls one cell thick all round)."""
    free = np.zeros((40, 100), bool)
    free[1:-1, 1:-1] = True
    return OccupancyGrid(GridSpec((0.0, 0.0), RES, free.shape), free)


def _room_at(grid: OccupancyGrid, xy) -> float:
    return float(grid.clearance()[grid.spec.world_to_cell(xy)])


def test_a_move_ending_against_a_wall_settles_where_the_map_leaves_room():
    grid = _hall()
    path = np.array([[2.0, 2.0], [4.0, 0.45]])  # ends 0.3 m from the south wall's face
    assert _room_at(grid, path[-1]) < 0.45
    out = settle(grid, path, 0.25, 0.45, 0.25, 3.0, 0.5)
    assert out[0] == pytest.approx(path[0]) and path_length(out) <= 3.0 + 1e-9
    assert _room_at(grid, out[-1]) >= 0.45
    assert np.linalg.norm(out[-1] - path[-1]) <= 0.25 + 1e-9
    # Where it has room already, or with no clearance asked for, the path is left alone.
    assert settle(grid, np.array([[2.0, 2.0], [4.0, 2.0]]), 0.25, 0.45, 0.25, 3.0, 0.5) == \
        pytest.approx(np.array([[2.0, 2.0], [4.0, 2.0]]))
    assert settle(grid, path, 0.25, 0.0, 0.25, 3.0, 0.5) is path


def test_a_settled_end_keeps_the_move_within_its_length_and_the_reachable_floor():
    grid = _hall()
    # A full 3 m move along the wall: the roomy cells within 0.25 m of its end that are still
    # within 3 m of path are behind it or beside it, never beyond it.
    path = np.array([[1.0, 0.45], [4.0, 0.45]])
    out = settle(grid, path, 0.0, 0.45, 0.25, 3.0, 0.5)
    assert path_length(out) <= 3.0 + 1e-9 and _room_at(grid, out[-1]) > _room_at(grid, path[-1])
    # In a corridor too narrow for the clearance, the roomiest cell (its middle) is taken.
    free = np.zeros((8, 100), bool)
    free[1:-1, 1:-1] = True  # 0.6 m wide: no cell has 0.45 m
    narrow = OccupancyGrid(GridSpec((0.0, 0.0), RES, free.shape), free)
    out = settle(narrow, np.array([[1.0, 0.4], [3.0, 0.2]]), 0.0, 0.45, 0.25, 3.0, 0.5)
    assert _room_at(narrow, out[-1]) == pytest.approx(narrow.clearance().max())


def test_the_frontier_explorer_stops_with_room_unless_told_not_to():
    # 12 x 6 m, explored west of x = 5 m; a wall from the south side up to y = 4.5 m at
    # x = 1.8-2.2 m. From (1, 1) the way east goes north round the wall's end: the 3 m move
    # ends beside the wall.
    free = np.zeros((60, 120), bool)
    free[1:-1, 1:-1] = True
    free[:45, 18:22] = False
    explored = np.zeros_like(free)
    explored[:, :50] = True
    spec = GridSpec((0.0, 0.0), RES, free.shape)
    state = MapState(spec, free, ~free, explored, free.copy(), (1.0, 1.0))
    ends = {}
    for clearance in (0.0, 0.45):
        explorer = FrontierExplorer(SFEConfig(use_values=False, stop_clearance_m=clearance))
        explorer.reset(0)
        d = explorer.decide(state, Pose2D(1.0, 1.0, 0.0), None, 1)
        assert path_length(d.path) <= 3.0 + 1e-9 and d.path[-1] == pytest.approx(d.pose.xy)
        ends[clearance] = d.pose.xy
    assert _room_at(state.island_grid, ends[0.0]) < 0.45  # cut where the path hugs the wall
    assert _room_at(state.island_grid, ends[0.45]) >= 0.45
    assert np.linalg.norm(ends[0.45] - ends[0.0]) <= 0.25 + 1e-9


class _Env:
    """Refuses the poses it is told to; counts its moves."""

    def __init__(self, refuse: set) -> None:
        self.refuse, self.tries, self.pose = refuse, [], Pose2D(0.0, 0.0, 0.0)

    def step(self, pose: Pose2D):
        self.tries.append((pose.x, pose.y))
        blocked = (pose.x, pose.y) in self.refuse
        if not blocked:
            self.pose = pose
        return f"frame at {self.pose.x}", 0.0, False, False, {"blocked": blocked}


class _Explore:
    """Re-plans to the next pose of a script; remembers what was blocked."""

    def __init__(self, plans: list[Decision]) -> None:
        self.plans, self.blocked_at, self.replans = list(plans), [], []

    def blocked(self, xy) -> None:
        self.blocked_at.append(xy)

    def replan(self, pose: Pose2D, step: int) -> Decision:
        self.replans.append((pose, step))
        return self.plans.pop(0)


def _to(x: float, done: bool = False) -> Decision:
    return Decision(Pose2D(x, 0.0, 0.0), np.array([[0.0, 0.0], [x, 0.0]]), done=done)


def test_a_refused_move_is_replanned_within_the_step():
    env, explore = _Env({(1.0, 0.0), (2.0, 0.0)}), _Explore([_to(2.0), _to(3.0), _to(4.0)])
    here = Pose2D(0.0, 0.0, 0.0)
    moved = move(env, explore, here, _to(1.0), step=5)
    assert moved.obs == "frame at 3.0" and not moved.blocked and moved.refused == 2
    assert moved.decision.pose.x == 3.0
    assert explore.blocked_at == [(1.0, 0.0), (2.0, 0.0)]
    assert explore.replans == [(here, 5), (here, 5)]  # from where the robot stands, same step


def test_tries_are_bounded_and_zero_retries_spend_the_step():
    refuse = {(float(x), 0.0) for x in range(1, 10)}
    env, explore = _Env(refuse), _Explore([_to(float(x)) for x in range(2, 10)])
    moved = move(env, explore, Pose2D(0.0, 0.0, 0.0), _to(1.0), step=1)
    assert moved.blocked and moved.refused == REFUSAL_RETRIES + 1
    assert len(env.tries) == REFUSAL_RETRIES + 1 and len(explore.replans) == REFUSAL_RETRIES
    env, explore = _Env({(1.0, 0.0)}), _Explore([_to(2.0)])
    moved = move(env, explore, Pose2D(0.0, 0.0, 0.0), _to(1.0), step=1, retries=0)
    assert moved.blocked and moved.refused == 1 and explore.replans == []
    # A re-plan that finds nothing left to explore ends the tries.
    env, explore = _Env({(1.0, 0.0)}), _Explore([_to(0.0, done=True), _to(2.0)])
    moved = move(env, explore, Pose2D(0.0, 0.0, 0.0), _to(1.0), step=1)
    assert moved.decision.done and moved.refused == 1 and len(env.tries) == 1


class _RefusingEnv(SyntheticEnv):
    """Refuses the first ``n`` moves of each episode, wherever they go."""

    n = 2

    def reset(self, **kwargs):
        self.left = self.n
        return super().reset(**kwargs)

    def step(self, action):
        if self.left > 0:
            self.left -= 1
            self.steps += 1
            return self.observe(), 0.0, False, False, self._info(blocked=True)
        return super().step(action)


@pytest.fixture(scope="module")
def refusing_house(catalog):
    env = _RefusingEnv(generate_house(4, catalog, "builtin"), catalog, CameraSpec().scaled(320, 240))
    questions = synthetic_questions(env)
    yield Scene(env, "synthetic:4 (builtin)", questions), next(q for q in questions if q.id == "syn-4-10")
    env.close()


def _run(scene, q, tmp_path, **config):
    desk = scene.env.house.object(q.evidence[0])
    room = scene.env.house.room(desk.room_id).name
    done = ask(q.question, scene, tmp_path, stack=Stack(grouping="rules", explore_scorer="vlm"),
               model=seeking_model(desk.category, room), relevancy=MentionScorer(desk.category, room),
               config=AgentConfig.of(max_steps=4, **config), report=False)
    return json.loads(done.episode_json.read_text())


@needs_egl
def test_refused_moves_cost_no_step_and_no_model_call(refusing_house, tmp_path):
    scene, q = refusing_house
    record = _run(scene, q, tmp_path)
    first, second = record["per_step"][:2]
    assert first["refused"] == 2 and not first["blocked"]
    assert first["pose"] != second["pose"]  # the robot moved on its first step all the same
    assert record["refused_moves"] == 2
    # One model call per step that offered directions, the step with the re-plans included.
    assert first["prompts"] and len(first["calls"]) == 1
    assert all(len(s["calls"]) == bool(s["prompts"]) for s in record["per_step"])


@needs_egl
def test_without_retries_a_refused_move_spends_the_step(refusing_house, tmp_path):
    scene, q = refusing_house
    record = _run(scene, q, tmp_path, refusal_retries=0)
    steps = record["per_step"]
    assert [s["refused"] for s in steps[:3]] == [1, 1, 0]
    assert steps[0]["blocked"] and steps[1]["blocked"] and not steps[2]["blocked"]
    assert steps[0]["pose"] == steps[1]["pose"] == steps[2]["pose"]  # two steps spent in place
    assert record["refused_moves"] == 2 and record["config"]["explore"]["refusal_retries"] == 0


@needs_egl
def test_retrieval_sends_the_model_one_frame_per_view(refusing_house, tmp_path):
    """Three steps spent in place are one view: the answer reads it once (the default), or
    three times with DESIGN 3.5's retrieval (--repeated-views, the paper preset)."""
    scene, q = refusing_house
    distinct = _run(scene, q, tmp_path / "distinct", refusal_retries=0)
    repeated = _run(scene, q, tmp_path / "repeated", refusal_retries=0, distinct_views=False)
    assert sorted(r["step"] for r in repeated["retrieved"]) == [1, 2, 3, 4]  # K = 5
    kept = sorted(r["step"] for r in distinct["retrieved"])
    assert len(kept) == 2 and kept[0] in (1, 2, 3) and kept[1] == 4
