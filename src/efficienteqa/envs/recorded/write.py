"""Write an episode's frames as a recorded walk, in one of three layouts (``RECORD_LAYOUTS``):

- ``mcap``: one MCAP file as ROS 2 records one (the default for a path ending in .mcap);
- ``rosbag2``: a folder as ``ros2 bag record -s mcap`` writes one, ``metadata.yaml`` and
  ``PATH/NAME_0.mcap`` (``bagfolder``), which ``ros2 bag info`` and ``ros2 bag play`` open as
  they are;
- ``frames``: a folder in ``folder``'s layout, ``poses.jsonl`` and images (the default for any
  other path).

``WalkRecorder(path)`` is a step hook (``agent.StepHook``): each step's frame is written as it
is read, with the time it was read as its stamp. In MCAP (both first layouts), one message per
step on each of:

==========================================  =================================================
``/camera/color/image_raw``                 sensor_msgs/msg/Image, rgb8
``/camera/aligned_depth_to_color/image_raw`` sensor_msgs/msg/Image, 32FC1 metres (exact) or
                                            16UC1 millimetres (``depth_encoding``)
``/camera/color/camera_info``               sensor_msgs/msg/CameraInfo (K in OpenCV's convention)
``/tf``                                     tf2_msgs/msg/TFMessage: ``map`` ->
                                            ``camera_color_optical_frame``
``/efficienteqa/instance``                  sensor_msgs/msg/Image, 32SC1 instance ids (only
                                            where the environment has an instance sensor)
==========================================  =================================================

and, at the end, one ``/efficienteqa/labels`` (std_msgs/msg/String, ``labels.LABELS_FORMAT``
JSON) where the environment has a semantic sensor. All three read back with
``open_recording``.
"""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import numpy as np
from PIL import Image

from efficienteqa.envs.base import SceneLabels
from efficienteqa.envs.recorded import rosmsg
from efficienteqa.envs.recorded.bagfolder import (
    METADATA_FILE,
    OFFERED_QOS,
    BagFile,
    bag_file_name,
    metadata_yaml,
)
from efficienteqa.envs.recorded.folder import LABELS_FILE, POSES_FILE
from efficienteqa.envs.recorded.labels import labels_json
from efficienteqa.envs.recorded.mcapwalk import INSTANCE_TOPIC, LABELS_TOPIC, require_mcap
from efficienteqa.envs.recorded.tf import quaternion_of
from efficienteqa.envs.recorded.walk import opencv_intrinsics
from efficienteqa.errors import EfficientEQAError
from efficienteqa.observation import Observation
from efficienteqa.records import probe_write

COLOUR_TOPIC = "/camera/color/image_raw"
DEPTH_TOPIC = "/camera/aligned_depth_to_color/image_raw"
INFO_TOPIC = "/camera/color/camera_info"
TF_TOPIC = "/tf"
WORLD_FRAME = "map"
CAMERA_FRAME = "camera_color_optical_frame"
DEPTH_ENCODINGS = ("32FC1", "16UC1")
RECORD_LAYOUTS = ("mcap", "rosbag2", "frames")
MAX_MM = 65535  # 16UC1: deeper than 65.535 m is written as no depth


def is_mcap(path: Path) -> bool:
    return path.suffix.lower() == ".mcap"


def record_layout(path: Path, layout: str | None = None) -> str:
    """The layout ``path`` is written in: ``layout`` (checked against the path: an .mcap file
    ends in .mcap, a folder does not), or by default mcap for a path ending in .mcap, else
    frames."""
    if layout is None:
        return "mcap" if is_mcap(path) else "frames"
    if layout not in RECORD_LAYOUTS:
        raise EfficientEQAError(f"unknown recording layout {layout!r}",
                                fix=f"use --record-format {' or '.join(RECORD_LAYOUTS)}")
    if layout == "mcap" and not is_mcap(path):
        raise EfficientEQAError(f"an MCAP recording is a file ending in .mcap, not {path}",
                                fix=f"give {path.with_suffix('.mcap')}, or --record-format "
                                    "rosbag2 for a bag folder")
    if layout != "mcap" and is_mcap(path):
        raise EfficientEQAError(f"a {layout} recording is a folder, and {path} ends in .mcap",
                                fix=f"give a folder path such as {path.with_suffix('')}")
    return layout


def check_record_path(path: Path, depth_encoding: str = "32FC1",
                      layout: str | None = None) -> None:
    """One line, before any work, when ``path`` cannot take a recording in ``layout``
    (``record_layout``): it exists (a file, a device such as /dev/null, a link, a folder that
    is not empty, or any folder where an .mcap file is asked for), its folder cannot be written
    (read-only, immutable: a file is made and removed there to know), or MCAP is not
    installed."""
    if depth_encoding not in DEPTH_ENCODINGS:
        raise EfficientEQAError(f"unknown depth encoding {depth_encoding!r}",
                                fix=f"use one of {', '.join(DEPTH_ENCODINGS)}")
    layout = record_layout(path, layout)
    folder = path.parent
    if path.is_symlink() or path.exists():
        if path.is_symlink() or not path.is_dir():
            raise EfficientEQAError(f"{path} exists; a recording is never written over",
                                    fix="remove it or give another path")
        if is_mcap(path):
            raise EfficientEQAError(f"{path} is a folder, and an MCAP recording is a file",
                                    fix="remove the folder or give another path")
        try:
            taken = any(path.iterdir())
        except OSError as error:
            raise EfficientEQAError(f"cannot read the folder {path}: {error.strerror or error}",
                                    fix="give another path") from None
        if taken:
            raise EfficientEQAError(f"{path} exists; a recording is never written over",
                                    fix="remove it or give another path")
        folder = path  # an empty folder: the recording's own
    if layout != "frames":
        require_mcap()
    try:
        probe_write(folder)
    except OSError as error:
        raise EfficientEQAError(f"cannot write to {folder}: {error.strerror or error}",
                                fix="give another path") from None


def depth_bytes(depth_m: np.ndarray, encoding: str) -> bytes:
    if encoding == "16UC1":
        mm = np.rint(depth_m.astype(np.float64) * 1000.0)
        mm[(mm > MAX_MM) | ~np.isfinite(mm) | (mm < 0)] = 0
        return mm.astype("<u2").tobytes()
    return depth_m.astype("<f4").tobytes()


class WalkRecorder:
    """Writes frames to ``path`` in ``layout`` (``record_layout``: by default .mcap, one ROS 2
    MCAP file, else a folder of frames). ``labels``: the environment's semantic sensor, written
    at the end; ``clock``: nanoseconds of each frame's stamp (made strictly increasing)."""

    def __init__(self, path: Path, *, labels: SceneLabels | None = None,
                 depth_encoding: str = "32FC1", clock: Callable[[], int] = time.time_ns,
                 layout: str | None = None) -> None:
        check_record_path(path, depth_encoding, layout)
        self.path, self.labels, self.depth_encoding, self.clock = path, labels, depth_encoding, clock
        self.layout = record_layout(path, layout)
        # What metadata.yaml says of a bag's file: its messages per topic, their types.
        self._bag = BagFile(bag_file_name(path), {}, 0, 0)
        self._types: dict[str, str] = {}
        self.frames = 0
        self.error: str | None = None  # why the recording stopped early (a full disk)
        self._last = -1
        self._seen: set[int] = set()
        self._closed = False
        self._stream: IO[bytes] | None = None
        self._poses: IO[str] | None = None
        try:
            if self.layout != "frames":
                from mcap_ros2.writer import Writer

                if self.layout == "rosbag2":
                    path.mkdir(parents=True, exist_ok=True)
                file = path / self._bag.name if self.layout == "rosbag2" else path
                self._stream = open(file, "wb")  # noqa: SIM115 - closed by close()
                self._writer: Any = Writer(self._stream)
                self._schemas = {name: self._writer.register_msgdef(name, text)
                                 for name, text in rosmsg.DEFINITIONS.items()}
            else:
                for sub in ("rgb", "depth"):
                    (path / sub).mkdir(parents=True, exist_ok=True)
                self._poses = open(path / POSES_FILE, "w")  # noqa: SIM115 - closed by close()
        except OSError as error:  # checked writable, then full: as a failure of the first frame
            self._fail(error)

    def __call__(self, record: object, obs: Observation, out: object = None) -> None:
        """The step hook: writes the step's frame."""
        self.add(obs)

    def add(self, obs: Observation, stamp_ns: int | None = None) -> None:
        """Writes one frame; after a write failed (``error``), nothing."""
        if self.error is not None:
            return
        stamp = self.clock() if stamp_ns is None else int(stamp_ns)
        stamp = max(stamp, self._last + 1)
        self._last = stamp
        if obs.instance is not None:
            self._seen.update(int(i) for i in np.unique(obs.instance) if i > 0)
        try:
            if self._stream is not None:
                self._mcap(obs, stamp)
            else:
                self._folder(obs, stamp)
        except OSError as error:
            self._fail(error)
            return
        self.frames += 1

    def _fail(self, error: OSError) -> None:
        """A write failed (a full disk, a drive gone): the recording ends here, its file closed
        as it stands, and the episode it records goes on. ``error`` says so in one line; a
        folder keeps the frames its poses.jsonl lists, an MCAP file the chunks written."""
        kept = (f"it holds the first {self.frames}" if self.layout == "frames" else
                "mcap recover may rescue the frames written"
                + (f"; it has no {METADATA_FILE}" if self.layout == "rosbag2" else ""))
        self.error = (f"the recording {self.path} stopped after {self.frames} frames: "
                      f"{error.strerror or error} ({kept}); the episode went on without it")
        self._closed = True
        for file in (self._stream, self._poses):
            if file is not None:
                with contextlib.suppress(OSError):  # closed, though its last bytes are lost
                    file.close()

    def _channel(self, topic: str, kind: str) -> None:
        """Registers ``topic`` with its offered QoS, as rosbag2 does: ``ros2 bag play`` reads a
        topic's QoS from its channel, and Humble's fails on a channel without one. mcap_ros2's
        writer registers a channel, without metadata, at a topic's first message; so it is
        registered here first, through that writer's mcap writer and channel table (checked by
        tests/test_rosbag2.py, where rosbags matches the channel's QoS to metadata.yaml's)."""
        channel = self._writer._writer.register_channel(
            topic=topic, message_encoding="cdr", schema_id=self._schemas[kind].id,
            metadata={"offered_qos_profiles": OFFERED_QOS})
        self._writer._channel_ids[topic] = channel

    def _write(self, topic: str, kind: str, message: dict[str, Any], stamp: int) -> None:
        """One message of ROS 2 type ``kind``, counted for a bag's metadata."""
        if topic not in self._types:
            self._channel(topic, kind)
        self._writer.write_message(topic, self._schemas[kind], message, log_time=stamp,
                                   publish_time=stamp)
        bag = self._bag
        if not bag.counts:
            bag.first_ns = stamp
        bag.last_ns = max(bag.last_ns, stamp)
        bag.counts[topic] = bag.counts.get(topic, 0) + 1
        self._types[topic] = kind

    def _mcap(self, obs: Observation, stamp: int) -> None:
        h, w = obs.depth_m.shape
        write = self._write
        head = rosmsg.header(stamp, CAMERA_FRAME)

        def image(encoding: str, step: int, data: bytes) -> dict[str, Any]:
            return {"header": head, "height": h, "width": w, "encoding": encoding,
                    "is_bigendian": 0, "step": step, "data": data}

        size = 4 if self.depth_encoding == "32FC1" else 2
        write(COLOUR_TOPIC, rosmsg.IMAGE, image("rgb8", 3 * w,
                                                np.ascontiguousarray(obs.rgb).tobytes()), stamp)
        write(DEPTH_TOPIC, rosmsg.IMAGE, image(self.depth_encoding, size * w,
                                               depth_bytes(obs.depth_m, self.depth_encoding)), stamp)
        fx, fy, cx, cy = opencv_intrinsics(obs.intrinsics)
        write(INFO_TOPIC, rosmsg.CAMERA_INFO, {
            "header": head, "height": h, "width": w, "distortion_model": "plumb_bob",
            "d": [0.0] * 5, "k": [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            "r": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            "p": [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            "binning_x": 0, "binning_y": 0,
            "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False}},
              stamp)
        t, q = obs.cam_to_world[:3, 3], quaternion_of(obs.cam_to_world[:3, :3])
        write(TF_TOPIC, rosmsg.TF_MESSAGE, {"transforms": [{
            "header": rosmsg.header(stamp, WORLD_FRAME), "child_frame_id": CAMERA_FRAME,
            "transform": {"translation": {"x": float(t[0]), "y": float(t[1]), "z": float(t[2])},
                          "rotation": {"x": float(q[0]), "y": float(q[1]), "z": float(q[2]),
                                       "w": float(q[3])}}}]}, stamp)
        if obs.instance is not None:
            write(INSTANCE_TOPIC, rosmsg.IMAGE,
                  image(rosmsg.INSTANCE_ENCODING, 4 * w, obs.instance.astype("<i4").tobytes()),
                  stamp)

    def _folder(self, obs: Observation, stamp: int) -> None:
        name = f"{self.frames:06d}"
        Image.fromarray(np.ascontiguousarray(obs.rgb)).save(self.path / "rgb" / f"{name}.png",
                                                            compress_level=1)
        if self.depth_encoding == "16UC1":
            depth = f"depth/{name}.png"
            mm = np.frombuffer(depth_bytes(obs.depth_m, "16UC1"), "<u2").reshape(obs.depth_m.shape)
            Image.fromarray(mm).save(self.path / depth, compress_level=1)
        else:
            depth = f"depth/{name}.npy"
            np.save(self.path / depth, obs.depth_m.astype(np.float32))
        fx, fy, cx, cy = opencv_intrinsics(obs.intrinsics)
        row: dict[str, Any] = {"rgb": f"rgb/{name}.png", "depth": depth,
                               "cam_to_world": obs.cam_to_world.tolist(),
                               "fx": fx, "fy": fy, "cx": cx, "cy": cy, "stamp": stamp / 1e9}
        if obs.instance is not None:  # a 16-bit PNG where the ids fit (a tenth of the .npy)
            (self.path / "instance").mkdir(exist_ok=True)
            ids = obs.instance
            if ids.size and int(ids.min()) >= 0 and int(ids.max()) <= 0xFFFF:
                row["instance"] = f"instance/{name}.png"
                Image.fromarray(ids.astype(np.uint16)).save(self.path / row["instance"],
                                                            compress_level=1)
            else:
                row["instance"] = f"instance/{name}.npy"
                np.save(self.path / row["instance"], ids.astype(np.int32))
        assert self._poses is not None  # a folder's recorder, open
        self._poses.write(json.dumps(row) + "\n")
        self._poses.flush()

    def close(self) -> None:
        """Writes the labels and finishes the file (a walk cut short is still a walk)."""
        if self._closed:
            return
        self._closed = True
        labels = labels_json(self.labels, self._seen) if self.labels is not None else None
        try:
            if self._stream is not None:
                if labels is not None:
                    stamp = self._last + 1 if self._last >= 0 else self.clock()
                    self._write(LABELS_TOPIC, rosmsg.STRING, {"data": json.dumps(labels)}, stamp)
                self._writer.finish()
                self._stream.close()
                if self.layout == "rosbag2":
                    (self.path / METADATA_FILE).write_text(metadata_yaml(self._bag, self._types))
            else:
                if self._poses is not None:
                    self._poses.close()
                if labels is not None:
                    (self.path / LABELS_FILE).write_text(json.dumps(labels))
        except OSError as error:  # the disk filled at the end: the frames' file as it stands
            self._fail(error)

    def __enter__(self) -> WalkRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
