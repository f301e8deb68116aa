"""The ROS 2 adapter's parameters: defaults for a RealSense camera and Nav2, or a TOML file.

A parameters file holds ``name = value`` lines at its top level, each a field of
``Ros2Params``; the fields it leaves out keep their defaults::

    color_topic = "/head_camera/rgb/image_raw"
    depth_topic = "/head_camera/depth_registered/image_raw"
    info_topic = "/head_camera/rgb/camera_info"
    move_timeout_s = 60.0
"""

from __future__ import annotations

import difflib
import json
import math
import sys
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from efficienteqa.errors import EfficientEQAError


@dataclass(frozen=True)
class Ros2Params:
    """Where the adapter reads the robot and how long it waits.

    The depth image must be registered to the colour image (same size, same optical frame:
    RealSense's ``aligned_depth_to_color``); ``info_topic`` is the colour camera's. ``camera_frame``
    empty takes the colour image's ``header.frame_id`` as the optical frame (x right, y down,
    z forward, as REP 103 names ``*_optical_frame``). ``floor_z_m`` is the floor's height in
    ``map_frame``."""

    color_topic: str = "/camera/color/image_raw"
    depth_topic: str = "/camera/aligned_depth_to_color/image_raw"
    info_topic: str = "/camera/color/camera_info"
    map_frame: str = "map"
    camera_frame: str = ""
    floor_z_m: float = 0.0
    sync_tolerance_s: float = 0.05  # the most a depth stamp may differ from its colour stamp
    frame_timeout_s: float = 5.0  # for camera info, and for a colour/depth pair after a move
    tf_timeout_s: float = 1.0  # for map -> optical frame at the colour image's stamp
    move_timeout_s: float = 120.0  # for a Nav2 goal; then it is cancelled
    wait_for_nav2: bool = True  # wait for bt_navigator to be active when the robot is opened
    navigator: str = "bt_navigator"
    namespace: str = ""  # the namespace of Nav2's nodes and actions (a namespaced robot)
    node_name: str = "efficienteqa"

    def __post_init__(self) -> None:
        for name in ("sync_tolerance_s", "frame_timeout_s", "tf_timeout_s", "move_timeout_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise EfficientEQAError(f"ROS 2 parameter {name} must be a positive number of "
                                        f"seconds, not {value!r}", fix=f"e.g. {name} = 1.0")
        if not (isinstance(self.floor_z_m, (int, float)) and math.isfinite(self.floor_z_m)):
            raise EfficientEQAError(f"ROS 2 parameter floor_z_m must be a number of metres, not "
                                    f"{self.floor_z_m!r}", fix="e.g. floor_z_m = 0.0")
        for name in ("color_topic", "depth_topic", "info_topic", "map_frame", "navigator",
                     "node_name"):
            if not getattr(self, name):
                raise EfficientEQAError(f"ROS 2 parameter {name} is empty",
                                        fix=f"leave it out for its default "
                                            f"{getattr(Ros2Params, name)!r}")

    @classmethod
    def of(cls, values: dict[str, Any], where: str = "the ROS 2 parameters") -> Ros2Params:
        """The defaults with ``values`` set; an unknown name or a value of the wrong type is
        refused in one line."""
        known = {f.name: f for f in fields(cls)}
        for name, value in values.items():
            if name not in known:
                near = difflib.get_close_matches(name, known, n=1)
                raise EfficientEQAError(f"unknown ROS 2 parameter {name!r} in {where}",
                                        fix=f"did you mean {near[0]!r}?" if near else
                                        f"use one of {', '.join(known)}")
            default = getattr(cls, name)
            if not _same_kind(value, default):
                raise EfficientEQAError(f"ROS 2 parameter {name} in {where} must be a "
                                        f"{type(default).__name__}, not {value!r}",
                                        fix=f"e.g. {name} = {_toml(default)}")
        typed: dict[str, Any] = {k: float(v) if isinstance(getattr(cls, k), float) else v
                                 for k, v in values.items()}
        return cls(**typed)

    @classmethod
    def load(cls, path: Path) -> Ros2Params:
        """The parameters of a TOML file (top-level ``name = value`` lines)."""
        if not path.is_file():
            raise EfficientEQAError(f"no ROS 2 parameters file {path}",
                                    fix="give --scene ros2 for the defaults, or "
                                        "ros2:FILE.toml naming a file that exists")
        return cls.of(read_toml(path), where=str(path))


def _same_kind(value: Any, default: Any) -> bool:
    if isinstance(default, bool) or isinstance(value, bool):
        return isinstance(value, bool) and isinstance(default, bool)
    if isinstance(default, float):
        return isinstance(value, (int, float))
    return isinstance(value, type(default))


def _toml(value: Any) -> str:
    """``value`` as a TOML file writes it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return json.dumps(value) if isinstance(value, str) else repr(value)


def read_toml(path: Path) -> dict[str, Any]:
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        try:
            import tomli as tomllib
        except ImportError:
            raise EfficientEQAError(f"cannot read {path}: TOML needs Python 3.11 or tomli",
                                    fix="pip install tomli") from None
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise EfficientEQAError(f"cannot read the ROS 2 parameters file {path}: {reason}",
                                fix='write it as UTF-8 TOML, name = value lines, e.g. '
                                    'map_frame = "map"') from None
    try:
        return tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError) as exc:  # RecursionError: nested too deep
        raise EfficientEQAError(f"{path} is not valid TOML: {exc}",
                                fix='write name = value lines, e.g. map_frame = "map"') from None
