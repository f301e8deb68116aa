"""Moves as a mobile base makes them, for agents other than the project's own.

``SyntheticEnv.step`` puts the robot at any free goal: the project's agent plans its own path
and asks for at most 3 m of it a step, but another agent (the Gymnasium environment, a
``--eval.method module:Class``) could ask for the far end of the house, through walls. Here a
move follows the shortest free path to the goal and goes at most ``oracle.STEP_M`` (3 m) along
it, the step the oracle's step counts assume: a farther goal ends short (``info["short"]``),
one no free path reaches is blocked and the robot stays. The yaw asked for is kept.
"""

from __future__ import annotations

from typing import Any

from efficienteqa.envs.base import Environment, move_info
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M
from efficienteqa.envs.synthetic.noise import NoisyEnv, compose, inverse
from efficienteqa.envs.synthetic.oracle import STEP_M
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.navgrid import truncate_path
from efficienteqa.observation import Observation


class PathMoves:
    """``env`` (a synthetic house, or one with a robot's noise) whose moves follow free paths,
    ``max_m`` metres at most. Under noise the path runs from where the robot truly is to where
    the goal truly lies (the goal is given in the drifted frame the robot reports), and the
    noise then acts on the shortened goal as on any other."""

    def __init__(self, env: SyntheticEnv | NoisyEnv, max_m: float = STEP_M) -> None:
        self.env, self.max_m = env, max_m
        self.camera = env.camera

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Observation, dict[str, Any]]:
        return self.env.reset(seed=seed, options=options)

    def step(self, action: Pose2D) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        house = self.env.env if isinstance(self.env, NoisyEnv) else self.env
        drift = self.env.drift if isinstance(self.env, NoisyEnv) else Pose2D(0.0, 0.0, 0.0)
        here, goal = house.pose, compose(inverse(drift), action)  # both where they truly are
        path = house.grid.shortest_path((here.x, here.y), (goal.x, goal.y), ROBOT_RADIUS_M)
        if path is None:  # inside furniture or a wall, or where no free path goes
            obs = self.env.observe()
            return obs, 0.0, False, False, move_info(action, obs.pose, True)
        end = truncate_path(path, self.max_m)
        shortened = compose(drift, Pose2D(float(end[0]), float(end[1]), goal.yaw))
        obs, reward, terminated, truncated, info = self.env.step(shortened)
        return obs, reward, terminated, truncated, {
            **info, **move_info(action, obs.pose, bool(info.get("blocked")))}

    def observe(self) -> Observation:
        return self.env.observe()

    def close(self) -> None:
        self.env.close()


def path_moves(env: Environment) -> Environment:
    """``env`` with ``PathMoves`` where it is a synthetic house (with noise or without); any
    other as it is (a robot and Habitat-Sim move along paths of their own)."""
    return PathMoves(env) if isinstance(env, (SyntheticEnv, NoisyEnv)) else env
