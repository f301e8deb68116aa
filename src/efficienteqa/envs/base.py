"""The environment contract (Gymnasium-like, DESIGN 4), in the canonical frame.

``Environment`` is what a robot gives: ``reset(seed=, options=) -> (obs, info)`` and
``step(target_pose) -> (obs, reward, terminated, truncated, info)``. An action is the next
pose, a goal (the planner asks for a collision-free path of at most 3 m); the observation holds
the pose the robot reports afterwards, wherever it ended, and ``info`` says what the move did
(``move_info``): ``blocked`` (refused or failed: the robot did not move), ``short`` (it ended
away from the goal). The agent reads nothing else.

``SimulatedScene`` adds what only a simulator knows (navigability, extent, floor area): the
evaluation reads it (start poses, the benchmark's step budget, ground truth), the agent never.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.observation import Observation


@dataclass(frozen=True)
class DoorSides:
    """Where a door is and which rooms it joins: ``rooms`` in the order people name them ("the
    door between the kitchen and the hallway"; None for the outside), ``(x, y)`` a point of its
    wall line and ``normal`` a unit vector across that line pointing to ``rooms[0]``'s side."""

    rooms: tuple[str | None, str | None]
    x: float
    y: float
    normal: tuple[float, float]

    def side(self, x: float, y: float) -> str | None:
        """The room on the side of the door's wall line where the point (x, y) lies."""
        ahead = (x - self.x) * self.normal[0] + (y - self.y) * self.normal[1]
        return self.rooms[0] if ahead > 0 else self.rooms[1]


@dataclass(frozen=True)
class ObjectLabel:
    """What the semantic sensor knows about an instance id. ``state`` only where the object has
    one ("on"/"off", "open"/"closed"); ``room`` is the name of the room it stands in; ``door``,
    for doors, the rooms on either side. A label is what the scene knows, not what a frame shows:
    perception names a room only when the frame shows it."""

    category: str
    colour: str | None
    state: str | None
    room: str | None
    door: DoorSides | None = None


class SceneLabels(Protocol):
    """The semantic sensor of a scene: labels of instance ids and names of rooms at floor points."""

    def label(self, instance_id: int) -> ObjectLabel | None: ...

    def room_at(self, x: float, y: float) -> str | None: ...


# A move that ends farther than this from its goal (metres, or radians of heading) fell short.
SHORT_M, SHORT_RAD = 0.25, 0.35


def move_info(goal: Pose2D, reached: Pose2D, blocked: bool) -> dict[str, Any]:
    """``step``'s info about a move to ``goal`` that ended at ``reached``: ``blocked`` (the
    robot did not move), ``short`` (it moved, but ended away from the goal), ``reached``."""
    away = math.hypot(reached.x - goal.x, reached.y - goal.y)
    turn = abs(math.remainder(reached.yaw - goal.yaw, math.tau))
    return {"blocked": blocked, "short": not blocked and (away > SHORT_M or turn > SHORT_RAD),
            "reached": (reached.x, reached.y, reached.yaw)}


@runtime_checkable
class Environment(Protocol):
    """What a robot gives the agent: frames with their camera pose, and moves to pose goals."""

    camera: CameraSpec

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]: ...

    def step(
        self, action: Pose2D
    ) -> tuple[Observation, float, bool, bool, dict[str, Any]]: ...

    def observe(self) -> Observation: ...

    def close(self) -> None: ...


@runtime_checkable
class Recording(Environment, Protocol):
    """A walk recorded beforehand (OpenEQA's episodic memory): the robot cannot choose where
    to go. ``reset`` gives the first frame; ``step`` ignores its goal and gives the next frame,
    with ``terminated`` True once there is none (the observation is then the last frame
    again). ``length`` is the number of frames. The agent walks it in order: it maps each
    frame, stops reading at a relevancy outlier, and answers from the top-K frames."""

    @property
    def length(self) -> int: ...


def is_recording(env: object) -> bool:
    """Whether ``env`` replays a recorded walk (``Recording``) rather than moving a robot."""
    return isinstance(env, Recording) and bool(getattr(env, "recorded", False))


@runtime_checkable
class SimulatedScene(Environment, Protocol):
    """An environment that is a simulated scene: what evaluation may read beside the agent."""

    def is_navigable(self, x: float, y: float) -> bool: ...

    @property
    def floor_area_m2(self) -> float: ...

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min_xyz, max_xyz) of the scene in metres."""
        ...


def scene_labels(env: object) -> SceneLabels | None:
    """The environment's semantic sensor, where it has one (a recording without labels: None)."""
    from efficienteqa.errors import EfficientEQAError

    labels = getattr(env, "scene_labels", None)
    if labels is None:
        return None
    try:
        return labels()
    except EfficientEQAError:  # a recording without labels
        return None


def is_rendered(env: object) -> bool:
    """Whether ``env``'s frames are a simulator's renders: a simulated scene, or a recording
    that carries a simulator's labels. Not: a robot, a robot's recording."""
    return isinstance(env, SimulatedScene) or scene_labels(env) is not None


def looks_real(env: object) -> bool:
    """Whether ``env``'s frames look like a camera's: a robot's, a robot's recording, or a
    simulated scene textured from photographs (``scanned``: HM3D in Habitat-Sim)."""
    return not is_rendered(env) or bool(getattr(env, "scanned", False))
