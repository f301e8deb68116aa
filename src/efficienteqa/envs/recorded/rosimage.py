"""A ``sensor_msgs/msg/Image`` as an array: which encodings are read, the check that a
message's data holds the pixels its header claims, and its pixels as colour, depth or instance
ids. Plain numpy on a decoded message, kept apart from the MCAP file's reading (``rosbag``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from efficienteqa.envs.recorded import rosmsg
from efficienteqa.errors import EfficientEQAError

_SIZES = {"colour": {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4},
          "depth": {"16UC1": 2, "mono16": 2, "32FC1": 4},
          "instance": {"32SC1": 4}}


def _pixel_bytes(what: str, encoding: str) -> int:
    """Bytes a pixel of ``what`` (colour, depth, instance) takes in ``encoding``; one line for
    an encoding that is not read."""
    size = _SIZES[what].get(encoding)
    if size is None:
        wanted = {"colour": rosmsg.COLOUR_ENCODINGS, "depth": rosmsg.DEPTH_ENCODINGS,
                  "instance": (rosmsg.INSTANCE_ENCODING,)}[what]
        raise EfficientEQAError(f"{what} encoding {encoding!r} is not read",
                                fix=f"record {', '.join(wanted)}")
    return size


def check_image(msg: Any, what: str, where: str) -> tuple[int, int, int]:
    """(height, width, step) of an image message whose encoding is read and whose data holds
    the pixels its header claims; else one line saying where (file, topic, message)."""
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    enc = str(msg.encoding)
    try:
        size = _pixel_bytes(what, enc)
    except EfficientEQAError as error:
        raise EfficientEQAError(f"{where}: {error.args[0]}", fix=error.fix) from None
    if h <= 0 or w <= 0:
        raise EfficientEQAError(f"{where}: the image is {w}x{h}", fix="record images with pixels")
    if step < w * size or len(msg.data) < h * step:
        raise EfficientEQAError(
            f"{where}: a {w}x{h} {enc} image needs {h} rows of {w * size} bytes, but step is "
            f"{step} and the data holds {len(msg.data)} bytes (height x step: {h * step})",
            fix="record the image again: its header does not match its data")
    return h, w, step


def pixels(msg: Any, what: str, where: str) -> np.ndarray:
    """The image of a ``sensor_msgs/msg/Image`` as an array: (H, W, 3) uint8 RGB for colour,
    (H, W) float32 metres for depth (0: none), (H, W) int32 for instance ids. ``where`` names
    the message in an error (file, topic, message)."""
    h, w, step = check_image(msg, what, where)
    enc = str(msg.encoding)
    size = _pixel_bytes(what, enc)
    rows = np.frombuffer(msg.data, np.uint8, count=h * step).reshape(h, step)
    if what == "colour":
        image = rows[:, :w * size].reshape(h, w, size)[..., :3]
        return np.ascontiguousarray(image[..., ::-1] if enc.startswith("bgr") else image)
    dtype = {"16UC1": "u2", "mono16": "u2", "32FC1": "f4", "32SC1": "i4"}[enc]
    order = ">" if msg.is_bigendian else "<"
    values = rows[:, :w * size].copy().view(order + dtype).reshape(h, w)
    if what == "instance":
        return values.astype(np.int32)
    if dtype == "u2":
        return (values.astype(np.float32) / np.float32(1000.0))
    depth = values.astype(np.float32)
    depth[~np.isfinite(depth) | (depth < 0)] = 0.0
    return depth
