"""The agent needs only what a robot gives: frames with their pose, and what each move did. The
scene's oracles (navigability, extent, floor area) are for the evaluation, never the agent."""

from __future__ import annotations

import math
from typing import Any

import pytest

from agent_stubs import seeking_model
from conftest import needs_egl
from efficienteqa.agent import AgentConfig, seen_budget
from efficienteqa.envs.base import Environment, SimulatedScene, move_info
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.extent import volume_around
from efficienteqa.stack import Stack, build_agent
from efficienteqa.stop.rules import StopConfig, env_step_budget, step_budget

ORACLES = ("is_navigable", "bounds", "floor_area_m2", "budget_area_m2", "house", "grid")


class RobotOnly:
    """A synthetic house seen as a robot sees it: reading any oracle fails the test."""

    def __init__(self, env: SyntheticEnv, shorten: float = 1.0) -> None:
        self._env, self._shorten = env, shorten
        self.camera = env.camera
        self.goals: list[Pose2D] = []

    def __getattr__(self, name: str) -> Any:
        if name in ORACLES:
            raise AssertionError(f"the agent read the scene's {name}")
        raise AttributeError(name)

    def reset(self, *, seed=None, options=None):
        return self._env.reset(seed=seed, options=options)

    def step(self, action: Pose2D):
        """Moves ``shorten`` of the way (a navigation stack that stops short), else refused."""
        self.goals.append(action)
        here = self._env.pose
        goal = Pose2D(here.x + self._shorten * (action.x - here.x),
                      here.y + self._shorten * (action.y - here.y), action.yaw)
        obs, reward, done, cut, _ = self._env.step(goal)
        return obs, reward, done, cut, move_info(action, self._env.pose, self._env.pose == here)

    def observe(self):
        return self._env.observe()

    def close(self) -> None:
        pass


def _agent(env, config: AgentConfig):
    return build_agent(env, Stack(grouping="rules", explore_scorer="direction-logit"), config,
                       "synthetic", model=seeking_model("bed", "bedroom")).agent


def test_a_robot_environment_is_an_environment_and_not_a_simulated_scene(env_seed3):
    class Bare(RobotOnly):
        def __getattr__(self, name: str) -> Any:
            raise AttributeError(name)

    robot = Bare(env_seed3)
    assert isinstance(robot, Environment) and not isinstance(robot, SimulatedScene)
    assert isinstance(env_seed3, SimulatedScene)
    assert env_step_budget(object()) is None  # a robot: no area, so no scene budget
    assert env_step_budget(env_seed3) == step_budget(env_seed3.floor_area_m2)


@needs_egl
def test_the_agent_reads_no_scene_oracle_and_budgets_by_the_floor_it_has_seen(env_seed3):
    robot = RobotOnly(env_seed3)
    config = AgentConfig.of(stop=StopConfig(enabled=False), gate="none")
    result = _agent(env_seed3, config).run(robot, "What colour is the bed?")
    assert result.stop_reason in ("budget", "explored", "searched")
    # The budget grew with the map: past the start disk's (5 steps), and the walk went past it.
    start_disk = step_budget(math.pi)
    assert result.budget > start_disk and result.steps > start_disk
    assert result.steps <= result.budget <= max(result.steps, seen_budget(result.state))


@needs_egl
def test_the_evaluation_budget_wins_over_the_seen_floor(env_seed3):
    config = AgentConfig.of(stop=StopConfig(enabled=False), gate="none")
    result = _agent(env_seed3, config).run(RobotOnly(env_seed3), "What colour is the bed?",
                                           budget=3)
    assert result.budget == 3 and result.steps <= 3


@needs_egl
def test_a_move_that_falls_short_is_planned_on_from_where_it_ended(env_seed3):
    robot = RobotOnly(env_seed3, shorten=0.5)
    config = AgentConfig.of(max_steps=5, gate="none", steering="none")
    result = _agent(env_seed3, config).run(robot, "What colour is the bed?")
    moved = [r for r in result.records if r.decision and not r.blocked][:-1]
    assert moved and any(r.short for r in moved)
    # Each step starts where the last move ended, not at the goal it was sent to.
    for record, goal, after in zip(result.records, robot.goals, result.records[1:]):
        if record.short:
            assert math.dist(after.pose[:2], (goal.x, goal.y)) > 0.2


def test_move_info_says_blocked_short_and_where_the_robot_ended():
    goal = Pose2D(2.0, 0.0, 0.0)
    assert move_info(goal, Pose2D(2.0, 0.05, 0.1), False) == {
        "blocked": False, "short": False, "reached": (2.0, 0.05, 0.1)}
    assert move_info(goal, Pose2D(1.0, 0.0, 0.0), False)["short"]
    assert move_info(goal, Pose2D(2.0, 0.0, 1.0), False)["short"]  # facing elsewhere
    assert move_info(goal, Pose2D(0.0, 0.0, 0.0), True) == {
        "blocked": True, "short": False, "reached": (0.0, 0.0, 0.0)}


def test_the_map_is_a_square_around_the_start_on_the_voxel_lattice():
    spec = volume_around((3.04, -7.33), 40.0)
    assert spec.shape[:2] == (400, 400)
    x0, y0, _ = spec.origin
    assert x0 <= 3.04 - 19.9 and x0 + 40 >= 3.04 + 19.9 and y0 <= -7.33 - 19.9
    assert round(x0 / 0.1) * 0.1 == pytest.approx(x0) and round(y0 / 0.1) * 0.1 == pytest.approx(y0)
    with pytest.raises(ValueError, match="at least"):
        volume_around((0.0, 0.0), 1.0)


class FramesWalk:
    """A recorded walk held in memory: the frames of ``poses`` in a synthetic house."""

    recorded = True

    def __init__(self, env: SyntheticEnv, poses: list[Pose2D]) -> None:
        self.camera = env.camera
        self._frames = [env.observe(p) for p in poses]
        self._at = 0
        self.goals: list[Pose2D] = []

    @property
    def length(self) -> int:
        return len(self._frames)

    def reset(self, *, seed=None, options=None):
        self._at = 0
        return self._frames[0], {}

    def step(self, action: Pose2D):
        self.goals.append(action)
        ended = self._at + 1 >= len(self._frames)
        self._at = min(self._at + 1, len(self._frames) - 1)
        return self._frames[self._at], 0.0, ended, False, {"blocked": False, "short": False}

    def observe(self):
        return self._frames[self._at]

    def close(self) -> None:
        pass


@needs_egl
def test_a_recorded_walk_is_read_in_order_to_its_end_without_planning(env_seed3):
    from efficienteqa.envs.base import is_recording

    start = env_seed3.start
    poses = [Pose2D(start.x, start.y, start.yaw + k * math.pi / 3) for k in range(6)]
    walk = FramesWalk(env_seed3, poses)
    assert is_recording(walk) and not is_recording(env_seed3)
    config = AgentConfig.of(stop=StopConfig(enabled=False), gate="none")
    result = _agent(env_seed3, config).run(walk, "What colour is the bed?")
    assert (result.steps, result.budget, result.stop_reason) == (6, 6, "ended")
    assert [r.pose for r in result.records] == [(p.x, p.y, p.yaw) for p in poses]
    assert all(not r.decision for r in result.records)  # nothing was planned
    assert len(result.retrieved) == min(6, config.answer.top_k)
    assert result.state.explored.sum() > 0  # the frames were mapped
    short = _agent(env_seed3, config).run(FramesWalk(env_seed3, poses), "What colour is the bed?",
                                          budget=4)
    assert (short.steps, short.stop_reason) == (4, "budget")
