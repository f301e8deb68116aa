"""The explorer contract: map state and robot pose in, next pose out."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.state import MapState


@dataclass(frozen=True)
class Frontier:
    """A frontier: its representative cell and point (m), outward unit normal (towards the
    unexplored side, world xy) and number of member cells."""

    cell: tuple[int, int]
    xy: tuple[float, float]
    normal: tuple[float, float]
    size: int


@dataclass
class Decision:
    """The next pose and why. ``path``: (K, 2) world waypoints from the robot to ``pose``.
    ``done``: nothing left to explore (the pose is the current one)."""

    pose: Pose2D
    path: np.ndarray
    target_xy: tuple[float, float] | None = None
    frontier: Frontier | None = None
    frontiers: list[Frontier] = field(default_factory=list)
    weights: np.ndarray | None = None
    reason: str = ""
    done: bool = False


class Explorer(Protocol):
    """Chooses where to go. ``values`` is the smoothed semantic value map on ``state.spec``
    (None for explorers that ignore semantics); ``step`` counts observations (the start view is
    step 1)."""

    name: str

    def reset(self, seed: int) -> None: ...

    def decide(self, state: MapState, pose: Pose2D, values: np.ndarray | None,
               step: int) -> Decision: ...
