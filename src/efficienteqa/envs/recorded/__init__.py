"""Recorded walks: RGB-D frames with their intrinsics and camera poses, replayed in order as an
``envs.base.Recording`` (``walk.RecordedWalk``), from MCAP as ROS 2 records it (``rosbag``: one
.mcap file, or the files of a rosbag2 folder, ``bagfolder``) or a plain folder (``folder``); and
any episode written as any of them (``write``).

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
    """The walk of ``spec``: an .mcap file (ROS 2), a rosbag2 folder (``metadata.yaml`` and its
    .mcap files, read in order as one walk) or a folder with ``poses.jsonl``, each checked whole
    before any frame is read."""
    path, options = parse_spec(spec)
    if not path.exists():
        raise EfficientEQAError(f"recording {path} does not exist",
                                fix="give an .mcap file, a rosbag2 folder or a walk folder with "
                                    "poses.jsonl")
    from efficienteqa.envs.recorded.mcapwalk import McapOptions

    if path.is_dir():
        from efficienteqa.envs.recorded.bagfolder import bag_files
        from efficienteqa.envs.recorded.folder import POSES_FILE, FolderSource

        bag = None if (path / POSES_FILE).is_file() else bag_files(path)
        if bag is None:
            if options:
                raise EfficientEQAError(f"options {', '.join(options)} are for MCAP recordings; "
                                        f"{path} is a walk folder", fix="leave them out")
            return RecordedWalk(FolderSource(path))
        from efficienteqa.envs.recorded.rosbag import McapSource

        files, note = bag
        source = McapSource(path, McapOptions(**options), files=files)
        if note:
            source.note += f"; {note}"
        return RecordedWalk(source)
    if path.suffix.lower() != ".mcap":
        raise EfficientEQAError(f"{path} is neither an .mcap file nor a walk folder",
                                fix="give an .mcap file, a rosbag2 folder (metadata.yaml and "
                                    ".mcap files) or a walk folder with poses.jsonl")
    from efficienteqa.envs.recorded.rosbag import McapSource

    return RecordedWalk(McapSource(path, McapOptions(**options)))
