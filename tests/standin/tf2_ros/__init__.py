"""A stand-in for ``tf2_ros`` (rclpy's tf2): ``Buffer``, ``TransformListener`` and tf2's
exceptions, as far as the ROS 2 adapter uses them.

As in tf2, the buffer keeps the transforms ``/tf`` and ``/tf_static`` carried (a tree of parent
-> child edges, the dynamic ones for ``cache_time``, 10 s) and ``lookup_transform(target,
source, time)`` chains them through their common ancestor at ``time``, interpolating each
dynamic edge between the stamps around it; time 0 is the latest time every edge on the chain
has. It raises ``LookupException`` for an unknown frame, ``ConnectivityException`` for frames
of separate trees and ``ExtrapolationException`` for a time outside an edge's data (newer than
its newest stamp: not received yet). As in rclpy's tf2_ros, the ``timeout`` of
``lookup_transform``/``can_transform`` waits by sleeping, without spinning any node: a
single-threaded caller receives nothing meanwhile.
"""

from __future__ import annotations

import time as _time
from bisect import bisect_left

import numpy as np
from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3
from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile
from rclpy.time import Time
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage

from tf2_ros._math import interpolate, matrix_quaternion, to_matrix

STANDIN = True

__all__ = ["Buffer", "ConnectivityException", "ExtrapolationException",
           "InvalidArgumentException", "LookupException", "TimeoutException",
           "TransformException", "TransformListener"]


class TransformException(Exception):
    pass


class LookupException(TransformException):
    pass


class ConnectivityException(TransformException):
    pass


class ExtrapolationException(TransformException):
    pass


class InvalidArgumentException(TransformException):
    pass


class TimeoutException(TransformException):
    pass


def _matrix(t: Transform) -> np.ndarray:
    r = t.rotation
    return to_matrix([t.translation.x, t.translation.y, t.translation.z], [r.x, r.y, r.z, r.w])


class Buffer:
    def __init__(self, cache_time: Duration | None = None, node=None) -> None:
        self._cache_ns = (cache_time or Duration(seconds=10)).nanoseconds
        self._parent: dict[str, str] = {}
        self._static: dict[str, np.ndarray] = {}
        self._dynamic: dict[str, list[tuple[int, np.ndarray]]] = {}

    def set_transform(self, transform: TransformStamped, authority: str) -> None:
        child, stamp = transform.child_frame_id, Time.from_msg(transform.header.stamp).nanoseconds
        self._parent[child] = transform.header.frame_id
        history = self._dynamic.setdefault(child, [])
        stamps = [s for s, _ in history]
        i = bisect_left(stamps, stamp)
        if i < len(history) and history[i][0] == stamp:
            history[i] = (stamp, _matrix(transform.transform))
        else:
            history.insert(i, (stamp, _matrix(transform.transform)))
        newest = history[-1][0]
        while history and history[0][0] < newest - self._cache_ns:
            history.pop(0)

    def set_transform_static(self, transform: TransformStamped, authority: str) -> None:
        self._parent[transform.child_frame_id] = transform.header.frame_id
        self._static[transform.child_frame_id] = _matrix(transform.transform)

    def _known(self, frame: str) -> bool:
        return frame in self._parent or frame in self._parent.values()

    def _chain(self, frame: str) -> list[str]:
        chain = [frame]
        while chain[-1] in self._parent:
            chain.append(self._parent[chain[-1]])
        return chain

    def _edge(self, child: str, stamp: int) -> np.ndarray:
        if child in self._static:
            return self._static[child]
        history = self._dynamic[child]
        stamps = [s for s, _ in history]
        if stamp > stamps[-1]:
            raise ExtrapolationException(
                f"Lookup would require extrapolation into the future. Requested time "
                f"{stamp / 1e9:.6f} but the latest data is at time {stamps[-1] / 1e9:.6f}, when "
                f"looking up transform from frame [{child}] to frame [{self._parent[child]}]")
        if stamp < stamps[0]:
            raise ExtrapolationException(
                f"Lookup would require extrapolation into the past. Requested time "
                f"{stamp / 1e9:.6f} but the earliest data is at time {stamps[0] / 1e9:.6f}, when "
                f"looking up transform from frame [{child}] to frame [{self._parent[child]}]")
        i = bisect_left(stamps, stamp)
        if stamps[i] == stamp:
            return history[i][1]
        (s0, a), (s1, b) = history[i - 1], history[i]
        return interpolate(a, b, (stamp - s0) / (s1 - s0))

    def _resolve(self, target: str, source: str, time: Time) -> tuple[np.ndarray, int]:
        for frame, argument in ((target, "target_frame"), (source, "source_frame")):
            if not self._known(frame):
                raise LookupException(f'"{frame}" passed to lookupTransform argument {argument} '
                                      "does not exist. ")
        up_source, up_target = self._chain(source), self._chain(target)
        common = next((f for f in up_source if f in up_target), None)
        if common is None:
            raise ConnectivityException(f"Could not find a connection between '{target}' and "
                                        f"'{source}' because they are not part of the same "
                                        "tree. Tf has two or more unconnected trees.")
        edges = (up_source[:up_source.index(common)], up_target[:up_target.index(common)])
        stamp = time.nanoseconds
        if stamp == 0:  # the latest time every dynamic edge has
            latest = [self._dynamic[c][-1][0] for part in edges for c in part if c in self._dynamic]
            stamp = min(latest) if latest else 0

        def up(part: list[str]) -> np.ndarray:  # common <- frame
            out = np.eye(4)
            for child in reversed(part):
                out = out @ self._edge(child, stamp)
            return out

        return np.linalg.inv(up(edges[1])) @ up(edges[0]), stamp

    def lookup_transform(self, target_frame: str, source_frame: str, time: Time,
                         timeout: Duration = Duration()) -> TransformStamped:
        self.can_transform(target_frame, source_frame, time, timeout)
        matrix, stamp = self._resolve(target_frame, source_frame, time)
        x, y, z, w = matrix_quaternion(matrix[:3, :3])
        tx, ty, tz = matrix[:3, 3]
        return TransformStamped(
            header=Header(stamp=Time(nanoseconds=stamp).to_msg(), frame_id=target_frame),
            child_frame_id=source_frame,
            transform=Transform(translation=Vector3(x=float(tx), y=float(ty), z=float(tz)),
                                rotation=Quaternion(x=float(x), y=float(y), z=float(z),
                                                    w=float(w))))

    def can_transform(self, target_frame: str, source_frame: str, time: Time,
                      timeout: Duration = Duration(), return_debug_tuple: bool = False) -> bool:
        deadline = _time.monotonic() + timeout.nanoseconds / 1e9
        while True:
            try:
                self._resolve(target_frame, source_frame, time)
                ok, why = True, ""
            except TransformException as error:
                ok, why = False, str(error)
            if ok or _time.monotonic() >= deadline:
                return (ok, why) if return_debug_tuple else ok
            _time.sleep(0.02)  # as rclpy's tf2_ros: nothing is spun meanwhile


class TransformListener:
    """Subscribes ``node`` to ``/tf`` and ``/tf_static`` (with tf2_ros's QoS) and fills
    ``buffer``; the node's owner spins it."""

    def __init__(self, buffer: Buffer, node, *, spin_thread: bool = False, qos=None,
                 static_qos=None, tf_topic: str = "/tf", tf_static_topic: str = "/tf_static",
                 static_only: bool = False) -> None:
        if spin_thread:
            raise NotImplementedError("the stand-in spins no threads")
        self.buffer, self.node = buffer, node
        static_qos = static_qos or QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                                              history=HistoryPolicy.KEEP_LAST)
        if not static_only:
            qos = qos or QoSProfile(depth=100, durability=DurabilityPolicy.VOLATILE,
                                    history=HistoryPolicy.KEEP_LAST)
            self.tf_sub = node.create_subscription(TFMessage, tf_topic, self.callback, qos)
        self.tf_static_sub = node.create_subscription(TFMessage, tf_static_topic,
                                                      self.static_callback, static_qos)

    def unregister(self) -> None:
        if hasattr(self, "tf_sub"):
            self.node.destroy_subscription(self.tf_sub)
        self.node.destroy_subscription(self.tf_static_sub)

    def callback(self, data: TFMessage) -> None:
        for transform in data.transforms:
            self.buffer.set_transform(transform, "default_authority")

    def static_callback(self, data: TFMessage) -> None:
        for transform in data.transforms:
            self.buffer.set_transform_static(transform, "default_authority")
