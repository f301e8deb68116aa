"""A TF tree as ROS 2 records it (``tf2_msgs/msg/TFMessage`` on ``/tf`` and ``/tf_static``).

Each transform says where a child frame is in its parent: ``p_parent = R(q) p_child + t``.
``TFTree.lookup(world, frame, stamp)`` composes the chain from ``world`` down to ``frame``
through every intermediate frame (map -> odom -> base_link -> camera_link -> optical frame).
Static transforms hold at every time; a dynamic one is interpolated between its two samples
around the stamp (linear translation, spherical rotation), as tf2 does, or taken from its nearest
sample when the stamp lies at most ``tolerance_ns`` outside its samples' span (no extrapolation
beyond that).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from efficienteqa.errors import EfficientEQAError


def frame_name(name: str) -> str:
    """ROS 1 habits (a leading "/") are dropped: "/map" and "map" are one frame."""
    return name.lstrip("/")


def normalised(q: np.ndarray) -> np.ndarray:
    norm = float(np.linalg.norm(q))
    if not math.isfinite(norm) or norm < 1e-9:
        raise ValueError(f"quaternion {q.tolist()} has no rotation")
    return q / norm


def matrix(translation: np.ndarray, quaternion: np.ndarray) -> np.ndarray:
    """4x4 of a translation (x, y, z) and a quaternion (x, y, z, w)."""
    x, y, z, w = normalised(np.asarray(quaternion, dtype=np.float64))
    out = np.eye(4)
    out[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                   [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                   [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    out[:3, 3] = translation
    return out


def quaternion_of(rotation: np.ndarray) -> np.ndarray:
    """The unit quaternion (x, y, z, w) of a 3x3 rotation (w >= 0)."""
    m = np.asarray(rotation, dtype=np.float64)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
    out = normalised(np.array(q))
    return -out if out[3] < 0 else out


def slerp(q0: np.ndarray, q1: np.ndarray, a: float) -> np.ndarray:
    """The rotation ``a`` of the way from ``q0`` to ``q1`` (shortest arc)."""
    dot = float(np.dot(q0, q1))
    if dot < 0:
        q1, dot = -q1, -dot
    if dot > 0.9995:  # nearly the same rotation: a normalised straight line is exact enough
        return normalised(q0 + a * (q1 - q0))
    theta = math.acos(min(dot, 1.0))
    return (math.sin((1 - a) * theta) * q0 + math.sin(a * theta) * q1) / math.sin(theta)


@dataclass
class _Edge:
    parent: str
    static: np.ndarray | None = None  # 4x4, for /tf_static
    stamps: list[int] = field(default_factory=list)
    translations: list[np.ndarray] = field(default_factory=list)
    rotations: list[np.ndarray] = field(default_factory=list)
    _sorted: bool = True

    def at(self, stamp_ns: int, tolerance_ns: int) -> np.ndarray | None:
        if self.static is not None:
            return self.static
        if not self._sorted:
            order = np.argsort(np.asarray(self.stamps), kind="stable")
            self.stamps = [self.stamps[i] for i in order]
            self.translations = [self.translations[i] for i in order]
            self.rotations = [self.rotations[i] for i in order]
            self._sorted = True
        stamps = self.stamps
        i = int(np.searchsorted(np.asarray(stamps), stamp_ns))
        if i < len(stamps) and stamps[i] == stamp_ns:
            return matrix(self.translations[i], self.rotations[i])
        if i == 0:
            near = 0 if stamps[0] - stamp_ns <= tolerance_ns else None
        elif i == len(stamps):
            near = i - 1 if stamp_ns - stamps[-1] <= tolerance_ns else None
        else:
            a = (stamp_ns - stamps[i - 1]) / (stamps[i] - stamps[i - 1])
            t = (1 - a) * self.translations[i - 1] + a * self.translations[i]
            return matrix(t, slerp(self.rotations[i - 1], self.rotations[i], a))
        return None if near is None else matrix(self.translations[near], self.rotations[near])


class TFTree:
    """Every transform of a recording, by child frame (a frame has one parent)."""

    def __init__(self) -> None:
        self._edges: dict[str, _Edge] = {}

    def add(self, parent: str, child: str, stamp_ns: int, translation: np.ndarray,
            rotation: np.ndarray, static: bool) -> None:
        parent, child = frame_name(parent), frame_name(child)
        edge = self._edges.get(child)
        if edge is None:
            edge = self._edges[child] = _Edge(parent)
        elif edge.parent != parent:
            raise EfficientEQAError(f"TF frame {child!r} has two parents, {edge.parent!r} and "
                                    f"{parent!r}", fix="record one TF tree (each frame one parent)")
        rotation = normalised(np.asarray(rotation, dtype=np.float64))
        translation = np.asarray(translation, dtype=np.float64)
        if static:
            edge.static = matrix(translation, rotation)
            return
        if edge.stamps and stamp_ns < edge.stamps[-1]:
            edge._sorted = False
        edge.stamps.append(stamp_ns)
        edge.translations.append(translation)
        edge.rotations.append(rotation)

    @property
    def frames(self) -> set[str]:
        return set(self._edges) | {e.parent for e in self._edges.values()}

    def chain(self, world: str, frame: str) -> list[str]:
        """The frames from ``frame`` up to ``world`` (both included), or a one-line error that
        says where the chain ends instead."""
        world, frame = frame_name(world), frame_name(frame)
        known = sorted(self.frames)
        if frame not in self._edges and frame != world:
            raise EfficientEQAError(
                f"no TF path from {world!r} to the camera frame {frame!r}: no transform names "
                f"it (frames in /tf and /tf_static: {', '.join(known) or 'none'})",
                fix="record /tf and /tf_static with the camera's transforms")
        path = [frame]
        while path[-1] != world:
            edge = self._edges.get(path[-1])
            if edge is None:
                raise EfficientEQAError(
                    f"no TF path from {world!r} to {frame!r}: the chain "
                    f"{' <- '.join(reversed(path))} ends at {path[-1]!r}",
                    fix=f"give the world frame, e.g. ?world={path[-1]} after the path, or record "
                        f"the transform to {world!r}")
            if edge.parent in path:
                raise EfficientEQAError(f"the TF tree has a loop through {edge.parent!r}",
                                        fix="record one TF tree")
            path.append(edge.parent)
        return path

    def lookup(self, world: str, frame: str, stamp_ns: int, tolerance_ns: int) -> np.ndarray | None:
        """4x4 pose of ``frame`` in ``world`` at ``stamp_ns``; None where a dynamic transform of
        the chain has no sample near enough."""
        path = self.chain(world, frame)
        pose = np.eye(4)
        for child in path[:-1]:
            step = self._edges[child].at(stamp_ns, tolerance_ns)
            if step is None:
                return None
            pose = step @ pose
        return pose
