"""A walk recorded as a plain folder: images and one JSON line per frame.

::

    WALK/
      poses.jsonl        one JSON object a line, one line per frame, in the walk's order
      rgb/000000.png     8-bit RGB (RGBA: alpha dropped)
      depth/000000.png   16-bit PNG, millimetres (0: no depth); or depth/000000.npy, float32 metres
      instance/000000.npy  optional: int32 instance ids (a simulated walk's truth)
      labels.json        optional: the simulator's labels (``labels.LABELS_FORMAT``)

A line of ``poses.jsonl``::

    {"rgb": "rgb/000000.png", "depth": "depth/000000.png",
     "cam_to_world": [[r00, r01, r02, x], [r10, r11, r12, y], [r20, r21, r22, z], [0, 0, 0, 1]],
     "fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5, "stamp": 12.25,
     "instance": "instance/000000.npy"}

File names are relative to the folder. ``cam_to_world`` takes camera points to the world (the
map frame: x, y on the floor, z up, metres, the floor at z = 0) with OpenCV camera axes (x
right, y down, z forward). ``fx fy cx cy`` are in pixels in OpenCV's convention (the centre of
the top-left pixel is (0, 0)), as ROS CameraInfo and OpenCV calibrations give them. ``stamp``
(seconds) and ``instance`` are optional. Depth is registered to colour: the same size.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from efficienteqa.envs.recorded.labels import RecordedLabels
from efficienteqa.envs.recorded.walk import RecordedCamera, floor_pose, intrinsics_matrix
from efficienteqa.errors import EfficientEQAError
from efficienteqa.observation import Observation

POSES_FILE = "poses.jsonl"
LABELS_FILE = "labels.json"
FIX_FOLDER = f"write {POSES_FILE} as efficienteqa.envs.recorded.folder describes"


@dataclass(frozen=True)
class _Frame:
    rgb: Path
    depth: Path
    instance: Path | None
    cam_to_world: np.ndarray
    intrinsics: np.ndarray


def _size(path: Path) -> tuple[int, int]:
    """(width, height) of an image or .npy file, from its header."""
    if path.suffix == ".npy":
        shape = np.load(path, mmap_mode="r").shape
        return int(shape[1]), int(shape[0])
    with Image.open(path) as image:
        return image.size


class FolderSource:
    """The frames of a walk folder (``walk.FrameSource``)."""

    def __init__(self, path: Path) -> None:
        self.path, self.name = path, path.name
        poses = path / POSES_FILE
        if not poses.is_file():
            raise EfficientEQAError(f"{path} has no {POSES_FILE}",
                                    fix=f"give an .mcap file or a folder with {POSES_FILE}")
        frames = [self._line(n, line) for n, line in enumerate(poses.read_text().splitlines(), 1)
                  if line.strip()]
        if not frames:
            raise EfficientEQAError(f"{poses} lists no frame", fix=FIX_FOLDER)
        w, h = _size(frames[0].rgb)
        for n, f in enumerate(frames, 1):
            for what, file in (("rgb", f.rgb), ("depth", f.depth), ("instance", f.instance)):
                if file is not None and _size(file) != (w, h):
                    size = "x".join(map(str, _size(file)))
                    raise EfficientEQAError(
                        f"{poses} line {n}: {what} {file.name} is {size}, the first colour frame "
                        f"{w}x{h}: depth must be registered to colour (the same pixels)",
                        fix="give every image of the walk the same size")
        self._frames = frames
        self.length = len(frames)
        self.camera = RecordedCamera.of(w, h, frames[0].intrinsics, frames[0].cam_to_world)
        labels = path / LABELS_FILE
        self.labels: RecordedLabels | None = None
        if labels.is_file():
            try:
                data = json.loads(labels.read_text())
            except ValueError as error:
                raise EfficientEQAError(f"{labels} is not JSON: {error}",
                                        fix="write it as efficienteqa-labels/1 JSON") from None
            self.labels = RecordedLabels.from_json(data, str(labels))
        self.note = (f"{self.name}: {len(frames)} frames"
                     + ("; with the simulator's labels" if self.labels is not None else ""))

    def _line(self, n: int, line: str) -> _Frame:
        where = f"{self.path / POSES_FILE} line {n}"
        try:
            row = json.loads(line)
            pose = np.asarray(row["cam_to_world"], dtype=np.float64)
            k = [float(row[key]) for key in ("fx", "fy", "cx", "cy")]
            files = {key: row.get(key) for key in ("rgb", "depth", "instance")}
        except (ValueError, KeyError, TypeError) as error:
            raise EfficientEQAError(f"cannot read {where}: {type(error).__name__}: {error}",
                                    fix=FIX_FOLDER) from None
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
            raise EfficientEQAError(f"{where}: cam_to_world is not a finite 4x4 matrix",
                                    fix=FIX_FOLDER)
        rot = pose[:3, :3]
        if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-4) or np.linalg.det(rot) < 0:
            raise EfficientEQAError(f"{where}: cam_to_world's 3x3 part is not a rotation",
                                    fix="give an orthonormal rotation (OpenCV camera axes)")
        if not all(math.isfinite(v) for v in k) or k[0] <= 0 or k[1] <= 0:
            raise EfficientEQAError(f"{where}: fx, fy, cx, cy must be finite, fx and fy > 0",
                                    fix=FIX_FOLDER)
        paths: dict[str, Path | None] = {}
        for key, name in files.items():
            if name is None and key != "instance":
                raise EfficientEQAError(f"{where} names no {key} file", fix=FIX_FOLDER)
            paths[key] = None if name is None else self.path / str(name)
            file = paths[key]
            if file is not None and not file.is_file():
                raise EfficientEQAError(f"{where}: {key} file {name} is missing",
                                        fix="keep the walk's files beside poses.jsonl")
        rgb, depth = paths["rgb"], paths["depth"]
        assert rgb is not None and depth is not None
        return _Frame(rgb, depth, paths["instance"], pose, intrinsics_matrix(*k))

    def frames(self) -> Iterator[Observation]:
        for f in self._frames:
            yield Observation(rgb=read_rgb(f.rgb), depth_m=read_depth(f.depth),
                              cam_to_world=f.cam_to_world.copy(), intrinsics=f.intrinsics.copy(),
                              pose=floor_pose(f.cam_to_world),
                              instance=(np.load(f.instance).astype(np.int32)
                                        if f.instance is not None else None))

    def close(self) -> None:
        pass


def read_rgb(path: Path) -> np.ndarray:
    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"), dtype=np.uint8).copy()


def read_depth(path: Path) -> np.ndarray:
    """Metres, float32, 0 where there is no depth: a 16-bit PNG in millimetres or a float32
    .npy in metres."""
    if path.suffix == ".npy":
        depth = np.load(path).astype(np.float32)
    else:
        with Image.open(path) as image:
            if image.mode not in ("I;16", "I;16B", "I;16L", "I"):
                raise EfficientEQAError(f"depth {path.name} is a {image.mode} image, not 16-bit",
                                        fix="write depth as a 16-bit PNG in millimetres or a "
                                            "float32 .npy in metres")
            depth = np.asarray(image, dtype=np.float32) / np.float32(1000.0)
    depth[~np.isfinite(depth) | (depth < 0)] = 0.0
    return depth
