"""Rigid transforms for the stand-in's tf: 4x4 matrices and (x, y, z, w) quaternions (its own
code: the tests compare the adapter's conversions with these)."""

from __future__ import annotations

import math

import numpy as np


def quaternion_matrix(q) -> np.ndarray:
    x, y, z, w = np.asarray(q, float) / np.linalg.norm(np.asarray(q, float))
    return np.array([[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]])


def matrix_quaternion(rot: np.ndarray) -> np.ndarray:
    """(x, y, z, w) of a rotation matrix (Shepperd's method: the largest diagonal term)."""
    m = np.asarray(rot, float)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    terms = [trace, m[0, 0], m[1, 1], m[2, 2]]
    i = int(np.argmax(terms))
    if i == 0:
        s = 2 * math.sqrt(1 + trace)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    elif i == 1:
        s = 2 * math.sqrt(1 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif i == 2:
        s = 2 * math.sqrt(1 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2 * math.sqrt(1 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
    return np.array(q)


def to_matrix(translation, quaternion) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = quaternion_matrix(quaternion)
    out[:3, 3] = translation
    return out


def planar(x: float, y: float, yaw: float, z: float = 0.0) -> np.ndarray:
    """The 4x4 of a pose on the floor."""
    c, s = math.cos(yaw), math.sin(yaw)
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    out[:3, 3] = [x, y, z]
    return out


def interpolate(a: np.ndarray, b: np.ndarray, f: float) -> np.ndarray:
    """Between two transforms: the translation linearly, the rotation by slerp."""
    qa, qb = matrix_quaternion(a[:3, :3]), matrix_quaternion(b[:3, :3])
    dot = float(np.dot(qa, qb))
    if dot < 0:
        qb, dot = -qb, -dot
    if dot > 0.9995:
        q = qa + f * (qb - qa)
    else:
        theta = math.acos(dot)
        q = (math.sin((1 - f) * theta) * qa + math.sin(f * theta) * qb) / math.sin(theta)
    return to_matrix(a[:3, 3] + f * (b[:3, 3] - a[:3, 3]), q)
