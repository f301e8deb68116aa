"""A walk recorded as a plain folder: images and one JSON line per frame.

::

    WALK/
      poses.jsonl        one JSON object a line, one line per frame, in the walk's order
      rgb/000000.png     8-bit RGB (RGBA: alpha dropped)
      depth/000000.png   16-bit PNG, millimetres (0: no depth); or depth/000000.npy, float32 metres
      instance/000000.png  optional: instance ids (a simulated walk's truth), a 16-bit PNG; or
                         instance/000000.npy, integer ids (any above 65535)
      labels.json        optional: the simulator's labels (``labels.LABELS_FORMAT``)

A line of ``poses.jsonl``::

    {"rgb": "rgb/000000.png", "depth": "depth/000000.png",
     "cam_to_world": [[r00, r01, r02, x], [r10, r11, r12, y], [r20, r21, r22, z], [0, 0, 0, 1]],
     "fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5, "stamp": 12.25,
     "instance": "instance/000000.png"}

File names are relative to the folder and stay inside it (``FolderSource._inside``).
``cam_to_world`` takes camera points to the world (the map frame: x, y on the floor, z up,
metres, the floor at z = 0) with OpenCV camera axes (x right, y down, z forward). ``fx fy cx
cy`` are in pixels in OpenCV's convention (the centre of the top-left pixel is (0, 0)), as ROS
CameraInfo and OpenCV calibrations give them. ``stamp`` (seconds) and ``instance`` are
optional. Depth is registered to colour: the same size.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from efficienteqa.envs.recorded.labels import RecordedLabels
from efficienteqa.envs.recorded.walk import RecordedCamera, floor_pose, intrinsics_matrix
from efficienteqa.errors import EfficientEQAError, first_line
from efficienteqa.observation import Observation
from efficienteqa.records import read_json

POSES_FILE = "poses.jsonl"
LABELS_FILE = "labels.json"
FIX_FOLDER = f"write {POSES_FILE} as efficienteqa.envs.recorded.folder describes"
FIX_IMAGE = "write rgb as an 8-bit PNG, depth as a 16-bit PNG (millimetres) or a float32 .npy " \
            "(metres), instance as a 16-bit PNG or an int32 .npy"
# What PIL and numpy raise on a damaged or foreign file (PIL's PNG reader raises SyntaxError on a
# broken chunk, zlib.error on a broken stream; numpy, ValueError on a bad .npy header).
_UNREADABLE = (OSError, ValueError, SyntaxError, EOFError, zlib.error, Image.DecompressionBombError)
# The .npy data types read: depth in metres (any real number type), instance ids (integers).
_NPY_KINDS = {"depth": "fiu", "instance": "iu"}
_DEPTH_MODES = ("I;16", "I;16B", "I;16L", "I")


@dataclass(frozen=True)
class _Frame:
    line: int  # its line in poses.jsonl, for the messages
    rgb: Path
    depth: Path
    instance: Path | None
    cam_to_world: np.ndarray
    intrinsics: np.ndarray


def _header(path: Path, what: str) -> tuple[int, int]:
    """(width, height) of ``what`` (rgb, depth or instance) from its file's header; a file that
    is not such an image raises ``ValueError`` saying why."""
    if path.suffix == ".npy":
        if what == "rgb":
            raise ValueError("rgb is read from an image file (PNG), not .npy")
        # Mapped, not read: a header that is no .npy's, an array of Python objects (never
        # unpickled) or data shorter than the header says are refused here.
        array = np.load(path, mmap_mode="r")
        shape, dtype = array.shape, array.dtype
        del array
        if len(shape) != 2:
            raise ValueError(f"its array is {len(shape)}-D, not 2-D (height x width)")
        if dtype.kind not in _NPY_KINDS[what]:
            raise ValueError(f"its array holds {dtype}, not "
                             + ("numbers" if what == "depth" else "integer ids"))
        return int(shape[1]), int(shape[0])
    with Image.open(path) as image:
        if what != "rgb" and image.mode not in _DEPTH_MODES:
            raise ValueError(f"it is a {image.mode} image, not 16-bit")
        return image.size


class FolderSource:
    """The frames of a walk folder (``walk.FrameSource``)."""

    def __init__(self, path: Path) -> None:
        self.path, self.name = path, path.name
        self.layout = "folder"
        self._root = path.resolve()
        poses = path / POSES_FILE
        if not poses.is_file():
            raise EfficientEQAError(f"{path} has no {POSES_FILE}, metadata.yaml or .mcap file",
                                    fix=f"give a walk folder with {POSES_FILE}, a rosbag2 folder "
                                        "or an .mcap file")
        try:
            data = poses.read_bytes()
        except OSError as error:
            raise EfficientEQAError(f"cannot read {poses}: {error.strerror or error}",
                                    fix=FIX_FOLDER) from None
        frames = [self._line(n, line) for n, line in enumerate(data.splitlines(), 1)
                  if line.strip()]
        if not frames:
            raise EfficientEQAError(f"{poses} lists no frame", fix=FIX_FOLDER)
        w, h = self._size(frames[0], "rgb", frames[0].rgb)
        for f in frames:
            for what, file in (("rgb", f.rgb), ("depth", f.depth), ("instance", f.instance)):
                if file is None:
                    continue
                size = self._size(f, what, file)
                if size != (w, h):
                    raise EfficientEQAError(
                        f"{poses} line {f.line}: {what} {file.name} is {size[0]}x{size[1]}, the "
                        f"first colour frame {w}x{h}: depth must be registered to colour (the "
                        "same pixels)", fix="give every image of the walk the same size")
        self._frames = frames
        self.length = len(frames)
        self.camera = RecordedCamera.of(w, h, frames[0].intrinsics, frames[0].cam_to_world)
        labels = path / LABELS_FILE
        self.labels: RecordedLabels | None = None
        if labels.is_file():
            try:
                data = read_json(labels.read_bytes())
            except (OSError, ValueError) as error:
                raise EfficientEQAError(f"{labels} is not JSON: {error}",
                                        fix="write it as efficienteqa-labels/1 JSON") from None
            self.labels = RecordedLabels.from_json(data, str(labels))
        self.note = (f"{self.name}: {len(frames)} frames"
                     + ("; with the simulator's labels" if self.labels is not None else ""))

    def _where(self, n: int) -> str:
        return f"{self.path / POSES_FILE} line {n}"

    def _size(self, f: _Frame, what: str, file: Path) -> tuple[int, int]:
        try:
            return _header(file, what)
        except _UNREADABLE as error:
            raise EfficientEQAError(f"{self._where(f.line)}: cannot read {what} file "
                                    f"{file.relative_to(self.path)}: {first_line(error)}",
                                    fix=FIX_IMAGE) from None

    def _line(self, n: int, raw: bytes) -> _Frame:
        where = self._where(n)
        try:
            row = read_json(raw.decode("utf-8"))
            pose = np.asarray(row["cam_to_world"], dtype=np.float64)
            k = [float(row[key]) for key in ("fx", "fy", "cx", "cy")]
            files = {key: row.get(key) for key in ("rgb", "depth", "instance")}
        except (ValueError, KeyError, TypeError, OverflowError) as error:
            raise EfficientEQAError(f"cannot read {where}: {type(error).__name__}: "
                                    f"{first_line(error)}", fix=FIX_FOLDER) from None
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
            paths[key] = None if name is None else self._inside(where, key, name)
        rgb, depth = paths["rgb"], paths["depth"]
        assert rgb is not None and depth is not None
        return _Frame(n, rgb, depth, paths["instance"], pose, intrinsics_matrix(*k))

    def _inside(self, where: str, key: str, name: object) -> Path:
        """The file ``name`` of a line, which must be a relative path that stays inside the
        folder (links followed): a walk never reads elsewhere."""
        if not isinstance(name, str) or not name or "\0" in name:
            raise EfficientEQAError(f"{where}: {key} must be a file name, not {name!r}",
                                    fix=FIX_FOLDER)
        file = self.path / name
        try:
            inside = file.resolve().is_relative_to(self._root)
        except (OSError, RuntimeError):  # a link loop
            inside = False
        if not inside:
            raise EfficientEQAError(f"{where}: {key} file {name!r} is outside the walk folder",
                                    fix="keep the walk's files in its folder and name them "
                                        "relative to it, e.g. rgb/000000.png")
        if not file.is_file():
            raise EfficientEQAError(f"{where}: {key} file {name} is missing",
                                    fix="keep the walk's files beside poses.jsonl")
        return file

    def frames(self) -> Iterator[Observation]:
        for f in self._frames:
            yield Observation(rgb=self._read(f, "rgb", f.rgb, read_rgb),
                              depth_m=self._read(f, "depth", f.depth, read_depth),
                              cam_to_world=f.cam_to_world.copy(), intrinsics=f.intrinsics.copy(),
                              pose=floor_pose(f.cam_to_world),
                              instance=(self._read(f, "instance", f.instance, read_instance)
                                        if f.instance is not None else None))

    def _read(self, f: _Frame, what: str, file: Path,
              read: Callable[[Path], np.ndarray]) -> np.ndarray:
        """A frame's image, or one line naming its file: a damage only decoding finds (a PNG
        cut short) shows mid-walk."""
        try:
            return read(file)
        except _UNREADABLE as error:
            raise EfficientEQAError(f"{self._where(f.line)}: cannot read {what} file "
                                    f"{file.relative_to(self.path)}: {first_line(error)}",
                                    fix=FIX_IMAGE) from None

    def close(self) -> None:
        pass


def read_rgb(path: Path) -> np.ndarray:
    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"), dtype=np.uint8).copy()


def _read_16bit(path: Path, dtype: type) -> np.ndarray:
    """A 16-bit image (depth in millimetres, instance ids) as a ``dtype`` array of its own."""
    with Image.open(path) as image:
        if image.mode not in _DEPTH_MODES:
            raise ValueError(f"it is a {image.mode} image, not 16-bit")
        return np.array(image, dtype=dtype)


def read_depth(path: Path) -> np.ndarray:
    """Metres, float32, 0 where there is no depth: a 16-bit PNG in millimetres or a float32
    .npy in metres."""
    if path.suffix == ".npy":
        depth = np.load(path).astype(np.float32)
        if depth.ndim != 2:
            raise ValueError(f"its array is {depth.ndim}-D, not 2-D (height x width)")
    else:
        depth = _read_16bit(path, np.float32) / np.float32(1000.0)
    depth[~np.isfinite(depth) | (depth < 0)] = 0.0
    return depth


def read_instance(path: Path) -> np.ndarray:
    """Instance ids, int32: a 16-bit PNG or an integer .npy."""
    if path.suffix != ".npy":
        return _read_16bit(path, np.int32)
    ids = np.load(path)
    if ids.ndim != 2 or ids.dtype.kind not in _NPY_KINDS["instance"]:
        raise ValueError(f"its array is {ids.ndim}-D {ids.dtype}, not 2-D integer ids")
    return ids.astype(np.int32)
