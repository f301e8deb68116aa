"""One question in one environment, as another agent sees it: plain observations in, pose goals
or an answer out. The Gymnasium environment (``efficienteqa.gym``) and a user's agent run by
``efficienteqa eval --eval.method module:Class`` (``eval.agents``) both step through it.

An observation is a dict of arrays and the question, and nothing a robot would not have:

============  =======================  ==============================================
key           value                    meaning
============  =======================  ==============================================
rgb           uint8 (H, W, 3)          the colour frame
depth         float32 (H, W)           metres along the optical axis (0: no return)
intrinsics    float32 (3, 3)           the pinhole K of both
pose          float32 (4, 4)           camera-to-world, OpenCV axes (x right, y down)
question      str                      the question, as asked
============  =======================  ==============================================

An action is a dict too: ``move(x, y, yaw)`` asks the robot to go to a floor pose (metres and
radians in the world frame, z up), ``answer(text)`` ends the episode. Each move's ``info`` says
what a robot would know of it (``envs.base.move_info``: blocked, short, reached, where it
ended); the simulator's truth (navigability, labels, the evidence) never appears.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from efficienteqa.envs.base import Environment
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D
from efficienteqa.observation import Observation

MOVE, ANSWER = 0, 1  # an action's "kind"
MAX_ANSWER_CHARS = 256
ROBOT_INFO = ("blocked", "short", "reached")  # what a move's info may pass on (move_info)


def move(x: float, y: float, yaw: float) -> dict[str, Any]:
    """The action that sends the robot to the floor pose (x, y, yaw)."""
    return {"kind": MOVE, "goal": np.array([x, y, yaw], dtype=np.float32), "answer": ""}


def answer(text: str) -> dict[str, Any]:
    """The action that answers and ends the episode."""
    return {"kind": ANSWER, "goal": np.zeros(3, dtype=np.float32),
            "answer": text[:MAX_ANSWER_CHARS]}


def observation(obs: Observation, question: str) -> dict[str, Any]:
    """A frame as another agent gets it (the table above): no labels, no instance ids."""
    return {"rgb": np.array(obs.rgb, dtype=np.uint8),
            "depth": np.array(obs.depth_m, dtype=np.float32),
            "intrinsics": np.array(obs.intrinsics, dtype=np.float32),  # copies: an agent
            "pose": np.array(obs.cam_to_world, dtype=np.float32),      # may keep them
            "question": question}


def as_observation(obs: dict[str, Any]) -> Observation:
    """The project's ``Observation`` of an observation dict, for an agent that wants the
    project's own perception or mapping on it (no labels: it is what a robot has)."""
    pose = np.asarray(obs["pose"], dtype=np.float64)
    forward = pose[:3, 2]
    floor = Pose2D(float(pose[0, 3]), float(pose[1, 3]), float(np.arctan2(forward[1], forward[0])))
    return Observation(rgb=np.asarray(obs["rgb"]), depth_m=np.asarray(obs["depth"]),
                       cam_to_world=pose, pose=floor,
                       intrinsics=np.asarray(obs["intrinsics"], dtype=np.float64))


def parse_action(action: Any) -> Pose2D | str:
    """A move's goal, or an answer's text; anything else fails in one line."""
    if not isinstance(action, dict) or "kind" not in action:
        raise EfficientEQAError(f"an action is a dict with 'kind' (got {type(action).__name__})",
                                fix="return efficienteqa.envs.episode.move(x, y, yaw) or "
                                    "answer(text)")
    if int(action["kind"]) == ANSWER:
        return str(action.get("answer", ""))
    goal = np.asarray(action.get("goal"), dtype=np.float64).reshape(-1)
    if goal.shape != (3,) or not np.all(np.isfinite(goal)):
        raise EfficientEQAError(f"a move's goal is three finite numbers (x, y, yaw), not {goal}",
                                fix="return efficienteqa.envs.episode.move(x, y, yaw)")
    return Pose2D(float(goal[0]), float(goal[1]), float(goal[2]))


@dataclass
class QuestionEpisode:
    """An episode of ``question`` in ``env``: ``reset`` from ``start``, then ``step`` moves
    until an answer, or until ``budget`` steps (the answer is then ""). ``steps`` counts the
    views, the start's included, as the oracle's step counts and the project's agent do: an
    answer at the start view takes 1 step, and ``budget`` steps allow ``budget - 1`` moves.
    Counts what a record needs: the steps, the moves refused, the poses."""

    env: Environment
    question: str
    budget: int
    start: Pose2D | None = None
    # Called with each view (its step, the frame with whatever the environment gives: the
    # evaluation's ground truth reads instance ids there, after the agent has seen the frame).
    on_view: Callable[[int, Observation], None] | None = None
    steps: int = 0
    refused: int = 0
    reply: str | None = None
    poses: list[Pose2D] = field(default_factory=list)

    @property
    def over(self) -> bool:
        return self.reply is not None or self.steps >= self.budget

    def reset(self) -> tuple[dict[str, Any], dict[str, Any]]:
        obs, _ = self.env.reset(options={"start": self.start} if self.start is not None else None)
        self.steps, self.refused, self.reply, self.poses = 1, 0, None, [obs.pose]
        if self.on_view is not None:
            self.on_view(self.steps, obs)
        return observation(obs, self.question), {"budget": self.budget}

    def step(self, action: Any) -> tuple[dict[str, Any] | None, dict[str, Any]]:
        """The next observation (None once answered) and what the robot knows of the move."""
        if self.over:
            raise EfficientEQAError("the episode is over", fix="reset it before stepping again")
        act = parse_action(action)
        if isinstance(act, str):
            self.reply = act
            return None, {"answered": True, "steps": self.steps}
        obs, _, _, _, info = self.env.step(act)
        self.steps += 1
        self.refused += bool(info.get("blocked"))
        self.poses.append(obs.pose)
        if self.on_view is not None:
            self.on_view(self.steps, obs)
        known = {k: info[k] for k in ROBOT_INFO if k in info}  # not a simulator's extras
        return observation(obs, self.question), {**known, "steps": self.steps,
                                                 "budget": self.budget}
