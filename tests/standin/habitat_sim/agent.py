"""``habitat_sim.agent`` of the stand-in (see the package docstring).

As in Habitat-Sim, ``get_state`` reports each sensor's pose in the world (``sensor_states``):
the body's pose composed with the sensor spec's position and orientation, rotations as
quaternions with ``w, x, y, z`` attributes (numpy-quaternion's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Quaternion:
    """numpy-quaternion's ``quaternion``, as far as the adapter reads it."""

    w: float
    x: float
    y: float
    z: float


@dataclass
class SixDOFPose:
    position: np.ndarray
    rotation: Quaternion


def xyzw(rotation) -> np.ndarray:
    """[x, y, z, w] from a coefficient list or an object with x, y, z, w."""
    if hasattr(rotation, "w"):
        return np.array([rotation.x, rotation.y, rotation.z, rotation.w], float)
    q = np.asarray(rotation, float)
    assert q.shape == (4,), "rotations are [x, y, z, w] coefficients"
    return q / np.linalg.norm(q)


def multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The Hamilton product of two [x, y, z, w] quaternions (``a`` applied after ``b``)."""
    va, wa, vb, wb = a[:3], a[3], b[:3], b[3]
    return np.array([*(wa * vb + wb * va + np.cross(va, vb)), wa * wb - va @ vb])


def matrix(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def about_x(angle: float) -> np.ndarray:
    return np.array([math.sin(angle / 2), 0.0, 0.0, math.cos(angle / 2)])


def sensor_pose(state: AgentState, spec) -> tuple[np.ndarray, np.ndarray]:
    """World position and [x, y, z, w] rotation of the sensor ``spec`` on a body at ``state``."""
    pitch, yaw, roll = spec.orientation
    assert yaw == 0 and roll == 0, "the stand-in pitches sensors only"
    q_body = xyzw(state.rotation)
    position = np.asarray(state.position, float) + matrix(q_body) @ np.asarray(spec.position, float)
    return position, multiply(q_body, about_x(pitch))


class AgentConfiguration:
    def __init__(self) -> None:
        self.height = 1.5
        self.radius = 0.1
        self.sensor_specifications: list = []


class AgentState:
    def __init__(self) -> None:
        self.position = np.zeros(3)
        self.rotation: object = [0.0, 0.0, 0.0, 1.0]
        self.sensor_states: dict[str, SixDOFPose] = {}


class Agent:
    def __init__(self, config: AgentConfiguration) -> None:
        self.config = config
        self.state = AgentState()

    def set_state(self, state: AgentState, reset_sensors: bool = True,
                  infer_sensor_states: bool = True, is_initial: bool = False) -> None:
        self.state = AgentState()
        self.state.position = np.array(state.position, dtype=float)
        self.state.rotation = list(np.asarray(state.rotation, dtype=float)) \
            if not hasattr(state.rotation, "w") else state.rotation

    def get_state(self) -> AgentState:
        out = AgentState()
        out.position, out.rotation = self.state.position.copy(), self.state.rotation
        for spec in self.config.sensor_specifications:
            position, q = sensor_pose(self.state, spec)
            out.sensor_states[spec.uuid] = SixDOFPose(position, Quaternion(q[3], *q[:3]))
        return out
