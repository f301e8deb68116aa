"""Habitat <-> canonical frames: every axis convention of the Habitat adapter, and nothing else.

Habitat: metres, y up; an agent with yaw ``theta`` (a rotation about +y) looks along its local
-z, so yaw 0 looks along world -z. Its camera frame is x right, y up, looking along -z; a
sensor's ``orientation[0]`` pitches it about its x axis (negative looks down).

Canonical (``efficienteqa.geometry``): z up, the floor at z = 0, yaw counter-clockwise from +x,
cameras in OpenCV axes (x right, y down, z forward).

A Habitat point (hx, hy, hz) on a floor at height ``floor_y`` is canonical (hx, -hz, hy -
floor_y): a proper rotation (+90 degrees about x) and a shift, so distances, areas and
handedness are kept. Habitat yaw ``theta`` is canonical yaw ``theta + pi/2`` (both look along
canonical +y at theta = 0).
"""

from __future__ import annotations

import math

import numpy as np

from efficienteqa.geometry import CameraSpec, Pose2D, wrap_angle

# Rows: canonical x, y, z as combinations of Habitat x, y, z.
HABITAT_TO_CANONICAL = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
# A Habitat camera (x right, y up, -z forward) to OpenCV axes (x right, y down, z forward).
_GL_TO_CV = np.diag([1.0, -1.0, -1.0])


def to_canonical(points_h: np.ndarray, floor_y: float) -> np.ndarray:
    """Habitat points (..., 3) -> canonical points (..., 3) with the floor at z = 0."""
    p = np.asarray(points_h, dtype=float) @ HABITAT_TO_CANONICAL.T
    p[..., 2] -= floor_y
    return p


def to_habitat(points_c: np.ndarray, floor_y: float) -> np.ndarray:
    """Canonical points (..., 3) -> Habitat points (..., 3); the inverse of ``to_canonical``."""
    p = np.array(points_c, dtype=float)
    p[..., 2] += floor_y
    return p @ HABITAT_TO_CANONICAL  # orthonormal: the inverse is the transpose


def yaw_to_canonical(theta_rad: float) -> float:
    return float(wrap_angle(theta_rad + math.pi / 2))


def yaw_to_habitat(yaw_rad: float) -> float:
    return float(wrap_angle(yaw_rad - math.pi / 2))


def yaw_quaternion(theta_rad: float) -> list[float]:
    """The rotation by ``theta_rad`` about +y as Habitat's coefficient list [x, y, z, w]."""
    return [0.0, math.sin(theta_rad / 2), 0.0, math.cos(theta_rad / 2)]


def body_quaternion(theta_rad: float, tilt_rad: float = 0.0) -> list[float]:
    """An agent body turned by ``theta_rad`` about +y, then tilted by ``tilt_rad`` about its own
    x axis (negative looks down), as Habitat's coefficient list [x, y, z, w]: the product
    yaw * tilt. ExploreEQA tilts the body this way and mounts its camera unpitched."""
    sy, cy = math.sin(theta_rad / 2), math.cos(theta_rad / 2)
    sx, cx = math.sin(tilt_rad / 2), math.cos(tilt_rad / 2)
    return [cy * sx, sy * cx, -sy * sx, cy * cx]


def quaternion_xyzw(rotation: object) -> np.ndarray:
    """[x, y, z, w] of a rotation as Habitat-Sim returns it (a numpy-quaternion, with ``w, x,
    y, z`` attributes) or as a coefficient list [x, y, z, w]."""
    if all(hasattr(rotation, k) for k in "wxyz"):
        q = np.array([getattr(rotation, k) for k in "xyzw"], dtype=float)
    else:
        q = np.asarray(rotation, dtype=float).reshape(4)
    return q / np.linalg.norm(q)


def rotation_matrix(q_xyzw: np.ndarray) -> np.ndarray:
    """The 3x3 rotation of a unit quaternion [x, y, z, w]."""
    x, y, z, w = (float(v) for v in q_xyzw)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def sensor_to_world(position_h: np.ndarray, rotation: object, floor_y: float) -> np.ndarray:
    """Canonical 4x4 cam_to_world (OpenCV axes) of a sensor whose world pose Habitat reports
    (``AgentState.sensor_states[uuid]``: a position and a rotation, the camera looking along
    its local -z): the pose the renderer used, however the sensor is mounted."""
    out = np.eye(4)
    out[:3, :3] = HABITAT_TO_CANONICAL @ rotation_matrix(quaternion_xyzw(rotation)) @ _GL_TO_CV
    out[:3, 3] = to_canonical(np.asarray(position_h, dtype=float), floor_y)
    return out


def pose_to_canonical(position_h: np.ndarray, theta_rad: float, floor_y: float) -> Pose2D:
    x, y, _ = to_canonical(np.asarray(position_h, dtype=float), floor_y)
    return Pose2D(float(x), float(y), yaw_to_canonical(theta_rad))


def camera_to_world(position_h: np.ndarray, theta_rad: float, floor_y: float,
                    camera: CameraSpec) -> np.ndarray:
    """Canonical 4x4 cam_to_world (OpenCV axes) of a Habitat agent at ``position_h`` with yaw
    ``theta_rad`` carrying ``camera`` (mounted ``height_m`` above the agent, pitched
    ``pitch_deg``: the "sensor-pitch" mount), composed the way Habitat composes it: agent yaw,
    sensor offset and pitch. Observations do not compose their pose: they read it back from the
    simulator (``sensor_to_world``); this is the reference the tests hold that to."""
    c, s = math.cos(theta_rad), math.sin(theta_rad)
    agent_rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # about +y
    p = math.radians(camera.pitch_deg)
    cp, sp = math.cos(p), math.sin(p)
    pitch_rot = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])  # about x
    cam_rot_h = agent_rot @ pitch_rot @ _GL_TO_CV
    cam_pos_h = np.asarray(position_h, dtype=float) + agent_rot @ np.array([0.0, camera.height_m, 0.0])
    out = np.eye(4)
    out[:3, :3] = HABITAT_TO_CANONICAL @ cam_rot_h
    out[:3, 3] = to_canonical(cam_pos_h, floor_y)
    return out


def triangle_area_m2(vertices_h: np.ndarray) -> float:
    """Summed floor-plan area of triangles given as Habitat vertices (3N, 3), projected on the
    horizontal plane (x, z)."""
    tri = np.asarray(vertices_h, dtype=float).reshape(-1, 3, 3)[:, :, [0, 2]]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    return float(np.abs(cross).sum() / 2)
