"""A walk recorded by ROS 2 as an MCAP file, read with the pure-Python ``mcap`` and
``mcap_ros2`` packages (no ROS install; the ``robot`` extra).

What is read:

- colour: ``sensor_msgs/msg/Image`` in rgb8 or bgr8 (rgba8/bgra8: alpha dropped);
- depth: ``sensor_msgs/msg/Image`` in 16UC1 (millimetres; mono16 alike) or 32FC1 (metres),
  *registered to colour* (the same pixels, as ``aligned_depth_to_color`` gives them): a depth
  image of another size is refused, one of the same size is read as registered;
- intrinsics: ``sensor_msgs/msg/CameraInfo`` (K; the images are read as rectified, D ignored);
- the camera's pose: ``tf2_msgs/msg/TFMessage`` on ``/tf`` and ``/tf_static``, the chain from
  the world frame (``map``) to the colour image's ``frame_id`` (an optical frame: x right, y
  down, z forward) through every intermediate frame, at each colour frame's stamp;
- optionally, a simulated walk's truth (``/efficienteqa/instance``, 32SC1 instance ids, and
  ``/efficienteqa/labels``, a ``std_msgs/msg/String`` of ``labels.LABELS_FORMAT`` JSON).

Topics are found by their message type and encoding where that is unambiguous, else named by
options (``McapOptions``; ``recorded:walk.mcap?colour=/cam/color/image_raw``). Each colour frame
is paired with the depth frame nearest in stamp within ``depth_tolerance_ms``; a frame with no
such depth, or no pose, is dropped, and ``note`` says how many. The file is read twice: once at
opening (every problem is one line before any model is called), then frame by frame as the
agent reads the walk.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from efficienteqa.envs.recorded import rosmsg
from efficienteqa.envs.recorded.labels import RecordedLabels
from efficienteqa.envs.recorded.tf import TFTree, frame_name
from efficienteqa.envs.recorded.walk import RecordedCamera, floor_pose, intrinsics_matrix
from efficienteqa.errors import EfficientEQAError
from efficienteqa.observation import Observation
from efficienteqa.records import read_json

INSTANCE_TOPIC = "/efficienteqa/instance"
LABELS_TOPIC = "/efficienteqa/labels"
FIX_MCAP = "pip install 'efficienteqa[robot]' (the mcap and mcap-ros2-support packages)"


def require_mcap() -> None:
    """One line when the ``robot`` extra is not installed."""
    try:
        import mcap.reader  # noqa: F401
        import mcap_ros2.decoder  # noqa: F401
    except ImportError:
        raise EfficientEQAError("MCAP recordings need the mcap packages, which are not "
                                "installed", fix=FIX_MCAP) from None


@dataclass(frozen=True)
class McapOptions:
    """How to read an MCAP walk: topics (None: found by type), the world frame, tolerances."""

    colour: str | None = None
    depth: str | None = None
    info: str | None = None
    world: str = "map"
    depth_tolerance_ms: float = 50.0
    tf_tolerance_ms: float = 50.0


@dataclass(frozen=True)
class _Image:
    """What the first pass keeps of an image message (not its pixels)."""

    ordinal: int  # its place among its topic's messages, in the file's log-time order
    stamp: int
    frame_id: str
    width: int
    height: int
    encoding: str


_Info = tuple[int, np.ndarray, int, int]  # a camera_info: stamp, K (this project's), width, height


@dataclass(frozen=True)
class _Frame:
    """A usable frame: which messages make it, its pose and intrinsics."""

    colour: int
    depth: int
    instance: int | None
    stamp: int
    cam_to_world: np.ndarray
    intrinsics: np.ndarray


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


def _check_image(msg: Any, what: str, where: str) -> tuple[int, int, int]:
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


def _pixels(msg: Any, what: str, where: str) -> np.ndarray:
    """The image of a ``sensor_msgs/msg/Image`` as an array: (H, W, 3) uint8 RGB for colour,
    (H, W) float32 metres for depth (0: none), (H, W) int32 for instance ids. ``where`` names
    the message in an error (file, topic, message)."""
    h, w, step = _check_image(msg, what, where)
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


class McapSource:
    """The frames of an MCAP walk (``walk.FrameSource``)."""

    def __init__(self, path: Path, options: McapOptions | None = None) -> None:
        require_mcap()
        from mcap_ros2.decoder import DecoderFactory

        self.path, self.options = path, options or McapOptions()
        self.name = path.name
        self._decoders = DecoderFactory()
        try:
            self._index()
        except EfficientEQAError:
            raise
        except Exception as error:  # noqa: BLE001 - anything the mcap reader says of a bad file
            raise EfficientEQAError(
                f"cannot read {path} as MCAP: {type(error).__name__}: {error}".split("\n")[0],
                fix="check the file (one cut short may be repaired with `mcap recover`)") from None

    # -- opening --------------------------------------------------------------------------
    def _reader(self, stream: IO[bytes]) -> Any:
        from mcap.reader import make_reader

        return make_reader(stream)

    def _decode(self, schema: Any, channel: Any, message: Any) -> Any:
        decoder = self._decoders.decoder_for(channel.message_encoding, schema)
        if decoder is None:
            raise EfficientEQAError(f"topic {channel.topic} of {self.name} is not ROS 2 CDR "
                                    f"({channel.message_encoding})",
                                    fix="record with ros2 bag record -s mcap")
        return decoder(message.data)

    def _where(self, topic: str, ordinal: int) -> str:
        """A message named in an error: the file, its topic, its place on the topic."""
        return f"{self.name}: {topic} message {ordinal + 1}"

    def _topics(self, reader: Any) -> dict[str, str]:
        """topic -> ROS 2 message type, from the summary (or one scan of an unindexed file)."""
        summary = reader.get_summary()
        if summary is not None:
            return {c.topic: rosmsg.type_name(summary.schemas[c.schema_id].name)
                    for c in summary.channels.values() if c.schema_id in summary.schemas}
        return {channel.topic: rosmsg.type_name(schema.name)
                for schema, channel, _ in reader.iter_messages() if schema is not None}

    def _first(self, reader: Any, topic: str) -> Any:
        for schema, channel, message in reader.iter_messages(topics=[topic]):
            return self._decode(schema, channel, message)
        return None

    def _pick(self, what: str, given: str | None, candidates: list[str], topics: dict[str, str],
              kind: str, prefer: list[str], key: str, example: str) -> str:
        """The topic of ``what``: the one given (checked), the only candidate, or the only
        preferred one; else one line naming the candidates and the option to choose one."""
        if given is not None:
            if topics.get(given) != kind:
                same = sorted(t for t in topics if topics[t] == kind)
                raise EfficientEQAError(f"{self.name} has no {kind} topic {given!r}",
                                        fix=f"topics of that type: {', '.join(same) or 'none'}")
            return given
        if len(candidates) == 1:
            return candidates[0]
        if len(prefer) == 1:
            return prefer[0]
        if not candidates:
            raise EfficientEQAError(f"{self.name} has no {what} topic ({kind})",
                                    fix=f"record one: {example}")
        raise EfficientEQAError(f"{self.name} has several {what} topics: {', '.join(candidates)}",
                                fix=f"choose one: recorded:{self.path}?{key}={candidates[0]}")

    def _index(self) -> None:
        o = self.options
        with open(self.path, "rb") as stream:
            reader = self._reader(stream)
            topics = self._topics(reader)
            images = [t for t, kind in topics.items() if kind == rosmsg.IMAGE
                      and not t.startswith("/efficienteqa/")]
            first = {t: self._first(reader, t) for t in images}
            encodings = {t: str(m.encoding) for t, m in first.items() if m is not None}
            colours = [t for t in images if encodings.get(t) in rosmsg.COLOUR_ENCODINGS]
            compressed = [t for t, k in topics.items() if k == "sensor_msgs/msg/CompressedImage"]
            colour = self._pick("colour", o.colour, colours, topics, rosmsg.IMAGE, [], "colour",
                                "/camera/color/image_raw, rgb8 or bgr8"
                                + (f"; {', '.join(compressed)}: compressed images are not read"
                                   if compressed else ""))
            if first.get(colour) is None:
                raise EfficientEQAError(f"{self.name}: the colour topic {colour} has no message",
                                        fix="record a walk with colour frames")
            camera_frame = frame_name(str(first[colour].header.frame_id))
            depths = [t for t in images if encodings.get(t) in rosmsg.DEPTH_ENCODINGS]
            registered = [t for t in depths
                          if frame_name(str(first[t].header.frame_id)) == camera_frame]
            depth = self._pick("depth", o.depth, depths, topics, rosmsg.IMAGE, registered,
                               "depth", "/camera/aligned_depth_to_color/image_raw, 16UC1 or 32FC1")
            infos = [t for t, kind in topics.items() if kind == rosmsg.CAMERA_INFO]
            near = [t for t in infos if t.rpartition("/")[0] == colour.rpartition("/")[0]]
            info = self._pick("camera_info", o.info, infos, topics, rosmsg.CAMERA_INFO, near,
                              "info", "/camera/color/camera_info")
            tfs = [t for t, kind in topics.items() if kind == rosmsg.TF_MESSAGE]
            instance = INSTANCE_TOPIC if topics.get(INSTANCE_TOPIC) == rosmsg.IMAGE else None
            labels = LABELS_TOPIC if topics.get(LABELS_TOPIC) == rosmsg.STRING else None
            self._topics_read = [t for t in (colour, depth, instance, info, labels, *tfs) if t]
            self._colour, self._depth, self._instance = colour, depth, instance
            metas = self._first_pass(reader, colour, depth, instance, info, labels, set(tfs))
        self._plan(camera_frame, *metas)

    def _first_pass(self, reader: Any, colour: str, depth: str, instance: str | None, info: str,
                    labels: str | None, tfs: set[str]
                    ) -> tuple[list[_Image], list[_Image], list[_Image], list[_Info], TFTree]:
        """Every message of the topics read, in log-time order, without keeping pixels."""
        seen = {t: 0 for t in self._topics_read}
        images: dict[str, list[_Image]] = {colour: [], depth: [], instance or "": []}
        infos: list[_Info] = []
        tree = TFTree()
        self.labels: RecordedLabels | None = None
        for schema, channel, message in reader.iter_messages(topics=self._topics_read,
                                                             log_time_order=True):
            topic = channel.topic
            ordinal = seen[topic]
            seen[topic] += 1
            msg = self._decode(schema, channel, message)
            where = self._where(topic, ordinal)
            if topic in images:
                what = "colour" if topic == colour else "depth" if topic == depth else "instance"
                _check_image(msg, what, where)  # pixels that are not there: one line now
                images[topic].append(_Image(ordinal, rosmsg.stamp_ns(msg.header),
                                            frame_name(str(msg.header.frame_id)), int(msg.width),
                                            int(msg.height), str(msg.encoding)))
            elif topic == info:
                k = np.asarray(msg.k, dtype=np.float64).reshape(3, 3)
                if not np.all(np.isfinite(k)):
                    raise EfficientEQAError(f"{where}: camera_info K is not finite "
                                            f"({k.ravel().tolist()})",
                                            fix="calibrate the camera, or record its driver's "
                                                "camera_info")
                infos.append((rosmsg.stamp_ns(msg.header),
                              intrinsics_matrix(k[0, 0], k[1, 1], k[0, 2], k[1, 2]),
                              int(msg.width), int(msg.height)))
            elif topic == labels:
                try:
                    data = read_json(str(msg.data))
                except ValueError as error:
                    raise EfficientEQAError(f"{LABELS_TOPIC} of {self.name} is not JSON: {error}",
                                            fix="write it as efficienteqa-labels/1 JSON") from None
                self.labels = RecordedLabels.from_json(data, f"{self.name} ({LABELS_TOPIC})")
            elif topic in tfs:
                static = topic.endswith("tf_static")
                for t in msg.transforms:
                    tr, rot = t.transform.translation, t.transform.rotation
                    translation = np.array([tr.x, tr.y, tr.z], dtype=np.float64)
                    rotation = np.array([rot.x, rot.y, rot.z, rot.w], dtype=np.float64)
                    parent, child = str(t.header.frame_id), str(t.child_frame_id)
                    norm = float(np.linalg.norm(rotation))
                    if not np.all(np.isfinite(translation)) or not (1e-9 < norm < np.inf):
                        bad = (f"translation {translation.tolist()}"
                               if not np.all(np.isfinite(translation))
                               else f"rotation {rotation.tolist()} (no quaternion)")
                        raise EfficientEQAError(
                            f"{where}: the transform {parent!r} -> {child!r} has the {bad}",
                            fix="record /tf again; a transform needs a finite translation and "
                                "a non-zero quaternion")
                    tree.add(parent, child, rosmsg.stamp_ns(t.header), translation, rotation,
                             static)
        return images[colour], images[depth], images.get(instance or "", []), infos, tree

    def _plan(self, camera_frame: str, colours: list[_Image], depths: list[_Image],
              instances: list[_Image], infos: list[_Info],
              tree: TFTree) -> None:
        """Pair each colour frame with its depth, instance ids, intrinsics and pose."""
        o = self.options
        if not colours:
            raise EfficientEQAError(f"{self.name}: the colour topic {self._colour} has no message",
                                    fix="record a walk with colour frames")
        sizes = {(c.width, c.height) for c in colours}
        if len(sizes) > 1:
            raise EfficientEQAError(f"{self.name}: the colour frames change size "
                                    f"({', '.join(f'{w}x{h}' for w, h in sorted(sizes))})",
                                    fix="record one camera resolution")
        (w, h), = sizes
        if not depths:
            raise EfficientEQAError(f"{self.name}: the depth topic {self._depth} has no message",
                                    fix="record depth registered to colour")
        other = next(((d.width, d.height) for d in depths if (d.width, d.height) != (w, h)), None)
        if other is not None:
            raise EfficientEQAError(
                f"{self.name}: colour frames are {w}x{h} and depth frames {other[0]}x{other[1]}: "
                "depth must be registered to colour (the same pixels)",
                fix="record depth aligned to colour, e.g. /camera/aligned_depth_to_color/image_raw")
        if not infos:
            raise EfficientEQAError(f"{self.name} has no camera_info message",
                                    fix="record the colour camera's sensor_msgs/msg/CameraInfo")
        bad = next(((iw, ih) for _, _, iw, ih in infos if (iw, ih) != (w, h)), None)
        if bad is not None:
            raise EfficientEQAError(f"{self.name}: camera_info is for {bad[0]}x{bad[1]} images, "
                                    f"the colour frames are {w}x{h}",
                                    fix="name the colour camera's: ?info=TOPIC after the path")
        if any(k[0, 0] <= 0 or k[1, 1] <= 0 for _, k, _, _ in infos):
            raise EfficientEQAError(f"{self.name}: camera_info has no calibration (K is zero)",
                                    fix="calibrate the camera, or record its driver's camera_info")
        tree.chain(o.world, camera_frame)  # no path at all: one line now
        # A frame is placed by its header stamp alone (its pose from /tf, its depth): frames
        # that share a stamp get one pose and one depth. When every colour frame has the same
        # stamp (a driver that leaves header.stamp unset, or zeroes it), the walk cannot be
        # placed at all and would be read as a camera standing still: refused. When only some
        # share one, the rest of the walk is sound: read, with a warning in the note.
        stamps = [c.stamp for c in colours]
        if len(stamps) > 1 and len(set(stamps)) == 1:
            raise EfficientEQAError(
                f"{self.name}: all {len(stamps)} colour frames of {self._colour} have the stamp "
                f"{stamps[0] / 1e9:.9f} s, so they cannot be placed (each would get the same "
                "pose and depth)", fix="record with the camera driver's stamps (header.stamp)")
        shared = len(stamps) - len(set(stamps))
        depth_stamps = np.array([d.stamp for d in depths])
        depth_order = np.argsort(depth_stamps, kind="stable")
        inst_stamps = np.array([i.stamp for i in instances])
        inst_order = np.argsort(inst_stamps, kind="stable")
        info_stamps = np.array([s for s, _, _, _ in infos])
        depth_tol = int(o.depth_tolerance_ms * 1e6)
        tf_tol = int(o.tf_tolerance_ms * 1e6)
        frames: list[_Frame] = []
        no_depth = no_pose = 0
        for c in sorted(colours, key=lambda c: c.stamp):
            d = _nearest(depth_stamps[depth_order], c.stamp, depth_tol)
            if d is None:
                no_depth += 1
                continue
            pose = tree.lookup(o.world, camera_frame, c.stamp, tf_tol)
            if pose is None:
                no_pose += 1
                continue
            i = _nearest(inst_stamps[inst_order], c.stamp, depth_tol) if len(instances) else None
            k = infos[int(np.argmin(np.abs(info_stamps - c.stamp)))][1]
            frames.append(_Frame(c.ordinal, depths[int(depth_order[d])].ordinal,
                                 None if i is None else instances[int(inst_order[i])].ordinal,
                                 c.stamp, pose, k))
        total = len(colours)
        why = (f"{no_depth} without depth within {o.depth_tolerance_ms:g} ms, "
               f"{no_pose} without a pose from {o.world!r}")
        if not frames:
            raise EfficientEQAError(f"{self.name} has no usable frame: {total} colour frames, {why}",
                                    fix="record depth and /tf with the colour frames, or widen "
                                        "?depth_tolerance_ms= / ?tf_tolerance_ms= after the path")
        self._frames = frames
        self.length = len(frames)
        self.camera = RecordedCamera.of(w, h, frames[0].intrinsics, frames[0].cam_to_world)
        dropped = total - len(frames)
        depth_frame = depths[0].frame_id
        self.note = (f"{self.name}: {len(frames)} frames of {total}"
                     + (f" ({dropped} dropped: {why})" if dropped else "")
                     + ("" if depth_frame == camera_frame else
                        f"; depth ({depth_frame}) read as registered to colour ({camera_frame})")
                     + ("; with the simulator's labels" if self.labels is not None else "")
                     + (f"; warning: {shared} colour frames repeat another's stamp, so they get "
                        "its pose and depth" if shared else ""))

    # -- reading --------------------------------------------------------------------------
    def frames(self) -> Iterator[Observation]:
        """The usable frames in order, decoding only their messages, keeping only those a
        frame still to come needs."""
        wanted: dict[tuple[str, int], int] = {}  # message -> the last frame that uses it
        for n, f in enumerate(self._frames):
            wanted[(self._colour, f.colour)] = n
            wanted[(self._depth, f.depth)] = n
            if f.instance is not None and self._instance is not None:
                wanted[(self._instance, f.instance)] = n
        kept: dict[tuple[str, int], Any] = {}
        seen = {t: 0 for t in self._topics_read}
        at = 0
        with open(self.path, "rb") as stream:
            reader = self._reader(stream)
            for schema, channel, message in reader.iter_messages(topics=self._topics_read,
                                                                 log_time_order=True):
                key = (channel.topic, seen[channel.topic])
                seen[channel.topic] += 1
                if key in wanted:
                    kept[key] = self._decode(schema, channel, message)
                while at < len(self._frames) and self._ready(self._frames[at], kept):
                    yield self._observation(self._frames[at], kept)
                    for k in [k for k in kept if wanted[k] <= at]:
                        del kept[k]
                    at += 1

    def _parts(self, f: _Frame) -> list[tuple[str, int]]:
        parts = [(self._colour, f.colour), (self._depth, f.depth)]
        if f.instance is not None and self._instance is not None:
            parts.append((self._instance, f.instance))
        return parts

    def _ready(self, f: _Frame, kept: dict[tuple[str, int], Any]) -> bool:
        return all(p in kept for p in self._parts(f))

    def _observation(self, f: _Frame, kept: dict[tuple[str, int], Any]) -> Observation:
        rgb = _pixels(kept[(self._colour, f.colour)], "colour", self._where(self._colour,
                                                                            f.colour))
        depth = _pixels(kept[(self._depth, f.depth)], "depth", self._where(self._depth, f.depth))
        instance = (_pixels(kept[(self._instance, f.instance)], "instance",
                            self._where(self._instance, f.instance))
                    if f.instance is not None and self._instance is not None else None)
        if instance is not None and instance.shape != depth.shape:
            instance = None
        return Observation(rgb=rgb, depth_m=depth, cam_to_world=f.cam_to_world.copy(),
                           intrinsics=f.intrinsics.copy(), pose=floor_pose(f.cam_to_world),
                           instance=instance)

    def close(self) -> None:
        pass


def _nearest(sorted_stamps: np.ndarray, stamp: int, tolerance: int) -> int | None:
    """Index of the stamp nearest ``stamp`` in a sorted array, if within ``tolerance``."""
    if len(sorted_stamps) == 0:
        return None
    i = int(np.searchsorted(sorted_stamps, stamp))
    best = min((j for j in (i - 1, i) if 0 <= j < len(sorted_stamps)),
               key=lambda j: abs(int(sorted_stamps[j]) - stamp))
    return best if abs(int(sorted_stamps[best]) - stamp) <= tolerance else None
