"""A simulated robot on the stand-in ROS 2 graph (``rclpy``'s docstring): a synthetic house seen
through an RGB-D camera, its tf and a Nav2 ``navigate_to_pose`` that takes goals.

Whenever any node on the graph is spun, the robot (another process, as on a real robot):

- moves along its current goal (``move_s`` seconds from start to end, in a straight line);
- publishes tf at ``tf_hz``: ``map -> odom`` (localization: ``odom_offset``, so odometry alone
  is off by it) and ``odom -> base_link`` (odometry), stamped now; ``base_link ->
  camera_color_optical_frame`` once, on ``/tf_static`` (transient local), with the synthetic
  camera's mount (``height_m`` up, pitched, optical axes);
- publishes at ``fps`` the colour image (rgb8 or bgr8, rows padded by ``row_padding`` bytes),
  the depth image registered to it (16UC1 millimetres or 32FC1 metres, stamped ``depth_lag_s``
  after the colour image), and the camera info (K in ROS's pixel convention: the first pixel's
  centre at (0, 0)), all rendered by the synthetic house at the robot's pose at that moment.

Goals (``PoseStamped`` in ``map``) end as Nav2's would: a navigable goal is reached
(SUCCEEDED); a goal that is not navigable fails where the robot stood (ABORTED); ``short(start,
goal)`` returning a fraction makes the robot stop that far along its way and fail (ABORTED);
``stall`` keeps every goal running, the robot still, until it is cancelled (CANCELED). A goal
in another frame than ``map`` is rejected, and so is every goal with ``reject``. Each accepted
goal is noted in ``goals``, where each goal that ran its course left the robot in ``ended``,
each cancel in ``cancels``, each ``initialpose`` message in ``initial_poses``.
"""

from __future__ import annotations

import math
import time
from array import array
from collections.abc import Callable

import numpy as np
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import (
    PoseWithCovarianceStamped,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
)
from rclpy import _graph
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage
from tf2_ros._math import matrix_quaternion, planar

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.geometry import Pose2D, camera_to_world

OPTICAL = "camera_color_optical_frame"
DONE = (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED, GoalStatus.STATUS_ABORTED)


def _stamp(ns: int) -> TimeMsg:
    return TimeMsg(sec=ns // 10**9, nanosec=ns % 10**9)


def _transform(parent: str, child: str, matrix: np.ndarray, ns: int) -> TransformStamped:
    x, y, z, w = matrix_quaternion(matrix[:3, :3])
    tx, ty, tz = (float(v) for v in matrix[:3, 3])
    return TransformStamped(header=Header(stamp=_stamp(ns), frame_id=parent), child_frame_id=child,
                            transform=Transform(translation=Vector3(x=tx, y=ty, z=tz),
                                                rotation=Quaternion(x=float(x), y=float(y),
                                                                    z=float(z), w=float(w))))


def _between(a: Pose2D, b: Pose2D, f: float) -> Pose2D:
    turn = math.remainder(b.yaw - a.yaw, math.tau)
    return Pose2D(a.x + f * (b.x - a.x), a.y + f * (b.y - a.y), a.yaw + f * turn)


class Goal:
    """One ``navigate_to_pose`` goal, as the simple commander's handle shows it."""

    def __init__(self, accepted: bool, start: Pose2D, end: Pose2D, final: int | None,
                 begin_ns: int, move_ns: int) -> None:
        self.accepted, self.start, self.end, self.final = accepted, start, end, final
        self.begin_ns, self.move_ns = begin_ns, move_ns
        self.status = GoalStatus.STATUS_EXECUTING if accepted else GoalStatus.STATUS_UNKNOWN
        self.cancel_requested = False

    def done(self) -> bool:
        return self.status in DONE

    def cancel(self) -> None:
        self.cancel_requested = True


class SimRobot:
    def __init__(self, env: SyntheticEnv, *, odom_offset: tuple[float, float, float] = (0.4, -0.3, 0.2),
                 fps: float = 30.0, tf_hz: float = 45.0, move_s: float = 0.05,
                 color_topic: str = "/camera/color/image_raw",
                 depth_topic: str = "/camera/aligned_depth_to_color/image_raw",
                 info_topic: str = "/camera/color/camera_info", colour_encoding: str = "rgb8",
                 depth_encoding: str = "16UC1", row_padding: int = 0, depth_lag_s: float = 0.004,
                 depth_stride: int = 1, publish_depth: bool = True, camera_tf: bool = True,
                 namespace: str = "",
                 short: Callable[[Pose2D, Pose2D], float | None] | None = None,
                 stall: bool = False, reject: bool = False) -> None:
        self.env, self.pose = env, env.start
        self.odom_offset = planar(*odom_offset)
        self.period_ns, self.tf_period_ns = int(1e9 / fps), int(1e9 / tf_hz)
        self.move_ns = int(move_s * 1e9)
        self.colour_encoding, self.depth_encoding = colour_encoding, depth_encoding
        self.row_padding, self.depth_lag_ns = row_padding, int(depth_lag_s * 1e9)
        self.depth_stride, self.publish_depth = depth_stride, publish_depth
        self.short, self.stall, self.reject = short, stall, reject
        self.goals: list[Pose2D] = []
        self.cancels = 0
        self.initial_poses: list[PoseWithCovarianceStamped] = []
        self.frames = 0
        self.ended: list[Pose2D] = []  # where each goal that ran its course left the robot
        self._goal: Goal | None = None
        self._last_frame_ns: int | None = None
        self._last_tf_ns: int | None = None
        self.node = node = Node("sim_robot", namespace=namespace)
        camera_qos = QoSProfile(depth=10)  # the camera driver's default: reliable, volatile
        self._colour = node.create_publisher(Image, color_topic, camera_qos)
        self._depth = node.create_publisher(Image, depth_topic, camera_qos)
        self._info = node.create_publisher(CameraInfo, info_topic, camera_qos)
        self._tf = node.create_publisher(TFMessage, "/tf", QoSProfile(depth=100))
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST)
        self._tf_static = node.create_publisher(TFMessage, "/tf_static", latched)
        amcl = node.create_publisher(PoseWithCovarianceStamped, "amcl_pose", latched)
        node.create_subscription(PoseWithCovarianceStamped, "initialpose",
                                 self.initial_poses.append, 10)
        graph = _graph.GRAPH
        graph.action_servers[node.resolve_topic_name("navigate_to_pose")] = self
        for name in ("bt_navigator", "amcl"):
            graph.lifecycle[node.resolve_topic_name(name)] = "active"
        graph.processes.append(self.tick)
        now = time.time_ns()
        self.mount = camera_to_world(Pose2D(0.0, 0.0, 0.0), env.camera)  # base_link -> optical
        if camera_tf:
            self._tf_static.publish(TFMessage(transforms=[_transform("base_link", OPTICAL,
                                                                     self.mount, now)]))
        amcl.publish(PoseWithCovarianceStamped(header=Header(stamp=_stamp(now), frame_id="map")))

    # -- Nav2's navigate_to_pose --------------------------------------------------------
    def send_goal(self, pose) -> Goal:
        now = time.time_ns()
        q = pose.pose.orientation
        goal = Pose2D(pose.pose.position.x, pose.pose.position.y,
                      math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)))
        if self.reject or pose.header.frame_id != "map":
            return Goal(False, self.pose, self.pose, None, now, 0)
        self.goals.append(goal)
        start, end, final = self.pose, self.pose, GoalStatus.STATUS_ABORTED
        if self.stall:
            final = None
        elif self.env.is_navigable(goal.x, goal.y):
            share = self.short(start, goal) if self.short is not None else None
            if share is None:
                end, final = goal, GoalStatus.STATUS_SUCCEEDED
            else:
                heading = math.atan2(goal.y - start.y, goal.x - start.x)
                stop = _between(start, Pose2D(goal.x, goal.y, heading), share)
                if self.env.is_navigable(stop.x, stop.y):
                    end = Pose2D(stop.x, stop.y, heading)
        self._goal = Goal(True, start, end, final, now, self.move_ns)
        return self._goal

    # -- the robot's own process ----------------------------------------------------------
    def tick(self) -> None:
        now = time.time_ns()
        moving = self._advance(now)  # odometry is continuous: tf follows every change at once
        if moving or self._last_tf_ns is None or now - self._last_tf_ns >= self.tf_period_ns:
            self._last_tf_ns = now
            odom_base = np.linalg.inv(self.odom_offset) @ planar(self.pose.x, self.pose.y,
                                                                 self.pose.yaw)
            self._tf.publish(TFMessage(transforms=[
                _transform("map", "odom", self.odom_offset, now),
                _transform("odom", "base_link", odom_base, now)]))
        if self._last_frame_ns is None or now - self._last_frame_ns >= self.period_ns:
            self._last_frame_ns = now
            self._publish_frame(now)

    def _advance(self, now: int) -> bool:
        """Moves along the current goal; whether the robot moved or its goal ended."""
        goal = self._goal
        if goal is None or goal.done():
            return False
        if goal.cancel_requested:
            self.cancels += 1
            goal.status = GoalStatus.STATUS_CANCELED  # it stops where it is
            return True
        if goal.final is None:  # stalled: never moves, never ends
            return False
        f = min(1.0, (now - goal.begin_ns) / goal.move_ns) if goal.move_ns else 1.0
        self.pose = goal.end if f >= 1.0 else _between(goal.start, goal.end, f)
        if f >= 1.0:
            goal.status = goal.final
            self.ended.append(self.pose)
        return True

    def _publish_frame(self, now: int) -> None:
        obs = self.env.observe(self.pose)
        cam = self.env.camera
        header = Header(stamp=_stamp(now), frame_id=OPTICAL)
        rgb = obs.rgb[..., ::-1] if self.colour_encoding == "bgr8" else obs.rgb
        self._colour.publish(self._image(header, rgb, self.colour_encoding))
        if self.publish_depth:
            depth = obs.depth_m[:: self.depth_stride, :: self.depth_stride]
            if self.depth_encoding == "16UC1":
                depth = np.round(depth * 1000).astype(np.uint16)
            else:
                depth = np.where(depth > 0, depth, np.nan).astype(np.float32)  # no surface: NaN
            self._depth.publish(self._image(Header(stamp=_stamp(now + self.depth_lag_ns),
                                                   frame_id=OPTICAL), depth, self.depth_encoding))
        k = cam.intrinsics.copy()
        k[0, 2] -= 0.5  # ROS: the first pixel's centre is (0, 0)
        k[1, 2] -= 0.5
        p = np.zeros((3, 4))
        p[:, :3] = k
        self._info.publish(CameraInfo(header=header, height=cam.height, width=cam.width,
                                      distortion_model="plumb_bob", d=array("d", [0.0] * 5),
                                      k=k.ravel(), r=np.eye(3).ravel(), p=p.ravel()))
        self.frames += 1

    def _image(self, header: Header, pixels: np.ndarray, encoding: str) -> Image:
        rows = np.ascontiguousarray(pixels).reshape(pixels.shape[0], -1).view(np.uint8)
        padded = np.zeros((rows.shape[0], rows.shape[1] + self.row_padding), np.uint8)
        padded[:, : rows.shape[1]] = rows
        return Image(header=header, height=pixels.shape[0], width=pixels.shape[1],
                     encoding=encoding, is_bigendian=0, step=padded.shape[1],
                     data=array("B", padded.tobytes()))

    def close(self) -> None:
        graph = _graph.GRAPH
        if self.tick in graph.processes:
            graph.processes.remove(self.tick)
        self.node.destroy_node()
