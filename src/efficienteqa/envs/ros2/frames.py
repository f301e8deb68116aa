"""ROS 2 messages to the canonical frame (``geometry``): images, camera info, transforms.

Pure: the functions read the messages' fields and import nothing of ROS. ROS's optical frames
have OpenCV's camera axes (REP 103: x right, y down, z forward), so ``cam_to_world`` is the
``map`` -> optical frame transform as it is; the canonical floor is z = 0, so the floor's height
in ``map`` is subtracted. Two conventions differ and are converted here:

- pixel centres: ROS's ``CameraInfo.k`` (OpenCV's) puts the first pixel's centre at (0, 0), the
  project at (0.5, 0.5) (``geometry.backproject``), so the principal point moves by half a pixel;
- depth: ``16UC1`` (and ``mono16``) is millimetres, ``32FC1`` metres (REP 118); 0, NaN and
  infinite values are "no surface", 0 in ``Observation.depth_m``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec, Pose2D

COLOUR_ENCODINGS = ("rgb8", "bgr8")
DEPTH_ENCODINGS = {"16UC1": 1e-3, "mono16": 1e-3, "32FC1": 1.0}  # metres per unit
FIX_COLOUR = "publish rgb8 or bgr8 colour (RealSense: rgb8, its default)"
FIX_DEPTH = "publish 16UC1 (millimetres) or 32FC1 (metres) depth"
FIX_REGISTERED = ("publish depth registered to the colour image, e.g. RealSense's "
                  "/camera/aligned_depth_to_color/image_raw (align_depth.enable:=true)")


@dataclass(frozen=True)
class RosCamera(CameraSpec):
    """A camera known from its ``CameraInfo``: ``k`` is its 3x3 K (row-major, the project's
    pixel centres). ``hfov_deg`` follows from K; ``height_m`` and ``pitch_deg`` are where the
    camera was when the robot was opened (tf, not the mount: nothing reads them)."""

    k: tuple[float, ...] = ()

    @property
    def intrinsics(self) -> np.ndarray:
        return np.array(self.k, dtype=float).reshape(3, 3) if self.k else super().intrinsics

    def scaled(self, width: int, height: int) -> RosCamera:
        sx, sy = width / self.width, height / self.height
        k = np.array(self.k, dtype=float).reshape(3, 3) * np.array([[sx], [sy], [1.0]])
        return RosCamera(width, height, self.hfov_deg, self.height_m, self.pitch_deg,
                         tuple(float(v) for v in k.ravel()))


def stamp_ns(stamp: Any) -> int:
    """A ``builtin_interfaces/Time`` in nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def camera_from_info(info: Any, topic: str, cam_to_world: np.ndarray | None = None) -> RosCamera:
    """The camera of a ``sensor_msgs/CameraInfo``; ``cam_to_world`` (where it is now) fills in
    the informative ``height_m`` and ``pitch_deg``."""
    width, height = int(info.width), int(info.height)
    k = np.asarray(info.k, dtype=float).reshape(3, 3)
    fx, fy = k[0, 0], k[1, 1]
    if width <= 0 or height <= 0 or not (fx > 0 and fy > 0 and np.all(np.isfinite(k))):
        raise EfficientEQAError(f"the camera info on {topic} has no intrinsics ({width}x{height}, "
                                f"fx {fx:g}, fy {fy:g})",
                                fix="calibrate the camera, or name the colour camera's info topic")
    k = k.copy()
    k[0, 2] += 0.5  # ROS's first pixel centre is (0, 0), the project's (0.5, 0.5)
    k[1, 2] += 0.5
    hfov = math.degrees(2 * math.atan(width / 2 / fx))
    height_m, pitch_deg = 1.5, -30.0
    if cam_to_world is not None:
        forward = cam_to_world[:3, 2]
        height_m = float(cam_to_world[2, 3])
        pitch_deg = math.degrees(math.asin(float(np.clip(forward[2], -1.0, 1.0))))
    return RosCamera(width, height, hfov, height_m, pitch_deg, tuple(float(v) for v in k.ravel()))


def _pixels(msg: Any, topic: str, dtype: np.dtype, channels: int) -> np.ndarray:
    """The (H, W, C) array of an image message, honouring ``step`` (rows may be padded) and
    ``is_bigendian``."""
    dt = np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<")
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    row = width * channels * dt.itemsize
    data = msg.data  # array.array("B") in rclpy; bytes or a list elsewhere
    raw = (np.asarray(data, dtype=np.uint8) if isinstance(data, list)
           else np.frombuffer(data, dtype=np.uint8))
    if step < row or raw.size < height * step:
        raise EfficientEQAError(f"the {msg.encoding} image on {topic} has {raw.size} bytes, not "
                                f"{height} rows of {step} (at least {row} each)",
                                fix="check the camera driver: the image message is malformed")
    rows = raw[: height * step].reshape(height, step)[:, :row]
    return np.ascontiguousarray(rows).view(dt).reshape(height, width, channels)


def colour_array(msg: Any, topic: str) -> np.ndarray:
    """(H, W, 3) uint8 RGB of an ``rgb8`` or ``bgr8`` image."""
    if msg.encoding not in COLOUR_ENCODINGS:
        raise EfficientEQAError(f"the colour image on {topic} is {msg.encoding!r}, not rgb8 or "
                                "bgr8", fix=FIX_COLOUR)
    rgb = _pixels(msg, topic, np.dtype(np.uint8), 3)
    return np.ascontiguousarray(rgb[..., ::-1]) if msg.encoding == "bgr8" else rgb.copy()


def depth_array(msg: Any, topic: str) -> np.ndarray:
    """(H, W) float32 metres of a ``16UC1``/``mono16`` (mm) or ``32FC1`` (m) image; 0 where
    there is no surface."""
    scale = DEPTH_ENCODINGS.get(msg.encoding)
    if scale is None:
        raise EfficientEQAError(f"the depth image on {topic} is {msg.encoding!r}, not 16UC1 or "
                                "32FC1", fix=FIX_DEPTH)
    dtype = np.dtype(np.float32 if msg.encoding == "32FC1" else np.uint16)
    depth = _pixels(msg, topic, dtype, 1)[..., 0].astype(np.float32) * np.float32(scale)
    return np.where(np.isfinite(depth) & (depth > 0), depth, np.float32(0)).astype(np.float32)


def check_registered(colour: Any, depth: Any, color_topic: str, depth_topic: str) -> None:
    """Depth must be registered to colour: the same image size."""
    if (colour.width, colour.height) != (depth.width, depth.height):
        raise EfficientEQAError(f"the depth image on {depth_topic} is {depth.width}x{depth.height}"
                                f", the colour image on {color_topic} {colour.width}x"
                                f"{colour.height}: depth must be registered to colour",
                                fix=FIX_REGISTERED)


def transform_matrix(transform: Any) -> np.ndarray:
    """The 4x4 of a ``geometry_msgs/Transform`` (translation, unit quaternion x, y, z, w)."""
    t, q = transform.translation, transform.rotation
    x, y, z, w = (float(v) for v in (q.x, q.y, q.z, q.w))
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not n > 0:
        raise EfficientEQAError("tf gave a zero quaternion", fix="check the tf publishers")
    x, y, z, w = x / n, y / n, z / n, w / n
    out = np.eye(4)
    out[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                   [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                   [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    out[:3, 3] = [float(t.x), float(t.y), float(t.z)]
    return out


def floor_pose(cam_to_world: np.ndarray) -> Pose2D:
    """The camera's floor projection: its (x, y), and the yaw of its optical axis on the floor
    (of its x axis turned left, where it looks straight down)."""
    forward, right = cam_to_world[:3, 2], cam_to_world[:3, 0]
    if math.hypot(forward[0], forward[1]) > 1e-3:
        yaw = math.atan2(forward[1], forward[0])
    else:  # looking straight down or up: the image's right is the robot's right
        yaw = math.atan2(right[0], -right[1])
    return Pose2D(float(cam_to_world[0, 3]), float(cam_to_world[1, 3]), yaw)


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a turn by ``yaw`` about z."""
    return 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)
