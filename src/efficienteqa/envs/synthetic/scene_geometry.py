"""What the synthetic renderer draws and returns: lights, the scene description and a frame.

Plain data, no OpenGL: kept out of ``render.py`` so that describing a house's scene
(``build.py``) or handling its frames needs neither moderngl nor a GL context.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from efficienteqa.envs.synthetic.mesh import MeshPart


@dataclass
class PointLight:
    """A point light: ``position`` (3,) world metres, ``colour`` (3,) RGB in [0, 1].

    Its contribution is ``colour * intensity * (1 - (d / radius_m)^2)^2`` (zero beyond
    ``radius_m``), times the Lambert term. No shadows: keep the radius inside the room.
    """

    position: tuple[float, float, float]
    colour: tuple[float, float, float] = (1.0, 0.95, 0.85)
    intensity: float = 0.6
    radius_m: float = 5.0


@dataclass
class SceneGeometry:
    """Everything drawn: parts (world frame), point lights and global lighting.

    ambient: uniform light level in [0, 1]. sun_direction: direction the sun's light travels
    (world, need not be unit). sun_intensity: its Lambert weight. sky_colour: RGB in [0, 1] of
    pixels where nothing is hit.
    """

    parts: list[MeshPart]
    lights: list[PointLight] = field(default_factory=list)
    ambient: float = 0.35
    sun_direction: tuple[float, float, float] = (-0.35, -0.25, -1.0)
    sun_intensity: float = 0.45
    sky_colour: tuple[float, float, float] = (0.62, 0.72, 0.85)


@dataclass
class Frame:
    """rgb (H, W, 3) uint8; depth_m (H, W) float32 linear depth along the optical axis, 0 where
    nothing was hit; instance (H, W) int32 part instance_id, -1 where nothing was hit.
    Row 0 is the top of the image (OpenCV)."""

    rgb: np.ndarray
    depth_m: np.ndarray
    instance: np.ndarray
