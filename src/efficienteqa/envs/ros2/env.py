"""A live robot on ROS 2 behind the environment contract of ``envs.base``.

What the robot must run (``Ros2Params`` names the topics and frames):

- an RGB-D camera publishing colour (``sensor_msgs/Image``, rgb8 or bgr8), depth registered to
  the colour image (the same size and optical frame; 16UC1 millimetres or 32FC1 metres) and the
  colour camera's ``CameraInfo``;
- tf from ``map`` to the camera's optical frame (localization's ``map -> odom``, odometry's
  ``odom -> base_link``, the robot description's ``base_link -> ..._optical_frame``);
- Nav2, whose ``navigate_to_pose`` action is driven through the simple commander
  (``nav2_simple_commander.robot_navigator.BasicNavigator``).

ROS 2 is imported when a robot is opened, never at import time (it comes with a ROS 2
installation, not with pip); without it the adapter refuses in one line.

One node (the simple commander's ``BasicNavigator``, itself an ``rclpy`` node) holds the camera
subscriptions and the tf listener, and the adapter spins it itself: ``observe`` waits for a
colour image stamped after the last move ended and a depth image within ``sync_tolerance_s`` of
it, then looks ``map`` -> optical frame up at the colour image's stamp, spinning until tf has it
or ``tf_timeout_s`` has passed (``Buffer.lookup_transform``'s own timeout sleeps without
spinning, so a single-threaded node would never receive the transform it waits for).

``step`` sends the goal as a ``PoseStamped`` in ``map`` and waits for Nav2's result (past
``move_timeout_s`` the goal is cancelled). A goal Nav2 rejects, or one that failed or was
cancelled where the robot did not move, is ``blocked``; one that moved and ended away from the
goal is ``short`` (``move_info``). The robot's pose is the camera's floor projection, so a goal
is where the camera should stand: on a robot whose camera sits off its rotation centre, moves
end that offset away from their goals.

A robot cannot teleport: ``reset`` observes where the robot stands; a ``start`` is refused.
Nothing of ``SimulatedScene`` is offered (no navigability, extent or floor area): the agent maps
the house as it goes and budgets by the floor it has seen.
"""

from __future__ import annotations

import logging
import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from efficienteqa.envs.base import move_info
from efficienteqa.envs.ros2.frames import (
    camera_from_info,
    check_registered,
    colour_array,
    depth_array,
    floor_pose,
    stamp_ns,
    transform_matrix,
    yaw_quaternion,
)
from efficienteqa.envs.ros2.params import Ros2Params
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.observation import Observation

log = logging.getLogger(__name__)

T = TypeVar("T")

FIX_SOURCE = ("source ROS 2 in this shell (source /opt/ros/$ROS_DISTRO/setup.bash) and run "
              "efficienteqa with the Python ROS 2 was built for")
FIX_NAV2 = "sudo apt install ros-$ROS_DISTRO-nav2-simple-commander, then source ROS 2 again"
SPIN_S = 0.02  # one spin's wait for a message
KEEP = 8  # colour and depth images kept for pairing (the newest)
STILL_M, STILL_RAD = 0.05, 0.1  # a move that ended within this of where it began did not move
CANCEL_WAIT_S = 10.0  # for Nav2 to end a cancelled goal


@dataclass(frozen=True)
class Ros2:
    """The parts of ROS 2 the adapter uses, imported once a robot is opened."""

    rclpy: Any
    Time: Any
    sensor_qos: Any
    Image: Any
    CameraInfo: Any
    PoseStamped: Any
    Buffer: Any
    TransformListener: Any
    tf_errors: tuple[type[BaseException], ...]
    BasicNavigator: Any


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def import_ros2() -> Ros2:
    """rclpy, the messages, tf2 and Nav2's simple commander, or one line saying what is missing."""
    try:
        import rclpy
        import tf2_ros
        from geometry_msgs.msg import PoseStamped
        from rclpy.qos import qos_profile_sensor_data
        from rclpy.time import Time
        from sensor_msgs.msg import CameraInfo, Image
    except ImportError as error:
        if isinstance(error, ModuleNotFoundError) and error.name and "." not in error.name:
            raise EfficientEQAError(f"ROS 2 is not sourced: Python cannot import {error.name}",
                                    fix=FIX_SOURCE) from None
        raise EfficientEQAError(f"ROS 2 cannot be imported by this Python: {_one_line(error)}",
                                fix=FIX_SOURCE) from None
    try:
        from nav2_simple_commander.robot_navigator import BasicNavigator
    except ImportError as error:
        raise EfficientEQAError(f"Nav2's simple commander cannot be imported: {_one_line(error)}",
                                fix=FIX_NAV2) from None
    errors = (tf2_ros.LookupException, tf2_ros.ConnectivityException,
              tf2_ros.ExtrapolationException)
    return Ros2(rclpy, Time, qos_profile_sensor_data, Image, CameraInfo, PoseStamped,
                tf2_ros.Buffer, tf2_ros.TransformListener, errors, BasicNavigator)


class Ros2Env:
    """A robot on a live ROS 2 graph, in the canonical frame. Opening it waits for Nav2 (unless
    ``wait_for_nav2`` is off), for the camera info and for a first frame with its transform, so a
    robot that cannot be observed fails here, before any model is loaded."""

    camera: CameraSpec  # a RosCamera: the colour camera's own K

    def __init__(self, params: Ros2Params | None = None) -> None:
        self.params = p = params or Ros2Params()
        self._ros = ros = import_ros2()
        self._own_context = not ros.rclpy.ok()
        if self._own_context:
            ros.rclpy.init()
        self._colour: deque[Any] = deque(maxlen=KEEP)
        self._depth: deque[Any] = deque(maxlen=KEEP)
        self._info: Any = None
        self._last: Observation | None = None
        self._closed = False
        self._warned: set[str] = set()
        self.steps = 0
        self.nav: Any = None
        try:
            options = {"namespace": p.namespace} if p.namespace else {}
            self.nav = nav = ros.BasicNavigator(node_name=p.node_name, **options)
            self._subscriptions = [
                nav.create_subscription(ros.Image, p.color_topic, self._colour.append, ros.sensor_qos),
                nav.create_subscription(ros.Image, p.depth_topic, self._depth.append, ros.sensor_qos),
                nav.create_subscription(ros.CameraInfo, p.info_topic, self._on_info, ros.sensor_qos)]
            self._tf = ros.Buffer()
            self._listener = ros.TransformListener(self._tf, nav)
            if p.wait_for_nav2:
                # "robot_localization" is the simple commander's word for "wait for no
                # localizer": with "amcl" it would publish an initial pose (the map's origin,
                # unless one was set) and so move a robot that is already localized.
                nav.waitUntilNav2Active(navigator=p.navigator, localizer="robot_localization")
            info = self._spin_until(lambda: self._info, p.frame_timeout_s)
            if info is None:
                raise EfficientEQAError(f"no camera info on {p.info_topic} within "
                                        f"{p.frame_timeout_s:g} s",
                                        fix=f"check the camera driver runs (ros2 topic hz "
                                            f"{p.info_topic}) and info_topic names the colour "
                                            "camera's camera_info")
            self.camera = camera_from_info(info, p.info_topic)
            self._since_ns = self._now_ns()
            first = self.observe()
            self.camera = camera_from_info(info, p.info_topic, first.cam_to_world)
            if any(abs(float(v)) > 1e-6 for v in info.d):
                log.warning("the camera info on %s has distortion coefficients (%s): frames are "
                            "used as they come, not undistorted", p.info_topic,
                            info.distortion_model)
        except BaseException:
            self.close()
            raise

    # -- the contract --------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Observation, dict[str, Any]]:
        """The robot where it stands now (``seed`` is accepted for the contract)."""
        start = (options or {}).get("start")
        if start is not None:
            raise EfficientEQAError(f"a robot cannot be set down at the start {start}",
                                    fix="drive the robot to where the episode should begin, "
                                        "then ask without --start")
        self.steps = 0
        self._since_ns = self._now_ns()
        obs = self.observe()
        return obs, {"step": 0, "pose": obs.pose}

    def step(self, action: Pose2D) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        """Nav2 to ``action`` (a goal in ``map``), then the frame where the robot ended."""
        before = self._last if self._last is not None else self.observe()
        result, timed_out = self._drive(action)
        self._since_ns = self._now_ns()
        obs = self.observe()
        moved = (math.hypot(obs.pose.x - before.pose.x, obs.pose.y - before.pose.y) > STILL_M
                 or abs(math.remainder(obs.pose.yaw - before.pose.yaw, math.tau)) > STILL_RAD)
        blocked = result != "succeeded" and not moved
        self.steps += 1
        return obs, 0.0, False, False, {**move_info(action, obs.pose, blocked), "step": self.steps,
                                        "result": result, "timed_out": timed_out}

    def observe(self) -> Observation:
        """The newest colour/depth pair stamped after the last move ended, with the camera's
        pose in ``map`` at the colour image's stamp."""
        p = self.params
        colour, depth = self._fresh_pair(self._since_ns)
        frame = p.camera_frame or colour.header.frame_id
        if not frame:
            raise EfficientEQAError(f"the colour image on {p.color_topic} names no frame_id",
                                    fix="set camera_frame to the camera's optical frame")
        if depth.header.frame_id and depth.header.frame_id != colour.header.frame_id:
            self._warn_once("frames", "depth on %s is in %s, colour in %s: depth is used as "
                            "registered to colour", p.depth_topic, depth.header.frame_id,
                            colour.header.frame_id)
        cam_to_world = transform_matrix(self._lookup(frame, colour.header.stamp).transform)
        cam_to_world[2, 3] -= p.floor_z_m
        obs = Observation(rgb=colour_array(colour, p.color_topic),
                          depth_m=depth_array(depth, p.depth_topic), cam_to_world=cam_to_world,
                          intrinsics=self.camera.intrinsics, pose=floor_pose(cam_to_world))
        self._last = obs
        return obs

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self.nav is not None:
            listener = getattr(self, "_listener", None)
            if listener is not None:
                listener.unregister()
            self.nav.destroy_node()
        if self._own_context and self._ros.rclpy.ok():
            self._ros.rclpy.shutdown()

    def __enter__(self) -> Ros2Env:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- ROS ---------------------------------------------------------------------------
    def _on_info(self, msg: Any) -> None:
        self._info = msg

    def _now_ns(self) -> int:
        return int(self.nav.get_clock().now().nanoseconds)

    def _warn_once(self, key: str, message: str, *args: object) -> None:
        if key not in self._warned:
            self._warned.add(key)
            log.warning(message, *args)

    def _spin_until(self, ready: Callable[[], T | None], timeout_s: float) -> T | None:
        """``ready()``'s first value that is not None, spinning the node between tries; None
        once ``timeout_s`` has passed."""
        deadline = time.monotonic() + timeout_s
        while True:
            value = ready()
            if value is not None:
                return value
            if time.monotonic() >= deadline:
                return None
            self._ros.rclpy.spin_once(self.nav, timeout_sec=SPIN_S)

    def _pair(self, since_ns: int) -> tuple[Any, Any] | None:
        """The newest colour image stamped at or after ``since_ns`` with a depth image, also
        after it, within the sync tolerance."""
        tolerance = round(self.params.sync_tolerance_s * 1e9)
        depths = [(stamp_ns(d.header.stamp), d) for d in self._depth]
        for colour in reversed(self._colour):
            t = stamp_ns(colour.header.stamp)
            if t < since_ns:
                continue
            near = [(abs(td - t), d) for td, d in depths if td >= since_ns]
            if near:
                gap, depth = min(near, key=lambda x: x[0])
                if gap <= tolerance:
                    return colour, depth
        return None

    def _fresh_pair(self, since_ns: int) -> tuple[Any, Any]:
        p = self.params
        pair = self._spin_until(lambda: self._pair(since_ns), p.frame_timeout_s)
        if pair is None:
            raise self._no_pair(since_ns)
        colour, depth = pair
        check_registered(colour, depth, p.color_topic, p.depth_topic)
        if (colour.width, colour.height) != (self.camera.width, self.camera.height):
            raise EfficientEQAError(f"the colour image on {p.color_topic} is {colour.width}x"
                                    f"{colour.height}, its camera info on {p.info_topic} "
                                    f"{self.camera.width}x{self.camera.height}",
                                    fix="name the colour camera's camera_info as info_topic")
        return colour, depth

    def _no_pair(self, since_ns: int) -> EfficientEQAError:
        """Why no fresh colour/depth pair came, in one line."""
        p = self.params
        wait = f"within {p.frame_timeout_s:g} s"
        fix_clock = ("check the camera publishes and this machine's clock agrees with the "
                     "camera's (chrony; use_sim_time in a simulator)")
        if not self._colour:
            return EfficientEQAError(f"no colour image on {p.color_topic} {wait}",
                                     fix=f"check the camera driver runs (ros2 topic hz {p.color_topic})")
        newest = max(stamp_ns(c.header.stamp) for c in self._colour)
        if newest < since_ns:
            return EfficientEQAError(f"no colour image on {p.color_topic} stamped after the "
                                     f"robot stopped {wait} (the newest is "
                                     f"{(since_ns - newest) / 1e9:.2f} s older)", fix=fix_clock)
        if not self._depth:
            return EfficientEQAError(f"no depth image on {p.depth_topic} {wait}",
                                     fix=f"check the camera publishes registered depth (ros2 "
                                         f"topic hz {p.depth_topic})")
        gap = min(abs(stamp_ns(d.header.stamp) - stamp_ns(c.header.stamp))
                  for c in self._colour for d in self._depth)
        return EfficientEQAError(f"no depth image on {p.depth_topic} within sync_tolerance_s "
                                 f"{p.sync_tolerance_s:g} s of a fresh colour image on "
                                 f"{p.color_topic} {wait} (the nearest are {gap / 1e9:.3f} s "
                                 "apart)", fix="raise sync_tolerance_s, or publish depth with "
                                                "the colour image's stamps")

    def _lookup(self, frame: str, stamp: Any) -> Any:
        """``map`` -> ``frame`` at ``stamp``, spinning until tf has it."""
        p, when = self.params, self._ros.Time.from_msg(stamp)
        said: list[str] = []

        def attempt() -> Any:
            try:
                return self._tf.lookup_transform(p.map_frame, frame, when)
            except self._ros.tf_errors as error:
                said[:] = [_one_line(error)]
                return None

        found = self._spin_until(attempt, p.tf_timeout_s)
        if found is None:
            raise EfficientEQAError(f"no transform from {p.map_frame} to {frame} at the colour "
                                    f"image's stamp within {p.tf_timeout_s:g} s"
                                    + (f": {said[0]}" if said else ""),
                                    fix=f"check tf (ros2 run tf2_ros tf2_echo {p.map_frame} "
                                        f"{frame}): localization publishes {p.map_frame} -> odom, "
                                        "odometry odom -> base_link, the robot description the "
                                        "camera")
        return found

    def _goal(self, goal: Pose2D) -> Any:
        msg = self._ros.PoseStamped()
        msg.header.frame_id = self.params.map_frame
        msg.header.stamp = self.nav.get_clock().now().to_msg()
        msg.pose.position.x, msg.pose.position.y = float(goal.x), float(goal.y)
        msg.pose.position.z = float(self.params.floor_z_m)
        q = msg.pose.orientation
        q.x, q.y, q.z, q.w = yaw_quaternion(goal.yaw)
        return msg

    def _drive(self, goal: Pose2D) -> tuple[str, bool]:
        """Nav2's result for ``goal`` ("succeeded", "failed", "canceled", "unknown", or
        "rejected"), and whether it ran past ``move_timeout_s`` and was cancelled."""
        nav, p = self.nav, self.params
        if not nav.goToPose(self._goal(goal)):
            return "rejected", False
        deadline, timed_out = time.monotonic() + p.move_timeout_s, False
        try:
            while not nav.isTaskComplete():
                if time.monotonic() < deadline:
                    continue
                if timed_out:
                    raise EfficientEQAError(f"Nav2 did not end the goal ({goal.x:.2f}, "
                                            f"{goal.y:.2f}) within {CANCEL_WAIT_S:g} s of "
                                            "cancelling it",
                                            fix="check Nav2's bt_navigator; the robot may still "
                                                "be moving")
                log.warning("Nav2 did not reach (%.2f, %.2f) within %g s: cancelling the goal",
                            goal.x, goal.y, p.move_timeout_s)
                nav.cancelTask()
                deadline, timed_out = time.monotonic() + CANCEL_WAIT_S, True
        except BaseException:  # interrupted (Ctrl-C) or given up: the robot must not go on
            if not timed_out:
                nav.cancelTask()
            raise
        result = nav.getResult()
        return str(getattr(result, "name", result)).lower(), timed_out


def open_ros2(params_file: str | Path | None = None) -> Ros2Env:
    """The robot on the ROS 2 graph, with the parameters of ``params_file`` (TOML) or the
    defaults."""
    params = Ros2Params.load(Path(params_file)) if params_file else Ros2Params()
    return Ros2Env(params)
