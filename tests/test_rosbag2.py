"""Recordings as ROS 2 writes them, checked by an independent reader: what ``--record`` writes
(a bare .mcap and a rosbag2 folder) opened by ``rosbags`` with ROS 2 Humble's message types, and
a rosbag2 folder that ``rosbags``' own writer made, split in two files, read through
``recorded:`` to the same walk and answer as the single file. The frames are made by hand (no
renderer), with a simulator's labels so that the stub stack can answer."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from agent_stubs import MentionScorer, seeking_model
from efficienteqa.agent import AgentConfig
from efficienteqa.ask import ask
from efficienteqa.envs.base import is_rendered
from efficienteqa.envs.recorded import open_recording
from efficienteqa.envs.recorded.labels import LABELS_FORMAT, RecordedLabels
from efficienteqa.envs.recorded.walk import floor_pose, intrinsics_matrix
from efficienteqa.envs.recorded.write import WalkRecorder
from efficienteqa.errors import EfficientEQAError
from efficienteqa.observation import Observation
from efficienteqa.scenes import open_scene
from efficienteqa.stack import Stack

pytest.importorskip("mcap_ros2")
pytest.importorskip("rosbags")
yaml = pytest.importorskip("yaml")

from rosbags.highlevel import AnyReader  # noqa: E402 - after the skip
from rosbags.rosbag2 import StoragePlugin, Writer  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

QUESTION = "What colour is the bed?"
N, W, H = 6, 32, 24
K = (30.0, 31.0, 15.5, 11.5)  # fx, fy, cx, cy in OpenCV's convention, as CameraInfo holds them
T0 = 1_700_000_000_000_000_000
STEP_NS = 200_000_000
BED = 12
LABELS = {"format": LABELS_FORMAT,
          "objects": [{"id": BED, "category": "bed", "colour": "white", "state": None,
                       "room": "bedroom", "door": None}],
          "rooms": [{"name": "bedroom", "polygon": [[-5, -5], [5, -5], [5, 5], [-5, 5]]}]}
HUMBLE = get_typestore(Stores.ROS2_HUMBLE)
TOPICS = {"/camera/color/image_raw": "sensor_msgs/msg/Image",
          "/camera/aligned_depth_to_color/image_raw": "sensor_msgs/msg/Image",
          "/camera/color/camera_info": "sensor_msgs/msg/CameraInfo",
          "/tf": "tf2_msgs/msg/TFMessage",
          "/efficienteqa/instance": "sensor_msgs/msg/Image",
          "/efficienteqa/labels": "std_msgs/msg/String"}


def _camera(k: int) -> np.ndarray:
    """Camera k at 1.2 m, looking level along yaw 60k degrees (OpenCV axes in the map frame)."""
    yaw = math.radians(60 * k)
    forward = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    pose = np.eye(4)
    pose[:3, :3] = np.stack([right, [0.0, 0.0, -1.0], forward], axis=1)
    pose[:3, 3] = [0.5 * k, -0.25 * k, 1.2]
    return pose


def _frames(labelled: bool = True) -> list[Observation]:
    frames = []
    y, x = np.mgrid[0:H, 0:W]
    for k in range(N):
        rgb = np.stack([y * 7, x * 5, np.full_like(x, 30 * k)], axis=-1).astype(np.uint8)
        depth = (1.5 + 0.01 * x + 0.1 * k).astype(np.float32)
        instance = np.where(x < W // 2 + k, BED, 0).astype(np.int32) if labelled else None
        pose = _camera(k)
        frames.append(Observation(rgb=rgb, depth_m=depth, cam_to_world=pose,
                                  intrinsics=intrinsics_matrix(*K), pose=floor_pose(pose),
                                  instance=instance))
    return frames


def _record(path: Path, layout: str | None = None, labelled: bool = True) -> list[Observation]:
    frames = _frames(labelled)
    labels = RecordedLabels.from_json(LABELS, "test") if labelled else None
    with WalkRecorder(path, labels=labels, layout=layout) as recorder:
        for k, obs in enumerate(frames):
            recorder.add(obs, stamp_ns=T0 + k * STEP_NS)
    return frames


def _read(walk) -> list[Observation]:
    obs, _ = walk.reset()
    got = [obs]
    while True:
        obs, _, ended, _, _ = walk.step(obs.pose)
        if ended:
            return got
        got.append(obs)


# -- what --record writes, opened by rosbags with ROS 2 Humble's types ------------------------
@pytest.mark.parametrize("layout", ["mcap", "rosbag2"])
def test_rosbags_reads_what_record_writes_with_humble_types(tmp_path, layout):
    path = tmp_path / ("walk.mcap" if layout == "mcap" else "walk")
    frames = _record(path, layout)
    if layout == "rosbag2":
        assert sorted(p.name for p in path.iterdir()) == ["metadata.yaml", "walk_0.mcap"]
    with AnyReader([path], default_typestore=HUMBLE) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == TOPICS
        # Each topic's offered QoS on its channel, as rosbag2 keeps it (Humble's play needs it).
        assert all(c.ext.offered_qos_profiles for c in reader.connections)
        counts: dict[str, int] = {}
        seen: dict[str, list] = {}
        for connection, stamp, raw in reader.messages():
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
            msg = reader.deserialize(raw, connection.msgtype)
            seen.setdefault(connection.topic, []).append((stamp, msg))
        assert counts == {**{t: N for t in TOPICS}, "/efficienteqa/labels": 1}
        assert reader.message_count == 5 * N + 1
        assert reader.start_time == T0
    for k, obs in enumerate(frames):
        stamp = T0 + k * STEP_NS
        t, colour = seen["/camera/color/image_raw"][k]
        assert t == stamp and colour.encoding == "rgb8" and (colour.width, colour.height) == (W, H)
        assert colour.header.frame_id == "camera_color_optical_frame"
        assert colour.header.stamp.sec * 10**9 + colour.header.stamp.nanosec == stamp
        assert np.array_equal(colour.data.reshape(H, W, 3), obs.rgb)
        _, depth = seen["/camera/aligned_depth_to_color/image_raw"][k]
        assert depth.encoding == "32FC1" and depth.step == 4 * W
        assert depth.header.frame_id == "camera_color_optical_frame"
        assert np.array_equal(depth.data.view("<f4").reshape(H, W), obs.depth_m)
        _, info = seen["/camera/color/camera_info"][k]
        assert info.distortion_model == "plumb_bob" and (info.width, info.height) == (W, H)
        assert np.array_equal(info.k, [K[0], 0, K[2], 0, K[1], K[3], 0, 0, 1])
        _, tf = seen["/tf"][k]
        (transform,) = tf.transforms
        assert (transform.header.frame_id, transform.child_frame_id) == \
               ("map", "camera_color_optical_frame")
        tr, q = transform.transform.translation, transform.transform.rotation
        assert np.allclose([tr.x, tr.y, tr.z], obs.cam_to_world[:3, 3], atol=1e-12)
        x, y, z, w = q.x, q.y, q.z, q.w  # the quaternion's rotation is the camera's
        rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        assert np.allclose(rot, obs.cam_to_world[:3, :3], atol=1e-9)
        _, instance = seen["/efficienteqa/instance"][k]
        assert instance.encoding == "32SC1"
        assert np.array_equal(instance.data.view("<i4").reshape(H, W), obs.instance)
    (_, labels), = seen["/efficienteqa/labels"]
    assert json.loads(labels.data)["objects"] == LABELS["objects"]
    if layout == "rosbag2":
        _check_metadata(path / "metadata.yaml")


def _check_metadata(path: Path) -> None:
    """The keys and units of rosbag2's own metadata (version 5, Humble's), as ros2 bag info reads
    them."""
    info = yaml.safe_load(path.read_text())["rosbag2_bagfile_information"]
    duration = (N - 1) * STEP_NS + 1  # the labels, 1 ns after the last frame
    assert info["version"] == 5 and info["storage_identifier"] == "mcap"
    assert info["duration"] == {"nanoseconds": duration}
    assert info["starting_time"] == {"nanoseconds_since_epoch": T0}
    assert info["message_count"] == 5 * N + 1
    assert (info["compression_format"], info["compression_mode"]) == ("", "")
    assert info["relative_file_paths"] == ["walk_0.mcap"]
    assert info["files"] == [{"path": "walk_0.mcap", "starting_time": {
        "nanoseconds_since_epoch": T0}, "duration": {"nanoseconds": duration},
        "message_count": 5 * N + 1}]
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert {name: t["topic_metadata"]["type"] for name, t in topics.items()} == TOPICS
    for name, t in topics.items():
        assert t["message_count"] == (1 if name == "/efficienteqa/labels" else N)
        assert t["topic_metadata"]["serialization_format"] == "cdr"
        (qos,) = yaml.safe_load(t["topic_metadata"]["offered_qos_profiles"])  # a YAML string
        assert (qos["history"], qos["depth"], qos["reliability"], qos["durability"]) == (1, 10, 1, 2)


# -- a rosbag2 folder rosbags wrote, split in two files, read through recorded: ---------------
def _split_bag(source: Path, folder: Path) -> int:
    """The messages of ``source`` rewritten by rosbags' writer into a bag folder of two .mcap
    files, split mid-frame. rosbags' writer does not split a bag by itself: two bags are written
    and assembled into one folder, with one metadata.yaml listing both files in order, as
    ``ros2 bag record --max-bag-size`` lays them out. Returns where the split is."""
    with AnyReader([source], default_typestore=HUMBLE) as reader:
        messages = [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in reader.messages()]
    half = len(messages) // 2 + 2  # a frame's colour in one file, its depth in the next
    metas = []
    for n, part in enumerate((messages[:half], messages[half:])):
        bag = folder.parent / f"part{n}"
        with Writer(bag, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
            connections = {topic: writer.add_connection(topic, kind, typestore=HUMBLE)
                           for topic, kind in TOPICS.items()}
            for topic, _, stamp, raw in part:
                writer.write(connections[topic], stamp, raw)
        (mcap,) = bag.glob("*.mcap")
        folder.mkdir(exist_ok=True)
        shutil.move(mcap, folder / f"{folder.name}_{n}.mcap")
        metas.append(yaml.safe_load((bag / "metadata.yaml").read_text())
                     ["rosbag2_bagfile_information"])
    info = metas[0]
    info["relative_file_paths"] = [f"{folder.name}_{n}.mcap" for n in range(2)]
    info["files"] = [{**m["files"][0], "path": name}
                     for m, name in zip(metas, info["relative_file_paths"])]
    info["message_count"] = len(messages)
    (folder / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}))
    return half


def _ask(spec: str, out: Path):
    scene = open_scene(f"recorded:{spec}")
    try:
        return scene, ask(QUESTION, scene, out, stack=Stack(grouping="rules",
                                                            explore_scorer="direction-logit"),
                          config=AgentConfig.of(max_steps=N + 2, matching="words"),
                          model=seeking_model("bed", "bedroom"), relevancy=MentionScorer("bed"),
                          report=False)
    finally:
        scene.env.close()


def test_a_bag_folder_split_in_two_reads_as_the_single_file(tmp_path):
    single = tmp_path / "walk.mcap"
    _record(single)
    folder = tmp_path / "bag"
    half = _split_bag(single, folder)
    assert 0 < half < 5 * N + 1 and sorted(p.name for p in folder.iterdir()) == \
           ["bag_0.mcap", "bag_1.mcap", "metadata.yaml"]
    one, two = open_recording(str(single)), open_recording(str(folder))
    assert two.source.files == [folder / "bag_0.mcap", folder / "bag_1.mcap"]
    assert one.length == two.length == N
    assert two.note == f"bag: {N} frames of {N}; with the simulator's labels"
    for a, b in zip(_read(one), _read(two), strict=True):
        for field in ("rgb", "depth_m", "cam_to_world", "intrinsics", "instance"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), field
        assert a.pose == b.pose
    assert two.scene_labels().objects() == one.scene_labels().objects()
    one.close(), two.close()

    scene_a, a = _ask(str(single), tmp_path / "a")
    scene_b, b = _ask(str(folder), tmp_path / "b")
    assert scene_b.name == f"recorded:{folder} (rosbag2)" and scene_a.name.endswith("(mcap)")
    assert a.result.answer == b.result.answer and "white" in a.result.answer.lower()
    assert a.result.steps == b.result.steps and a.result.retrieved == b.result.retrieved
    assert [r.check.sim if r.check else None for r in a.result.records] == \
           [r.check.sim if r.check else None for r in b.result.records]

    # Cut or copied by hand, without metadata.yaml: the files in file-name order, with a note.
    (folder / "metadata.yaml").unlink()
    (folder / "bag_1.mcap").rename(folder / "bag_10.mcap")  # numbers by value: 0 before 10
    bare = open_recording(str(folder))
    assert [p.name for p in bare.source.files] == ["bag_0.mcap", "bag_10.mcap"]
    assert bare.note == (f"bag: {N} frames of {N}; with the simulator's labels; no metadata.yaml: "
                         "its 2 .mcap files read in file-name order (bag_0.mcap, bag_10.mcap)")
    assert all(np.array_equal(x.rgb, y.rgb) for x, y in zip(_read(bare), _frames(), strict=True))
    bare.close()


def test_record_format_rosbag2_reads_back_and_refuses_what_it_cannot_be(tmp_path):
    frames = _record(tmp_path / "walk", "rosbag2")
    walk = open_recording(str(tmp_path / "walk"))
    assert walk.source.layout == "rosbag2" and walk.length == N
    assert all(np.array_equal(a.depth_m, b.depth_m) for a, b in zip(_read(walk), frames))
    walk.close()
    with pytest.raises(EfficientEQAError, match="is a folder, and .* ends in .mcap"):
        WalkRecorder(tmp_path / "x.mcap", layout="rosbag2")
    with pytest.raises(EfficientEQAError, match="is a file ending in .mcap"):
        WalkRecorder(tmp_path / "x", layout="mcap")
    with pytest.raises(EfficientEQAError, match="--record-format mcap or rosbag2 or frames"):
        WalkRecorder(tmp_path / "x", layout="bag")
    with pytest.raises(EfficientEQAError, match="never written over"):
        WalkRecorder(tmp_path / "walk", layout="rosbag2")


@pytest.mark.parametrize(("case", "says"), [
    ("sqlite3", "in sqlite3 storage; only MCAP storage is read (convert it to MCAP with ROS 2: "
                "ros2 bag convert -i"),
    ("db3", "holds a rosbag2 recording in sqlite3 storage (.db3)"),
    ("compressed", "is compressed (zstd, by file)"),
    ("missing", "lists bag_1.mcap, which is missing"),
    ("outside", "lists '../elsewhere.mcap', outside the bag folder"),
    ("not-yaml", "cannot read"),
])
def test_a_bag_that_cannot_be_read_is_one_line(tmp_path, case, says):
    folder = tmp_path / "bag"
    folder.mkdir()
    info = {"version": 5, "storage_identifier": "mcap", "relative_file_paths": ["bag_0.mcap"],
            "compression_format": "", "compression_mode": ""}
    (folder / "bag_0.mcap").write_bytes(b"")
    if case == "sqlite3":
        info["storage_identifier"], info["relative_file_paths"] = "sqlite3", ["bag_0.db3"]
    elif case == "compressed":
        info["compression_format"], info["compression_mode"] = "zstd", "file"
    elif case == "missing":
        info["relative_file_paths"] = ["bag_0.mcap", "bag_1.mcap"]
    elif case == "outside":
        (tmp_path / "elsewhere.mcap").write_bytes(b"")
        info["relative_file_paths"] = ["../elsewhere.mcap"]
    if case == "db3":
        (folder / "bag_0.mcap").unlink()
        (folder / "bag_0.db3").write_bytes(b"")
    elif case == "not-yaml":
        (folder / "metadata.yaml").write_text("rosbag2_bagfile_information: [\n")
    else:
        (folder / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}))
    with pytest.raises(EfficientEQAError) as raised:
        open_recording(str(folder))
    assert says in str(raised.value) and "\n" not in str(raised.value)


# -- the pixel network on frames no simulator rendered ----------------------------------------
def test_pixels_on_a_robots_recording_say_once_to_use_an_image_vlm(tmp_path, capsys):
    from efficienteqa.stack import build_agent, say_once

    _record(tmp_path / "robot.mcap", labelled=False)
    _record(tmp_path / "sim.mcap")
    robot, sim = open_recording(str(tmp_path / "robot.mcap")), open_recording(str(tmp_path / "sim.mcap"))
    assert not is_rendered(robot) and is_rendered(sim) and not is_rendered(object())
    say_once.cache_clear()
    for env in (sim, robot, robot):  # said for the robot's frames only, and once
        build_agent(env, Stack(perception="pixels", grouping="rules"), AgentConfig(), "recorded",
                    model=seeking_model("bed", "bedroom"), relevancy=MentionScorer("bed"))
    err = capsys.readouterr().err
    assert err.count("trained on synthetic renders only") == 1
    assert "--backends.perception rgb --backends.vlm openai:gpt-4o" in err
    robot.close(), sim.close()


def test_hm3d_scans_look_real_and_the_synthetic_houses_do_not(small_camera):
    """HM3D's houses are textured from photographs: the pixel network's note is said there too."""
    from efficienteqa.envs.base import looks_real
    from efficienteqa.envs.habitat.env import HabitatEnv
    from efficienteqa.envs.synthetic.env import SyntheticEnv

    house = SyntheticEnv.from_seed(1, "builtin", camera=small_camera)
    try:
        assert not looks_real(house) and HabitatEnv.scanned
        house.scanned = True  # a simulated scene that says it is a scan
        assert looks_real(house)
    finally:
        house.close()


def test_the_cli_asks_for_a_bag_folder_by_record_format(cli, tmp_path):
    help_text = " ".join(cli("ask", "--help").stdout.split())
    assert "--record-format" in help_text and "rosbag2" in help_text
    for args, says in ((("--record", str(tmp_path / "w.mcap"), "--record-format", "rosbag2"),
                        "a rosbag2 recording is a folder"),
                       (("--record-format", "rosbag2"), "there is no --record"),
                       (("--record", str(tmp_path / "w"), "--record-format", "bag"),
                        "unknown recording layout 'bag'")):
        result = cli("ask", QUESTION, *args, "--out", str(tmp_path / "out"))
        assert result.returncode == 1 and says in " ".join(result.stdout.split()), result.stdout
        assert len([line for line in result.stdout.splitlines() if line.strip()]) == 1
    assert not (tmp_path / "w").exists() and not (tmp_path / "out" / "episode.json").exists()
