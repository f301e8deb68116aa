"""The canonical frame, the camera model and poses.

World frame: x and y span the floor, z points up, metres; the floor of the scene is z = 0.
Robot pose: (x, y, yaw) with yaw in radians, counter-clockwise from +x.
Camera frame: OpenCV optical convention (x right, y down, z forward).
``cam_to_world`` is the 4x4 transform taking camera coordinates to world coordinates.
Environment adapters convert their own conventions to these; nothing else flips axes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CameraSpec:
    """A pinhole RGB-D camera mounted on the robot (DESIGN 3.1 defaults)."""

    width: int = 640
    height: int = 480
    hfov_deg: float = 120.0
    height_m: float = 1.5
    pitch_deg: float = -30.0  # negative looks down

    @property
    def fx(self) -> float:
        return (self.width / 2) / math.tan(math.radians(self.hfov_deg) / 2)

    @property
    def vfov_deg(self) -> float:
        half = math.atan(math.tan(math.radians(self.hfov_deg) / 2) * self.height / self.width)
        return math.degrees(2 * half)

    @property
    def fy(self) -> float:
        return (self.height / 2) / math.tan(math.radians(self.vfov_deg) / 2)

    @property
    def intrinsics(self) -> np.ndarray:
        """3x3 K with the principal point at the image centre."""
        return np.array(
            [[self.fx, 0.0, self.width / 2], [0.0, self.fy, self.height / 2], [0.0, 0.0, 1.0]]
        )

    def scaled(self, width: int, height: int) -> CameraSpec:
        return CameraSpec(width, height, self.hfov_deg, self.height_m, self.pitch_deg)


@dataclass(frozen=True)
class Pose2D:
    """Robot pose on the floor: metres and radians (yaw counter-clockwise from +x)."""

    x: float
    y: float
    yaw: float

    @property
    def xy(self) -> np.ndarray:
        return np.array([self.x, self.y])


def wrap_angle(angle_rad: float | np.ndarray) -> float | np.ndarray:
    """Wrap to [-pi, pi)."""
    return (angle_rad + math.pi) % (2 * math.pi) - math.pi


def camera_to_world(pose: Pose2D, camera: CameraSpec) -> np.ndarray:
    """4x4 cam_to_world for a camera at ``camera.height_m`` looking along yaw, pitched."""
    cy, sy = math.cos(pose.yaw), math.sin(pose.yaw)
    pitch = math.radians(camera.pitch_deg)
    cp, sp = math.cos(pitch), math.sin(pitch)
    forward = np.array([cy * cp, sy * cp, sp])
    right = np.array([sy, -cy, 0.0])
    down = np.cross(forward, right)
    pose_mat = np.eye(4)
    pose_mat[:3, 0] = right
    pose_mat[:3, 1] = down
    pose_mat[:3, 2] = forward
    pose_mat[:3, 3] = [pose.x, pose.y, camera.height_m]
    return pose_mat


def backproject(depth_m: np.ndarray, intrinsics: np.ndarray, cam_to_world: np.ndarray) -> np.ndarray:
    """World points (H, W, 3) of every pixel; pixels with depth 0 map to the camera centre."""
    h, w = depth_m.shape
    u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    x = (u - intrinsics[0, 2]) / intrinsics[0, 0] * depth_m
    y = (v - intrinsics[1, 2]) / intrinsics[1, 1] * depth_m
    pts = np.stack([x, y, depth_m], axis=-1)
    return pts @ cam_to_world[:3, :3].T + cam_to_world[:3, 3]
