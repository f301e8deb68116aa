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


@dataclass
class Observation:
    """One RGB-D frame in canonical form.

    rgb: (H, W, 3) uint8. depth_m: (H, W) float32 metres along the optical axis, 0 = no
    surface. instance: (H, W) int32 object id, 0 = structure (walls, floors), -1 = nothing, or
    None where the back-end has no instance sensor. cam_to_world: 4x4 (OpenCV camera axes).
    """

    rgb: np.ndarray
    depth_m: np.ndarray
    cam_to_world: np.ndarray
    intrinsics: np.ndarray
    pose: Pose2D
    instance: np.ndarray | None = None

    @property
    def invalid_fraction(self) -> float:
        """Share of pixels without depth (SPEC 3.1: frames >= 0.5 are not sent to models)."""
        return float(np.mean(self.depth_m <= 0))


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
