"""The frame contract: what every environment adapter hands the rest of the code.

An ``Observation`` is one RGB-D frame in canonical form (``geometry``: x, y on the floor, z up,
metres; OpenCV camera axes). A ``PromptPoint`` is a lettered floor point marked on a frame
(visual prompting, DESIGN 3.3). Both sit at the bottom of the layers so that environments,
mapping, perception and exploration share them without importing each other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from efficienteqa.geometry import Pose2D


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
        """Share of pixels without depth (DESIGN 3.1: frames >= 0.5 are not sent to models)."""
        return float(np.mean(self.depth_m <= 0))


@dataclass(frozen=True)
class PromptPoint:
    """A lettered candidate: world floor point ``xy`` (m, z = 0) and its ``pixel`` (u, v)."""

    letter: str
    xy: tuple[float, float]
    pixel: tuple[float, float]
