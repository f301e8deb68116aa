"""The ROS 2 adapter (``envs.ros2``) against the stand-in ROS 2 of tests/standin: ``rclpy``, the
messages, ``tf2_ros`` and Nav2's simple commander, behind which a simulated robot
(``sim_robot.SimRobot``) drives through a synthetic house. Nothing here ran on a real robot."""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import needs_egl
from efficienteqa.envs.base import Environment, SimulatedScene
from efficienteqa.envs.checks import check_arrays
from efficienteqa.envs.ros2 import frames
from efficienteqa.envs.ros2.params import Ros2Params
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec, Pose2D, camera_to_world

STANDIN = Path(__file__).parent / "standin"
ROS_PACKAGES = {"rclpy", "builtin_interfaces", "std_msgs", "sensor_msgs", "geometry_msgs",
                "tf2_msgs", "tf2_ros", "action_msgs", "nav2_simple_commander", "sim_robot"}
QUICK = {"frame_timeout_s": 0.4, "tf_timeout_s": 0.4}  # for the tests that wait in vain


def _drop_ros_modules() -> None:
    for name in [m for m in sys.modules if m.partition(".")[0] in ROS_PACKAGES]:
        del sys.modules[name]


@pytest.fixture
def ros(monkeypatch):
    """The stand-in ROS 2, initialised for the test and shut down after it."""
    _drop_ros_modules()
    monkeypatch.syspath_prepend(str(STANDIN))
    import rclpy

    assert rclpy.STANDIN
    rclpy.init()
    yield rclpy
    if rclpy.ok():
        rclpy.shutdown()
    _drop_ros_modules()


@pytest.fixture(scope="module")
def house(catalog):
    env = SyntheticEnv(generate_house(3, catalog, "builtin"), catalog, CameraSpec().scaled(160, 120))
    yield env
    env.close()


@pytest.fixture
def robot(ros, house):
    """Starts a simulated robot (``SimRobot``'s options); each is closed after the test."""
    from sim_robot import SimRobot

    started = []

    def _start(**options):
        started.append(SimRobot(house, **options))
        return started[-1]

    yield _start
    for r in started:
        r.close()


@pytest.fixture
def open_env(ros):
    """Opens the adapter with ``Ros2Params``' values; each is closed after the test."""
    from efficienteqa.envs.ros2.env import Ros2Env

    opened = []

    def _open(**params):
        opened.append(Ros2Env(Ros2Params(**params)))
        return opened[-1]

    yield _open
    for env in opened:
        env.close()


def _near_navigable(house: SyntheticEnv, at: Pose2D, distance: float) -> Pose2D:
    """A navigable pose ``distance`` from ``at`` (the first direction that has one)."""
    for k in range(16):
        a = k * math.tau / 16
        x, y = at.x + distance * math.cos(a), at.y + distance * math.sin(a)
        if house.is_navigable(x, y) and house.is_navigable((x + at.x) / 2, (y + at.y) / 2):
            return Pose2D(x, y, a)
    raise AssertionError("no navigable pose near the start")


def _assert_seen_from(obs, house: SyntheticEnv, pose: Pose2D, depth_atol: float = 6e-4) -> None:
    """The frame is the synthetic camera's at ``pose``, its pose that camera's."""
    assert np.allclose(obs.cam_to_world, camera_to_world(pose, house.camera), atol=1e-6)
    assert (obs.pose.x, obs.pose.y) == pytest.approx((pose.x, pose.y), abs=1e-6)
    assert math.cos(obs.pose.yaw - pose.yaw) == pytest.approx(1.0)
    truth = house.observe(pose)
    assert np.array_equal(obs.rgb, truth.rgb)
    assert np.allclose(obs.depth_m, truth.depth_m, atol=depth_atol)


# -- frames ---------------------------------------------------------------------------------
@needs_egl
def test_frames_pass_the_contract_and_are_the_synthetic_cameras_through_the_tf_chain(
        robot, open_env, house):
    sim = robot()
    env = open_env()
    assert isinstance(env, Environment) and not isinstance(env, SimulatedScene)
    assert not any(hasattr(env, name) for name in ("is_navigable", "bounds", "floor_area_m2"))
    obs, info = env.reset()
    check_arrays(obs, env)
    # map -> odom (off by the odometry offset) -> base_link -> optical frame is the synthetic
    # camera's pose; the intrinsics are the synthetic camera's once ROS's half pixel is undone.
    _assert_seen_from(obs, house, sim.pose)
    assert np.allclose(obs.intrinsics, house.camera.intrinsics)
    assert obs.instance is None and info["pose"] == obs.pose
    assert env.camera.height_m == pytest.approx(house.camera.height_m)
    assert env.camera.pitch_deg == pytest.approx(house.camera.pitch_deg)
    assert env.camera.hfov_deg == pytest.approx(house.camera.hfov_deg)
    assert sim.initial_poses == []  # waiting for Nav2 never re-set the robot's localization


@needs_egl
def test_bgr8_32fc1_and_padded_rows_are_read(robot, open_env, house):
    sim = robot(colour_encoding="bgr8", depth_encoding="32FC1", row_padding=8)
    obs, _ = open_env().reset()
    _assert_seen_from(obs, house, sim.pose, depth_atol=1e-6)  # NaN (no surface) reads as 0
    assert np.all(np.isfinite(obs.depth_m))


# -- moves ----------------------------------------------------------------------------------
@needs_egl
def test_a_reached_goal_is_observed_where_it_ended_not_on_the_way(robot, open_env, house):
    sim = robot(move_s=0.3, fps=60.0)  # frames are published all along the way
    env = open_env()
    env.reset()
    goal = _near_navigable(house, sim.pose, 1.5)
    obs, reward, terminated, truncated, info = env.step(goal)
    assert (reward, terminated, truncated) == (0.0, False, False)
    assert sim.frames > 10 and sim.goals == [goal]
    assert info["result"] == "succeeded" and not info["blocked"] and not info["short"]
    assert info["reached"] == pytest.approx((goal.x, goal.y, goal.yaw), abs=1e-6)
    _assert_seen_from(obs, house, goal)


@needs_egl
def test_a_failed_goal_is_blocked(robot, open_env, house):
    sim = robot()
    env = open_env()
    start, _ = env.reset()
    obs, *_, info = env.step(Pose2D(-20.0, -20.0, 0.0))  # outside the house
    assert info["result"] == "failed" and info["blocked"] and not info["short"]
    assert obs.pose == pytest.approx(start.pose) and sim.pose == house.start


@needs_egl
def test_a_goal_that_stops_short_is_short_and_the_next_frame_is_where_it_ended(robot, open_env,
                                                                                house):
    sim = robot(short=lambda start, goal: 0.5)
    env = open_env()
    env.reset()
    goal = _near_navigable(house, sim.pose, 1.6)
    obs, *_, info = env.step(goal)
    assert info["result"] == "failed" and info["short"] and not info["blocked"]
    assert math.dist((sim.pose.x, sim.pose.y), (goal.x, goal.y)) == pytest.approx(0.8)
    assert info["reached"] == pytest.approx((sim.pose.x, sim.pose.y, sim.pose.yaw), abs=1e-6)
    _assert_seen_from(obs, house, sim.pose)
    assert env.observe().pose == pytest.approx(obs.pose)  # the robot stays where it stopped


@needs_egl
def test_a_goal_past_its_timeout_is_cancelled_and_reads_as_blocked(robot, open_env):
    sim = robot(stall=True)
    env = open_env(move_timeout_s=0.3)
    start, _ = env.reset()
    obs, *_, info = env.step(Pose2D(start.pose.x + 1.0, start.pose.y, 0.0))
    assert sim.cancels == 1
    assert info["result"] == "canceled" and info["timed_out"] and info["blocked"]
    assert obs.pose == pytest.approx(start.pose)


@needs_egl
def test_a_goal_nav2_rejects_is_blocked_and_goals_go_in_map(robot, open_env, house):
    sim = robot(reject=True)  # the stand-in's Nav2 also rejects goals in frames other than map
    env = open_env()
    start, _ = env.reset()
    obs, *_, info = env.step(_near_navigable(house, sim.pose, 1.0))
    assert info["result"] == "rejected" and info["blocked"] and sim.goals == []
    assert obs.pose == pytest.approx(start.pose)


@needs_egl
def test_a_robot_cannot_be_set_down_at_a_start(robot, open_env):
    robot()
    env = open_env()
    with pytest.raises(EfficientEQAError, match="cannot be set down") as error:
        env.reset(options={"start": Pose2D(1.0, 2.0, 0.0)})
    assert "\n" not in str(error.value)


@needs_egl
def test_a_namespaced_nav2_gets_the_goals(robot, open_env, house):
    sim = robot(namespace="robot1")
    env = open_env(namespace="robot1")
    env.reset()
    goal = _near_navigable(house, sim.pose, 1.0)
    assert env.step(goal)[-1]["result"] == "succeeded" and sim.goals == [goal]


# -- what the adapter refuses, in one line ------------------------------------------------------
@needs_egl
@pytest.mark.parametrize(("robot_options", "params", "message"), [
    ({"publish_depth": False}, {}, "no depth image on /camera/aligned_depth_to_color/image_raw"),
    ({"camera_tf": False}, {}, "no transform from map to camera_color_optical_frame"),
    ({"fps": 5.0, "depth_lag_s": 0.1}, {}, "within sync_tolerance_s 0.05 s"),
    ({"depth_stride": 2}, {}, "depth must be registered to colour"),
    ({}, {"color_topic": "/camera/other/image_raw"}, "no colour image on /camera/other/image_raw"),
    ({}, {"info_topic": "/nothing"}, "no camera info on /nothing"),
    ({"colour_encoding": "bgr8"}, {"camera_frame": "camera_link"},
     "no transform from map to camera_link"),
])
def test_what_cannot_be_observed_is_one_line(robot, open_env, robot_options, params, message):
    robot(**robot_options)
    with pytest.raises(EfficientEQAError) as error:
        open_env(**QUICK, **params)
    assert message in str(error.value) and "\n" not in str(error.value)


@needs_egl
def test_frames_that_stop_coming_after_a_move_are_one_line(robot, open_env, house):
    sim = robot()
    env = open_env(**QUICK)
    env.reset()
    sim.period_ns = 10**12  # the camera stops publishing
    with pytest.raises(EfficientEQAError, match="stamped after the robot stopped") as error:
        env.step(_near_navigable(house, sim.pose, 1.0))
    assert "\n" not in str(error.value)


def test_without_ros_2_the_adapter_refuses_in_one_line(monkeypatch):
    from efficienteqa.envs.ros2.env import Ros2Env
    from efficienteqa.scenes import open_scene

    _drop_ros_modules()
    monkeypatch.setitem(sys.modules, "rclpy", None)  # not importable, as where ROS 2 is not sourced
    for opening in (Ros2Env, lambda: open_scene("ros2").env):
        with pytest.raises(EfficientEQAError, match="ROS 2 is not sourced") as error:
            opening()
        assert "source /opt/ros/" in str(error.value) and "\n" not in str(error.value)


def test_without_nav2s_simple_commander_the_adapter_refuses_in_one_line(ros, monkeypatch):
    from efficienteqa.envs.ros2.env import Ros2Env

    monkeypatch.setitem(sys.modules, "nav2_simple_commander.robot_navigator", None)
    with pytest.raises(EfficientEQAError, match="Nav2's simple commander") as error:
        Ros2Env()
    assert "nav2-simple-commander" in str(error.value) and "\n" not in str(error.value)


# -- parameters -------------------------------------------------------------------------------
def test_parameters_come_from_a_toml_file_and_bad_ones_are_one_line(tmp_path):
    path = tmp_path / "robot.toml"
    path.write_text('color_topic = "/head/rgb"\nmove_timeout_s = 30\nwait_for_nav2 = false\n')
    params = Ros2Params.load(path)
    assert (params.color_topic, params.move_timeout_s, params.wait_for_nav2) == ("/head/rgb", 30.0,
                                                                               False)
    assert params.depth_topic == Ros2Params().depth_topic  # left out: the default
    for text, message in (('colour_topic = "/x"', "did you mean 'color_topic'"),
                          ("tf_timeout_s = \"1\"", "must be a float"),
                          ("wait_for_nav2 = 1", "must be a bool"),
                          ("frame_timeout_s = 0", "positive number"),
                          ("map_frame = \"\"", "is empty"),
                          ("move_timeout_s = ", "is not valid TOML")):
        path.write_text(text + "\n")
        with pytest.raises(EfficientEQAError, match=message) as error:
            Ros2Params.load(path)
        assert "\n" not in str(error.value)
    with pytest.raises(EfficientEQAError, match="no ROS 2 parameters file"):
        Ros2Params.load(tmp_path / "none.toml")


# -- conversions ------------------------------------------------------------------------------
def test_big_endian_depth_and_a_transform_are_read():
    class Stamp:
        sec, nanosec = 3, 5

    class Msg:
        height, width, encoding, is_bigendian = 2, 3, "16UC1", 1
        step = 6
        data = np.array([[1000, 0, 65535], [1, 2, 3]], dtype=">u2").tobytes()

    depth = frames.depth_array(Msg(), "/d")
    assert depth.dtype == np.float32
    assert np.allclose(depth, [[1.0, 0.0, 65.535], [0.001, 0.002, 0.003]])
    assert frames.stamp_ns(Stamp()) == 3_000_000_005

    class V:
        x, y, z = 1.0, 2.0, 3.0

    class Q:  # a quarter turn about z
        x, y, z, w = 0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)

    class T:
        translation, rotation = V(), Q()

    m = frames.transform_matrix(T())
    assert np.allclose(m[:3, :3] @ [1, 0, 0], [0, 1, 0]) and np.allclose(m[:3, 3], [1, 2, 3])
    # A camera looking straight down faces the way its image's top points.
    down = camera_to_world(Pose2D(0.0, 0.0, 1.0), CameraSpec(pitch_deg=-90.0))
    assert frames.floor_pose(down).yaw == pytest.approx(1.0)


# -- an episode -----------------------------------------------------------------------------
class BrightnessScorer:
    """An image relevancy stand-in: the frame's mean brightness."""

    name = "brightness-stub"
    modality = "image"

    def score(self, question, *, image=None, text=None):
        return float(np.asarray(image, float).mean() / 255)

    def score_many(self, question, items):
        return np.array([self.score(question, image=i) for i in items])


def _image_model():
    from efficienteqa.models.stub import StubChatModel

    def reply(messages):
        text = messages[-1].text
        if text.startswith("You guide"):
            return "A: 70\nB: 30\nworth exploring: yes 80"
        return "blue" if "Reply with the answer only" in text else "blue; 80\nred; 20"

    return StubChatModel(reply)


def _every_other_goal_short():
    count = [0]

    def short(start, goal):
        count[0] += 1
        return 0.5 if count[0] % 2 == 0 else None

    return short


@needs_egl
def test_an_agent_episode_runs_through_the_adapter(robot, open_env):
    from efficienteqa.agent import AgentConfig
    from efficienteqa.stack import Stack, build_agent

    sim = robot(short=_every_other_goal_short())
    env = open_env()
    config = AgentConfig.of(gate="none", steering="none", stop=AgentConfig().stop.__class__(
        enabled=False))
    built = build_agent(env, Stack(perception="rgb", grouping="rules"), config, "ros2",
                        model=_image_model(), relevancy=BrightnessScorer())
    result = built.agent.run(env, "What colour is the bed?", budget=5)
    assert (result.steps, result.budget, result.stop_reason) == (5, 5, "budget")
    assert result.answer == "blue"
    moved = [r for r in result.records if r.decision][:-1]
    assert len(sim.goals) >= len(moved) >= 3
    assert any(r.short for r in result.records)
    # Every step starts where the robot really stood: the records' poses are, in order, poses
    # where the robot's moves ended (a refused goal is re-planned within its step).
    ends = iter(sim.ended)
    for record in result.records[1:]:
        assert any(math.dist(record.pose[:2], (e.x, e.y)) < 1e-6
                   and math.cos(record.pose[2] - e.yaw) == pytest.approx(1.0) for e in ends)
    assert len(result.retrieved) == min(5, config.answer.top_k)


@needs_egl
def test_ask_opens_ros2_from_a_parameters_file_and_writes_the_episode(robot, tmp_path):
    from efficienteqa.agent import AgentConfig
    from efficienteqa.ask import ask
    from efficienteqa.scenes import open_scene
    from efficienteqa.stack import Stack

    robot(color_topic="/head/rgb", info_topic="/head/rgb_info")
    params = tmp_path / "robot.toml"
    params.write_text('color_topic = "/head/rgb"\ninfo_topic = "/head/rgb_info"\n')
    scene = open_scene(f"ros2:{params}")
    try:
        assert (scene.name, scene.backend, scene.questions) == ("ros2:robot.toml", "ros2", [])
        done = ask("What colour is the bed?", scene, tmp_path / "out",
                   stack=Stack(perception="rgb", grouping="rules"), model=_image_model(),
                   relevancy=BrightnessScorer(), config=AgentConfig.of(max_steps=3, gate="none"),
                   report=False)
    finally:
        scene.env.close()
    record = json.loads(done.episode_json.read_text())
    assert record["backends"]["environment"] == "ros2" and record["answer"] == "blue"
    assert record["steps"] == len(record["per_step"]) == 3
    with pytest.raises(EfficientEQAError, match="not a Habitat scene"):
        open_scene("ros2", env="habitat")


@pytest.mark.skipif(importlib.util.find_spec("rclpy") is not None,
                    reason="ROS 2 is sourced here: the command would open the live robot")
def test_ask_on_ros2_without_ros_2_is_one_line(tmp_path):
    result = subprocess.run([sys.executable, "-m", "efficienteqa.cli", "ask", "Where is the sofa?",
                             "--scene", "ros2", "--out", str(tmp_path)], capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 1, (result.stdout, result.stderr)
    assert "ROS 2 is not sourced" in result.stdout
    assert len(result.stdout.strip().splitlines()) == 1
    assert "Traceback" not in result.stdout + result.stderr
