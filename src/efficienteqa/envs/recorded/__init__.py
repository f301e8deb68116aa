"""Recorded walks: RGB-D frames with their intrinsics and camera poses, replayed in order as an
``envs.base.Recording`` (``walk.RecordedWalk``), from an MCAP file as ROS 2 records one
(``rosbag``) or a plain folder (``folder``); and any episode written as either (``write``).

``open_recording("walk.mcap?world=odom")``: the options after "?" are ``McapOptions``' fields
(``colour``, ``depth``, ``info``, ``world``, ``depth_tolerance_ms``, ``tf_tolerance_ms``).
Independent of the synthetic and Habitat environments.
"""

from __future__ import annotations

import math
from dataclasses import fields
from pathlib import Path
from typing import Any

from efficienteqa.envs.recorded.walk import RecordedWalk
from efficienteqa.errors import EfficientEQAError

__all__ = ["RecordedWalk", "open_recording", "parse_spec"]

_ALIASES = {"color": "colour"}


def parse_spec(spec: str) -> tuple[Path, dict[str, Any]]:
    """``PATH[?key=value&...]`` -> the path and the options (checked by name and type)."""
    from efficienteqa.envs.recorded.mcapwalk import McapOptions

    text, _, query = spec.partition("?")
    if not text:
        raise EfficientEQAError("recorded: names no file", fix="use recorded:WALK.mcap or "
                                                               "recorded:FOLDER")
    known = {f.name: f.type for f in fields(McapOptions)}
    options: dict[str, Any] = {}
    for part in filter(None, query.split("&")):
        key, eq, value = part.partition("=")
        key = _ALIASES.get(key, key)
        if not eq or key not in known:
            raise EfficientEQAError(f"unknown recording option {part!r}",
                                    fix=f"use {', '.join(f'{k}=...' for k in known)}")
        if key.endswith("_ms"):
            try:
                options[key] = float(value)
            except ValueError:
                options[key] = -1.0
            if not (math.isfinite(options[key]) and options[key] >= 0):
                raise EfficientEQAError(f"recording option {key}={value!r} is not a duration: "
                                        "it must be a finite number of milliseconds, 0 or more",
                                        fix=f"give milliseconds, e.g. {key}=50")
        else:
            options[key] = value
    return Path(text), options


def open_recording(spec: str) -> RecordedWalk:
    """The walk of ``spec``: an .mcap file (ROS 2) or a folder with ``poses.jsonl``, each
    checked whole before any frame is read."""
    path, options = parse_spec(spec)
    if not path.exists():
        raise EfficientEQAError(f"recording {path} does not exist",
                                fix="give an .mcap file or a walk folder with poses.jsonl")
    if path.is_dir():
        from efficienteqa.envs.recorded.folder import FolderSource

        if options:
            raise EfficientEQAError(f"options {', '.join(options)} are for MCAP files; "
                                    f"{path} is a folder", fix="leave them out")
        return RecordedWalk(FolderSource(path))
    if path.suffix.lower() != ".mcap":
        raise EfficientEQAError(f"{path} is neither an .mcap file nor a walk folder",
                                fix="give an .mcap file (ROS 2) or a folder with poses.jsonl")
    from efficienteqa.envs.recorded.mcapwalk import McapOptions
    from efficienteqa.envs.recorded.rosbag import McapSource

    return RecordedWalk(McapSource(path, McapOptions(**options)))
