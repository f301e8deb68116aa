"""Recorded walks (envs.recorded): an MCAP file as ROS 2 records one, or a folder, replayed as a
``Recording``; any episode written as either. Nothing here runs on a robot: the MCAP files are
written by efficienteqa's own writer or by hand through mcap_ros2, the way ``ros2 bag record``
lays them out."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from agent_stubs import MentionScorer, seeking_model
from conftest import needs_egl
from efficienteqa.agent import AgentConfig
from efficienteqa.ask import ask
from efficienteqa.envs.base import is_recording
from efficienteqa.envs.checks import check_arrays
from efficienteqa.envs.recorded import open_recording
from efficienteqa.envs.recorded.write import WalkRecorder
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D
from efficienteqa.perception.semantic import SemanticPerception
from efficienteqa.scenes import Scene, open_scene
from efficienteqa.stack import Stack

pytest.importorskip("mcap_ros2")

QUESTION = "What colour is the bed?"


@pytest.fixture(scope="module")
def small_env(catalog, small_camera):
    from efficienteqa.envs.synthetic.env import SyntheticEnv
    from efficienteqa.envs.synthetic.generate import generate_house

    env = SyntheticEnv(generate_house(3, catalog, "builtin"), catalog, camera=small_camera)
    yield env
    env.close()


def _walk(env, n: int = 7) -> list:
    start = env.start
    return [env.observe(Pose2D(start.x, start.y, start.yaw + k * 2 * math.pi / n + 4 * math.pi))
            for k in range(n)]


def _read(walk) -> list:
    obs, _ = walk.reset()
    frames = [obs]
    while True:
        obs, _, ended, _, _ = walk.step(Pose2D(0.0, 0.0, 0.0))
        if ended:
            assert obs is frames[-1]  # past the end: the last frame again
            return frames
        frames.append(obs)


# -- round trips ---------------------------------------------------------------------------
@needs_egl
@pytest.mark.parametrize(("name", "depth", "depth_tol"), [("walk.mcap", "32FC1", 0.0),
                                                         ("walk.mcap", "16UC1", 0.0005),
                                                         ("walk", "16UC1", 0.0005),
                                                         ("walk", "32FC1", 0.0)])
def test_a_synthetic_walk_reads_back_as_it_was_written(small_env, tmp_path, name, depth, depth_tol):
    frames = _walk(small_env)
    path = tmp_path / name
    with WalkRecorder(path, labels=small_env.scene_labels(), depth_encoding=depth) as recorder:
        for obs in frames:
            recorder.add(obs)
    walk = open_recording(str(path))
    assert is_recording(walk) and walk.length == len(frames)
    assert (walk.camera.width, walk.camera.height) == (160, 120)
    got = _read(walk)
    assert len(got) == len(frames)
    for want, obs in zip(frames, got):
        check_arrays(obs, walk)
        assert np.array_equal(obs.rgb, want.rgb)
        assert np.max(np.abs(obs.depth_m - want.depth_m)) <= depth_tol
        assert np.array_equal(obs.depth_m > 0, want.depth_m > 0)
        assert np.max(np.abs(obs.cam_to_world - want.cam_to_world)) < 1e-6
        assert np.array_equal(obs.intrinsics, want.intrinsics)
        assert np.array_equal(obs.instance, want.instance)
        # The floor pose: the camera's centre, the yaw of its optical axis (wrapped).
        assert math.dist((obs.pose.x, obs.pose.y), (want.pose.x, want.pose.y)) < 1e-6
        assert abs(math.remainder(obs.pose.yaw - want.pose.yaw, math.tau)) < 1e-6
    # The simulator's labels travel with the walk: every object, and the rooms at every point.
    truth, labels = small_env.scene_labels(), walk.scene_labels()
    assert labels.objects() == truth.objects() and labels.categories()
    lo, hi = small_env.bounds
    for x in np.linspace(lo[0] - 0.5, hi[0] + 0.5, 41):
        for y in np.linspace(lo[1] - 0.5, hi[1] + 0.5, 41):
            assert labels.room_at(x, y) == truth.room_at(x, y)
    for room in small_env.house.layout.rooms:  # on the wall lines too
        assert labels.room_at(room.x0, room.y1) == truth.room_at(room.x0, room.y1)
    walk.close()


@needs_egl
def test_a_folder_keeps_instance_ids_as_16_bit_pngs_and_larger_ids_as_npy(small_env, tmp_path):
    """Ids that fit 16 bits go to a PNG (a tenth of the .npy's size); a frame with a larger id
    keeps its .npy; both read back exactly."""
    from dataclasses import replace

    frames = _walk(small_env, n=2)
    big = replace(frames[1], instance=frames[1].instance.astype(np.int32) + 70_000)
    with WalkRecorder(tmp_path / "walk", labels=small_env.scene_labels()) as recorder:
        recorder.add(frames[0])
        recorder.add(big)
    rows = [json.loads(line) for line in (tmp_path / "walk" / "poses.jsonl").read_text().splitlines()]
    assert [r["instance"] for r in rows] == ["instance/000000.png", "instance/000001.npy"]
    got = _read(open_recording(str(tmp_path / "walk")))
    assert np.array_equal(got[0].instance, frames[0].instance) and got[0].instance.dtype == np.int32
    assert np.array_equal(got[1].instance, big.instance)


@needs_egl
def test_a_replayed_recording_gives_the_live_episodes_texts_and_answer(small_env, tmp_path):
    """The live episode, recorded through real encodings, replayed through the agent with the
    same stub models: the same perception texts on the same frames, the same Sims, the same
    answer from the same frames."""
    config = AgentConfig.of(max_steps=8, matching="words")
    stack = Stack(grouping="rules", explore_scorer="direction-logit")
    texts: dict[str, list[str]] = {"live": [], "replay": []}

    def hook(key, labels):
        perception = SemanticPerception(labels)
        return lambda record, obs, _: texts[key].append(perception.frame(obs))

    live_model = seeking_model("bed", "bedroom")
    live = ask(QUESTION, Scene(small_env, "synthetic:3 (builtin)"), tmp_path / "live", stack=stack,
               config=config, model=live_model, relevancy=MentionScorer("bed"),
               on_step=hook("live", small_env.scene_labels()), record=tmp_path / "walk.mcap")
    walk = open_scene(f"recorded:{tmp_path / 'walk.mcap'}")
    assert walk.env.length == live.result.steps and "with the simulator's labels" in walk.note
    replay_model = seeking_model("bed", "bedroom")
    replay = ask(QUESTION, walk, tmp_path / "replay", stack=stack, config=config,
                 model=replay_model, relevancy=MentionScorer("bed"),
                 on_step=hook("replay", walk.env.scene_labels()))
    walk.env.close()
    a, b = live.result, replay.result
    assert texts["live"] == texts["replay"] and any("bed" in t for t in texts["live"])
    assert [r.check.sim if r.check else None for r in a.records] == \
           [r.check.sim if r.check else None for r in b.records]
    assert b.stop_reason == ("relevancy" if a.stop_reason == "relevancy" else "ended")
    assert b.steps == a.steps and b.retrieved == a.retrieved
    assert b.answer == a.answer and b.confidence == a.confidence
    # What the answer model read of the retrieved frames is the same text.
    answer = [r.messages[-1].text for r in live_model.requests if "robot explored" in
              r.messages[-1].text]
    assert answer and answer == [r.messages[-1].text for r in replay_model.requests
                                 if "robot explored" in r.messages[-1].text]
    assert replay.record["scene"].startswith("recorded:")
    assert replay.record["backends"]["environment"] == "recorded (mcap)"


# -- an MCAP written by hand, as a robot's ROS 2 stack records one ---------------------------
# The definitions as `ros2 bag record` stores them: each type's .msg text with its comments,
# then the types it uses.
SEP = "=" * 80 + "\n"
HEADER = ("# Standard metadata for higher-level stamped data types.\n"
          "builtin_interfaces/Time stamp\n# Transform frame with which this data is associated.\n"
          "string frame_id\n" + SEP + "MSG: builtin_interfaces/Time\n"
          "# The seconds component, valid over all int32 values.\nint32 sec\n"
          "# The nanoseconds component, valid in the range [0, 10e9).\nuint32 nanosec\n")
IMAGE = ("# This message contains an uncompressed image\nstd_msgs/Header header\n"
         "uint32 height  # image height, that is, number of rows\nuint32 width\n"
         "string encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n"
         + SEP + "MSG: std_msgs/Header\n" + HEADER)
INFO = ("std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n"
        "float64[] d\nfloat64[9]  k # 3x3 row-major matrix\nfloat64[9]  r\nfloat64[12] p\n"
        "uint32 binning_x\nuint32 binning_y\nRegionOfInterest roi\n" + SEP
        + "MSG: std_msgs/Header\n" + HEADER + SEP + "MSG: sensor_msgs/RegionOfInterest\n"
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n")
TF = ("geometry_msgs/TransformStamped[] transforms\n" + SEP
      + "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n"
      "Transform transform\n" + SEP + "MSG: std_msgs/Header\n" + HEADER + SEP
      + "MSG: geometry_msgs/Transform\nVector3 translation\nQuaternion rotation\n" + SEP
      + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n" + SEP
      + "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n")

S = 1_000_000_000
T0 = 1_700_000_000 * S  # the robot's clock
W, H = 32, 24
K = (30.0, 31.0, 15.5, 11.5)  # fx, fy, cx, cy (OpenCV's convention)
CAMERA_LINK = (np.array([0.1, 0.0, 1.2]), 0.35)  # on base_link, pitched down 0.35 rad
OPTICAL = (np.array([0.0, -0.015, 0.0]), np.array([-0.5, 0.5, -0.5, 0.5]))  # rpy (-pi/2, 0, -pi/2)
MAP_ODOM = (np.array([1.0, -2.0, 0.0]), 0.25)


def _rz(a: float) -> np.ndarray:
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


def _ry(a: float) -> np.ndarray:
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def _pose(rot: np.ndarray, t: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rot, t
    return out


def _robot(t: float) -> tuple[np.ndarray, float]:
    """base_link in odom at t seconds: 0.5 m/s along x, 0.2 along y, turning 0.3 rad/s."""
    return np.array([0.5 * t, 0.2 * t, 0.0]), 0.3 * t


def expected_camera(t: float) -> np.ndarray:
    """map -> camera_color_optical_frame at t seconds, from the motion above (no quaternions)."""
    robot_t, yaw = _robot(t)
    optical = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)
    return (_pose(_rz(MAP_ODOM[1]), MAP_ODOM[0]) @ _pose(_rz(yaw), robot_t)
            @ _pose(_ry(CAMERA_LINK[1]), CAMERA_LINK[0]) @ _pose(optical, OPTICAL[0]))


def _header(stamp: int, frame: str) -> dict:
    return {"stamp": {"sec": stamp // S, "nanosec": stamp % S}, "frame_id": frame}


def _tf(stamp: int, parent: str, child: str, t, q) -> dict:
    return {"header": _header(stamp, parent), "child_frame_id": child,
            "transform": {"translation": dict(zip("xyz", map(float, t))),
                          "rotation": dict(zip("xyzw", map(float, q)))}}


def _zq(a: float) -> tuple[float, ...]:
    return (0.0, 0.0, math.sin(a / 2), math.cos(a / 2))


COLOUR_TIMES = [0.05 + 0.1 * k for k in range(15)] + [2.5]  # the last is past the TF's end
NO_DEPTH = 5  # this colour frame has no depth within 50 ms


def colour_pixels(k: int) -> np.ndarray:
    """The RGB image of colour frame k (the file holds it as BGR)."""
    y, x = np.mgrid[0:H, 0:W]
    return np.stack([y * 5, x * 3, np.full_like(x, 10 * k)], axis=-1).astype(np.uint8)


def depth_mm(k: int, h: int = H, w: int = W) -> np.ndarray:
    return (1000 + 10 * k + np.mgrid[0:h, 0:w][1]).astype(np.uint16)


def write_bag(path: Path, *, colour: bool = True, depth_size: tuple[int, int] = (W, H),
              depth_shift_s: float = 0.007, map_odom: bool = True, second_colour: bool = False,
              extra_depth: bool = True, tf_shift_s: float = 0.0) -> None:
    """A walk as a robot records it: map -> odom (5 Hz) -> base_link (50 Hz) on /tf,
    base_link -> camera_link -> camera_color_optical_frame on /tf_static, colour (bgr8, 10 Hz)
    with its camera_info, depth aligned to colour (16UC1) 7 ms after each colour frame and
    logged 30 ms late, and the depth camera's own unaligned depth (another size and frame)."""
    from mcap_ros2.writer import Writer

    with open(path, "wb") as stream, Writer(stream) as writer:
        image = writer.register_msgdef("sensor_msgs/msg/Image", IMAGE)
        info = writer.register_msgdef("sensor_msgs/msg/CameraInfo", INFO)
        tf = writer.register_msgdef("tf2_msgs/msg/TFMessage", TF)
        link_t, pitch = CAMERA_LINK
        writer.write_message("/tf_static", tf, {"transforms": [
            _tf(T0, "base_link", "camera_link", link_t, (0.0, math.sin(pitch / 2), 0.0,
                                                         math.cos(pitch / 2))),
            _tf(T0, "camera_link", "camera_color_optical_frame", *OPTICAL)]}, log_time=T0)
        for n in range(101):  # 0 to 2 s
            t = n * 0.02
            stamp = T0 + round((t + tf_shift_s) * S)
            robot_t, yaw = _robot(t)
            transforms = [_tf(stamp, "odom", "base_link", robot_t, _zq(yaw))]
            if map_odom and n % 10 == 0:
                transforms.append(_tf(stamp, "map", "odom", MAP_ODOM[0], _zq(MAP_ODOM[1])))
            writer.write_message("/tf", tf, {"transforms": transforms}, log_time=stamp)
        for k, t in enumerate(COLOUR_TIMES):
            stamp = T0 + round(t * S)
            head = _header(stamp, "camera_color_optical_frame")
            if colour:
                bgr = colour_pixels(k)[..., ::-1]
                for topic in ["/camera/color/image_raw"] + (["/cam2/image"] if second_colour else []):
                    writer.write_message(topic, image, {
                        "header": head, "height": H, "width": W, "encoding": "bgr8",
                        "is_bigendian": 0, "step": 3 * W, "data": bgr.tobytes()}, log_time=stamp)
            writer.write_message("/camera/color/camera_info", info, {
                "header": head, "height": H, "width": W, "distortion_model": "plumb_bob",
                "d": [0.0] * 5, "k": [K[0], 0.0, K[2], 0.0, K[1], K[3], 0.0, 0.0, 1.0],
                "r": [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0],
                "p": [K[0], 0.0, K[2], 0.0, 0.0, K[1], K[3], 0.0, 0.0, 0.0, 1.0, 0.0]},
                log_time=stamp)
            if k != NO_DEPTH:
                d_stamp = stamp + round(depth_shift_s * S)
                dw, dh = depth_size
                writer.write_message("/camera/aligned_depth_to_color/image_raw", image, {
                    "header": _header(d_stamp, "camera_color_optical_frame"), "height": dh,
                    "width": dw, "encoding": "16UC1", "is_bigendian": 0, "step": 2 * dw,
                    "data": depth_mm(k, dh, dw).tobytes()}, log_time=d_stamp + round(0.03 * S))
            if extra_depth:
                writer.write_message("/camera/depth/image_rect_raw", image, {
                    "header": _header(stamp, "camera_depth_optical_frame"), "height": 12,
                    "width": 16, "encoding": "16UC1", "is_bigendian": 0, "step": 32,
                    "data": depth_mm(k, 12, 16).tobytes()}, log_time=stamp)


def test_a_robots_mcap_with_a_tf_tree_reads_as_the_camera_moved(tmp_path):
    path = tmp_path / "robot.mcap"
    write_bag(path)
    walk = open_recording(str(path))
    used = [k for k in range(len(COLOUR_TIMES) - 1) if k != NO_DEPTH]
    assert walk.length == len(used)
    assert "2 dropped: 1 without depth within 50 ms, 1 without a pose from 'map'" in walk.note
    assert np.array_equal(walk.camera.intrinsics, [[30, 0, 16], [0, 31, 12], [0, 0, 1]])
    frames = _read(walk)
    assert len(frames) == len(used)
    for k, obs in zip(used, frames):
        check_arrays(obs, walk)
        assert np.array_equal(obs.rgb, colour_pixels(k))  # bgr8 read as RGB
        assert np.array_equal(obs.depth_m, depth_mm(k).astype(np.float32) / np.float32(1000))
        want = expected_camera(COLOUR_TIMES[k])  # between TF samples: interpolated
        assert np.max(np.abs(obs.cam_to_world - want)) < 1e-6, k
        assert obs.instance is None
        # The floor pose: the camera's centre; its optical axis is the robot's heading in map.
        assert math.dist((obs.pose.x, obs.pose.y), want[:2, 3]) < 1e-9
        assert abs(math.remainder(obs.pose.yaw - (MAP_ODOM[1] + _robot(COLOUR_TIMES[k])[1]),
                                  math.tau)) < 1e-6
    assert obs.cam_to_world[2, 3] == pytest.approx(1.2 + 0.015 * 0)  # the camera's height
    # A recording of a robot carries no labels: the semantic perception says what to use.
    with pytest.raises(EfficientEQAError, match="carries no object labels.*perception pixels"):
        walk.scene_labels()
    walk.close()


def test_topics_are_chosen_by_option_where_the_types_do_not_say(tmp_path):
    path = tmp_path / "two.mcap"
    write_bag(path, second_colour=True)
    with pytest.raises(EfficientEQAError, match="several colour topics") as error:
        open_recording(str(path))
    assert "?colour=" in str(error.value) and "\n" not in str(error.value)
    walk = open_recording(f"{path}?colour=/cam2/image&depth_tolerance_ms=100")
    assert walk.length == len(COLOUR_TIMES) - 1  # 100 ms: frame 5 finds a depth frame
    with pytest.raises(EfficientEQAError, match="unknown recording option 'colur=x'"):
        open_recording(f"{path}?colur=x")


def test_a_tf_chain_that_ends_elsewhere_can_be_read_from_that_frame(tmp_path):
    path = tmp_path / "odom.mcap"
    write_bag(path, map_odom=False)
    with pytest.raises(EfficientEQAError, match=r"no TF path from 'map'.*ends at 'odom'"):
        open_recording(str(path))
    walk = open_recording(f"{path}?world=odom")
    obs = walk.reset()[0]
    robot_t, yaw = _robot(COLOUR_TIMES[0])
    assert obs.pose.x == pytest.approx(robot_t[0] + 0.1 * math.cos(yaw) + 0.015 * math.sin(yaw))
    walk.close()


# -- the folder format ---------------------------------------------------------------------
def test_a_folder_walk_reads_its_own_layout(tmp_path):
    """Written by hand as the folder's docstring lays it out (not by the recorder)."""
    from PIL import Image

    folder = tmp_path / "walk"
    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    lines = []
    for k in range(3):
        Image.fromarray(colour_pixels(k)).save(folder / "rgb" / f"{k}.png")
        if k == 1:
            np.save(folder / "depth" / f"{k}.npy", depth_mm(k).astype(np.float32) / 1000)
            depth = f"depth/{k}.npy"
        else:
            Image.fromarray(depth_mm(k)).save(folder / "depth" / f"{k}.png")
            depth = f"depth/{k}.png"
        pose = expected_camera(0.3 * k)
        lines.append(json.dumps({"rgb": f"rgb/{k}.png", "depth": depth,
                                 "cam_to_world": pose.tolist(), "fx": K[0], "fy": K[1],
                                 "cx": K[2], "cy": K[3], "stamp": 0.3 * k}))
    (folder / "poses.jsonl").write_text("\n".join(lines) + "\n")
    walk = open_recording(str(folder))
    frames = _read(walk)
    assert walk.length == 3 and len(frames) == 3 and walk.note == "walk: 3 frames"
    for k, obs in enumerate(frames):
        check_arrays(obs, walk)
        assert np.array_equal(obs.rgb, colour_pixels(k))
        assert np.allclose(obs.depth_m, depth_mm(k) / 1000, atol=1e-6)
        assert np.array_equal(obs.cam_to_world, expected_camera(0.3 * k))
        assert np.array_equal(obs.intrinsics, [[30, 0, 16], [0, 31, 12], [0, 0, 1]])


# -- one line for what a user can get wrong, before any model call --------------------------
def _bad(tmp_path: Path, case: str) -> str:
    """The scene spec of a broken recording."""
    path = tmp_path / f"{case}.mcap"
    if case == "corrupt":  # cut short, as when the recorder died
        write_bag(path)
        data = path.read_bytes()
        path.write_bytes(data[:len(data) // 2])
    elif case == "no-colour":
        write_bag(path, colour=False)
    elif case == "no-tf-path":
        write_bag(path, map_odom=False)
    elif case == "no-usable-frame":
        write_bag(path, tf_shift_s=10.0)  # the TF of another time
    elif case == "sizes":
        write_bag(path, depth_size=(16, 12))
    elif case == "folder-missing-file":
        path = tmp_path / "folder"
        path.mkdir()
        (path / "poses.jsonl").write_text(json.dumps({
            "rgb": "rgb/0.png", "depth": "depth/0.png", "cam_to_world": np.eye(4).tolist(),
            "fx": 1, "fy": 1, "cx": 0, "cy": 0}) + "\n")
    elif case == "not-a-walk":
        path = tmp_path / "walk.bag"
        path.write_text("ROS 1")
    return f"recorded:{path}"


BAD = {"missing": "does not exist", "corrupt": "as MCAP", "no-colour": "has no colour topic",
       "no-tf-path": "no TF path from 'map'", "no-usable-frame": "has no usable frame",
       "sizes": "depth must be registered to colour", "folder-missing-file": "rgb file rgb/0.png "
       "is missing", "not-a-walk": "neither an .mcap file nor a walk folder"}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_broken_recording_is_one_line_before_any_model_call(tmp_path, case):
    spec = f"recorded:{tmp_path / 'none.mcap'}" if case == "missing" else _bad(tmp_path, case)
    model = seeking_model("bed", "bedroom")
    with pytest.raises(EfficientEQAError) as error:
        ask(QUESTION, spec, tmp_path / "out", model=model, relevancy=MentionScorer("bed"))
    assert BAD[case] in str(error.value) and "\n" not in str(error.value)
    assert error.value.fix
    assert model.requests == []


def test_the_cli_says_a_broken_recording_in_one_line(cli, tmp_path):
    for case in ("missing", "corrupt", "no-tf-path", "sizes"):
        spec = f"recorded:{tmp_path / 'none.mcap'}" if case == "missing" else _bad(tmp_path, case)
        result = cli("ask", QUESTION, "--scene", spec, "--out", str(tmp_path / "out"))
        assert result.returncode == 1, (case, result.stdout, result.stderr)
        assert BAD[case] in result.stdout.replace("\n", " ") or BAD[case] in result.stdout
        assert "Traceback" not in result.stdout + result.stderr
        assert len([line for line in result.stdout.splitlines() if line.strip()]) == 1
        assert not (tmp_path / "out" / "episode.json").exists()
    start = cli("ask", QUESTION, "--scene", "recorded:walk.mcap", "--start", "1,2,0",
                 "--out", str(tmp_path / "out"))
    assert start.returncode == 1 and "starts where it was recorded" in start.stdout


# -- the command line, end to end, against a chat server with real servers' habits ----------
@needs_egl
def test_ask_records_a_walk_and_ask_and_eval_replay_it(cli, vlm, tmp_path):
    server = vlm()
    env = {**os.environ, "EFFICIENTEQA_CACHE": str(tmp_path / "cache"),
           "PYTHONPATH": os.pathsep.join([str(Path(__file__).parent),
                                          os.environ.get("PYTHONPATH", "")])}
    backends = ("--backends.vlm", f"openai:test-vlm@{server.base_url}", "--backends.relevancy",
                "overlap", "--explore.matching", "words", "--backends.no-cache")
    walk = tmp_path / "walks" / "walk.mcap"
    live = cli("ask", QUESTION, "--scene", "synthetic:3", "--assets", "builtin",
                "--max-steps", "4", *backends, "--record", str(walk), "--out",
                str(tmp_path / "live"), env=env)
    assert live.returncode == 0, live.stdout + live.stderr
    assert f"recorded: {walk}" in live.stdout.replace("\n", "")
    steps = json.loads((tmp_path / "live" / "episode.json").read_text())["steps"]
    again = cli("ask", QUESTION, "--scene", "synthetic:3", "--assets", "builtin", "--max-steps",
                 "1", *backends, "--record", str(walk), "--out", str(tmp_path / "x"), env=env)
    assert again.returncode == 1 and "never written over" in again.stdout

    replay = cli("ask", QUESTION, "--scene", f"recorded:{walk}", *backends, "--out",
                  str(tmp_path / "replay"), env=env)
    assert replay.returncode == 0, replay.stdout + replay.stderr
    assert f"walk.mcap: {steps} frames of {steps}; with the simulator's labels" in replay.stdout
    assert "reading frames" in replay.stdout and f"steps: {steps} of {steps}" in replay.stdout
    record = json.loads((tmp_path / "replay" / "episode.json").read_text())
    assert record["stop_reason"] in ("ended", "relevancy")
    assert record["backends"]["perception"] == "semantic-sensor"


@needs_egl
def test_eval_answers_a_file_of_questions_about_a_recording(cli, vlm, small_env, tmp_path):
    """``--eval.dataset FILE.jsonl``: rows with a question, a scene (a recording's path relative
    to the file) and, optionally, the reference answer; a row without one is run, not graded."""
    server = vlm()
    folder = tmp_path / "walks"
    with WalkRecorder(folder / "walk.mcap", labels=small_env.scene_labels()) as recorder:
        for obs in _walk(small_env, 5):
            recorder.add(obs)
    questions = folder / "questions.jsonl"
    questions.write_text(json.dumps({"question": QUESTION, "answer": "white",
                                     "scene": "recorded:walk.mcap", "id": "bed"}) + "\n"
                         + json.dumps({"question": "Is there a sofa?",
                                       "scene": "recorded:walk.mcap"}) + "\n")
    env = {**os.environ, "EFFICIENTEQA_CACHE": str(tmp_path / "cache")}
    run = cli("eval", "--eval.dataset", str(questions), "--eval.judge", "none",
               "--backends.vlm", f"openai:test-vlm@{server.base_url}", "--backends.relevancy",
               "overlap", "--explore.matching", "words", "--out", str(tmp_path / "run"), env=env)
    assert run.returncode == 0, run.stdout + run.stderr
    rows = [json.loads(line) for line in (tmp_path / "run" / "episodes.jsonl").read_text()
            .splitlines()]
    assert [r["id"] for r in rows] == ["bed", "questions/001"]
    assert all(r["status"] == "done" and r["scene"] == f"recorded:{folder / 'walk.mcap'}"
               for r in rows)
    assert all(r["budget"] == 5 and r["stop_reason"] in ("ended", "relevancy") for r in rows)
    assert rows[0]["reference"] == "white" and rows[1]["reference"] == ""
    assert all(r["backends"]["environment"] == "recorded (mcap)" for r in rows)


def test_a_question_without_a_reference_is_run_and_not_graded(tmp_path):
    from efficienteqa.datasets import load_dataset
    from efficienteqa.eval.methods import RunSpec
    from efficienteqa.eval.runner import _judge

    questions = tmp_path / "q.jsonl"
    questions.write_text('{"question": "Is the stove on?", "scene": "recorded:w.mcap"}\n'
                         '{"question": "Where is the cat?", "scene": "recorded:/abs/w.mcap", '
                         '"answer": "on the sofa", "id": "cat"}\n')
    first, second = load_dataset(str(questions))
    assert (first.id, first.scene, first.answer) == ("q/000", f"recorded:{tmp_path / 'w.mcap'}", "")
    assert (second.id, second.scene, second.answer) == ("cat", "recorded:/abs/w.mcap", "on the sofa")
    # A judge that cannot be built: grading the row without a reference would fail.
    spec = RunSpec.of("efficienteqa", str(questions), judge="openai:no-such-model@http://127.0.0.1:9/v1")
    assert _judge(spec, first, "yes") is None
    for text, message in (("{}", "needs a question and a scene"), ("nope", "is not JSON"),
                          ('{"question": "a?", "scene": "recorded:w.mcap", "id": "x"}\n' * 2,
                           "id 'x' is used twice")):
        questions.write_text(text)
        with pytest.raises(EfficientEQAError, match=message):
            load_dataset(str(questions))


def test_rooms_of_any_shape_hold_their_floor_points_edges_included():
    from efficienteqa.envs.recorded.labels import RecordedLabels

    l_shape = [(0, 0), (4, 0), (4, 2), (2, 2), (2, 4), (0, 4)]
    labels = RecordedLabels.from_json({"format": "efficienteqa-labels/1", "objects": [], "rooms": [
        {"name": "hall", "polygon": l_shape}, {"name": "study", "polygon": [(2, 2), (4, 2), (4, 4),
                                                                           (2, 4)]}]}, "test")
    assert [labels.room_at(x, y) for x, y in ((1, 3), (3, 1), (3, 3), (5, 1), (-0.1, 1))] == [
        "hall", "hall", "study", None, None]
    assert labels.room_at(2, 3) == "hall" and labels.room_at(0, 0) == "hall"  # edges: the first
    assert labels.room_at(4, 3) == "study" and labels.room_at(3, 4) == "study"
    assert labels.rooms()[0] == ("hall", [(float(x), float(y)) for x, y in l_shape])
    with pytest.raises(EfficientEQAError, match="cannot read the object labels of test"):
        RecordedLabels.from_json({"format": "efficienteqa-labels/1", "rooms": [
            {"name": "x", "polygon": [(0, 0), (1, 1)]}]}, "test")
