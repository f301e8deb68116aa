"""A walk recorded by ROS 2 as MCAP, one file or the files of a rosbag2 folder (``bagfolder``)
read in order as one walk, read with the pure-Python ``mcap`` and
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
agent reads the walk. The options and the topics of truth are ``mcapwalk``'s, an image
message's pixels ``rosimage``'s, and the pairing of the messages into frames ``pairing``'s.
"""

from __future__ import annotations

from collections.abc import Generator, Iterator, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from efficienteqa.envs.recorded import rosmsg
from efficienteqa.envs.recorded.labels import RecordedLabels
from efficienteqa.envs.recorded.mcapwalk import INSTANCE_TOPIC, LABELS_TOPIC, McapOptions, require_mcap
from efficienteqa.envs.recorded.pairing import Frame, Image, Info, plan
from efficienteqa.envs.recorded.rosimage import check_image, pixels
from efficienteqa.envs.recorded.tf import TFTree, frame_name
from efficienteqa.envs.recorded.walk import floor_pose, intrinsics_matrix
from efficienteqa.errors import EfficientEQAError
from efficienteqa.observation import Observation
from efficienteqa.records import read_json


class McapSource:
    """The frames of an MCAP walk (``walk.FrameSource``)."""

    def __init__(self, path: Path, options: McapOptions | None = None,
                 files: Sequence[Path] | None = None) -> None:
        """``path``: an .mcap file, or a rosbag2 folder whose ``files`` are read in order."""
        require_mcap()
        from mcap_ros2.decoder import DecoderFactory

        self.path, self.options = path, options or McapOptions()
        self.files = list(files) if files is not None else [path]
        self.layout = "mcap" if files is None else "rosbag2"
        self.name = path.name
        self._file = self.files[0]  # the file being read, for the messages
        self._decoders = DecoderFactory()
        try:
            self._index()
        except EfficientEQAError:
            raise
        except Exception as error:  # noqa: BLE001 - anything the mcap reader says of a bad file
            raise EfficientEQAError(
                f"cannot read {self._file} as MCAP: {type(error).__name__}: {error}".split("\n")[0],
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

    def _messages(self, topics: list[str]) -> Generator[tuple[Any, Any, Any], None, None]:
        """(schema, channel, message) of ``topics`` in log-time order, file after file."""
        for file in self.files:
            self._file = file
            with open(file, "rb") as stream:
                yield from self._reader(stream).iter_messages(topics=topics, log_time_order=True)

    def _topics(self) -> dict[str, str]:
        """topic -> ROS 2 message type, from each file's summary (or one scan of an unindexed
        file)."""
        topics: dict[str, str] = {}
        for file in self.files:
            self._file = file
            with open(file, "rb") as stream:
                reader = self._reader(stream)
                summary = reader.get_summary()
                if summary is not None:
                    topics.update({c.topic: rosmsg.type_name(summary.schemas[c.schema_id].name)
                                   for c in summary.channels.values()
                                   if c.schema_id in summary.schemas})
                else:
                    topics.update({channel.topic: rosmsg.type_name(schema.name)
                                   for schema, channel, _ in reader.iter_messages()
                                   if schema is not None})
        return topics

    def _first(self, topic: str) -> Any:
        messages = self._messages([topic])
        try:
            for schema, channel, message in messages:
                return self._decode(schema, channel, message)
        finally:
            messages.close()
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
        topics = self._topics()
        images = [t for t, kind in topics.items() if kind == rosmsg.IMAGE
                  and not t.startswith("/efficienteqa/")]
        first = {t: self._first(t) for t in images}
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
        metas = self._first_pass(colour, depth, instance, info, labels, set(tfs))
        self._frames, self.camera, self.note = plan(self.name, o, colour, depth, camera_frame,
                                                    *metas, self.labels is not None)
        self.length = len(self._frames)

    def _first_pass(self, colour: str, depth: str, instance: str | None, info: str,
                    labels: str | None, tfs: set[str]
                    ) -> tuple[list[Image], list[Image], list[Image], list[Info], TFTree]:
        """Every message of the topics read, in log-time order, without keeping pixels."""
        seen = {t: 0 for t in self._topics_read}
        images: dict[str, list[Image]] = {colour: [], depth: [], instance or "": []}
        infos: list[Info] = []
        tree = TFTree()
        self.labels: RecordedLabels | None = None
        for schema, channel, message in self._messages(self._topics_read):
            topic = channel.topic
            ordinal = seen[topic]
            seen[topic] += 1
            msg = self._decode(schema, channel, message)
            where = self._where(topic, ordinal)
            if topic in images:
                what = "colour" if topic == colour else "depth" if topic == depth else "instance"
                check_image(msg, what, where)  # pixels that are not there: one line now
                images[topic].append(Image(ordinal, rosmsg.stamp_ns(msg.header),
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
        for schema, channel, message in self._messages(self._topics_read):
            key = (channel.topic, seen[channel.topic])
            seen[channel.topic] += 1
            if key in wanted:
                kept[key] = self._decode(schema, channel, message)
            while at < len(self._frames) and self._ready(self._frames[at], kept):
                yield self._observation(self._frames[at], kept)
                for k in [k for k in kept if wanted[k] <= at]:
                    del kept[k]
                at += 1

    def _parts(self, f: Frame) -> list[tuple[str, int]]:
        parts = [(self._colour, f.colour), (self._depth, f.depth)]
        if f.instance is not None and self._instance is not None:
            parts.append((self._instance, f.instance))
        return parts

    def _ready(self, f: Frame, kept: dict[tuple[str, int], Any]) -> bool:
        return all(p in kept for p in self._parts(f))

    def _observation(self, f: Frame, kept: dict[tuple[str, int], Any]) -> Observation:
        rgb = pixels(kept[(self._colour, f.colour)], "colour", self._where(self._colour,
                                                                            f.colour))
        depth = pixels(kept[(self._depth, f.depth)], "depth", self._where(self._depth, f.depth))
        instance = (pixels(kept[(self._instance, f.instance)], "instance",
                            self._where(self._instance, f.instance))
                    if f.instance is not None and self._instance is not None else None)
        if instance is not None and instance.shape != depth.shape:
            instance = None
        return Observation(rgb=rgb, depth_m=depth, cam_to_world=f.cam_to_world.copy(),
                           intrinsics=f.intrinsics.copy(), pose=floor_pose(f.cam_to_world),
                           instance=instance)

    def close(self) -> None:
        pass

