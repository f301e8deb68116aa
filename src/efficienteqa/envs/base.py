"""The environment contract (Gymnasium-like, SPEC section 4), in the canonical frame.

``reset(seed=, options=) -> (obs, info)``; ``step(target_pose) -> (obs, reward, terminated,
truncated, info)``. An action is the next pose: the adapter teleports the robot there (the
planner guarantees a collision-free path of at most 3 m) and observes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.observation import Observation


@dataclass(frozen=True)
class ObjectLabel:
    """What the semantic sensor knows about an instance id. ``state`` only where the object has
    one ("on"/"off", "open"/"closed"); ``room`` is the name of the room it stands in; ``place``,
    where set, says where it is in words that name it apart ("between the kitchen and the
    hallway" for a door, as people and the questions refer to doors)."""

    category: str
    colour: str | None
    state: str | None
    room: str | None
    place: str | None = None


class SceneLabels(Protocol):
    """The semantic sensor of a scene: labels of instance ids and names of rooms at floor points."""

    def label(self, instance_id: int) -> ObjectLabel | None: ...

    def room_at(self, x: float, y: float) -> str | None: ...


@runtime_checkable
class Environment(Protocol):
    camera: CameraSpec

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]: ...

    def step(
        self, action: Pose2D
    ) -> tuple[Observation, float, bool, bool, dict[str, Any]]: ...

    def observe(self) -> Observation: ...

    def is_navigable(self, x: float, y: float) -> bool: ...

    @property
    def floor_area_m2(self) -> float: ...

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min_xyz, max_xyz) of the scene in metres."""
        ...

    def close(self) -> None: ...
