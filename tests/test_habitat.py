"""The Habitat-Sim adapter against the stand-in ``habitat_sim`` (tests/standin), and against the
real one where it is installed and ``$EFFICIENTEQA_HM3D_ROOT`` names HM3D scenes."""

from __future__ import annotations

import csv
import json
import math
import os
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from efficienteqa.envs.base import Environment
from efficienteqa.envs.checks import check_env
from efficienteqa.envs.habitat import frames
from efficienteqa.envs.habitat.checks import check_habitat_env
from efficienteqa.envs.habitat.scenes import HabitatStart, file_stem, find_scene
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec, Pose2D, backproject, camera_to_world

STANDIN = Path(__file__).parent / "standin"
SCENE = "00800-TEEsavR23oF"
FLOOR_Y = 0.1  # Habitat height of the stand-in scene's floor
ROOM = {"min": [-1.0, FLOOR_Y, -4.0], "max": [5.0, 2.7, 2.0]}
TABLE = {"id": 7, "category": "Table", "min": [2.0, FLOOR_Y, -3.0], "max": [3.0, 0.85, -2.0]}
NAV = {"x": [-0.5, 4.5], "z": [-3.5, 1.5], "y": FLOOR_Y}  # 25 m^2
START = HabitatStart((0.0, FLOOR_Y, 0.0), 0.0)


def _drop_habitat_modules() -> None:
    for name in [m for m in sys.modules if m == "habitat_sim" or m.startswith("habitat_sim.")]:
        del sys.modules[name]


@pytest.fixture
def standin(monkeypatch):
    """``habitat_sim`` is the stand-in for this test."""
    _drop_habitat_modules()
    monkeypatch.syspath_prepend(str(STANDIN))
    import habitat_sim

    assert habitat_sim.STANDIN
    yield habitat_sim
    _drop_habitat_modules()


def write_scene(root: Path, *, faces=("floor", "ceiling", "walls"), annotated: bool = True,
                split: str = "val", room=ROOM, navmesh=(NAV,), dataset_config: str | None = "{}"
                ) -> Path:
    """An HM3D scene folder for the stand-in; ``dataset_config`` None leaves the annotated
    scene's dataset config out."""
    folder = root / split / SCENE
    folder.mkdir(parents=True)
    stem = file_stem(SCENE)
    scene = {"room": room, "faces": list(faces), "objects": [TABLE]}
    (folder / f"{stem}.basis.glb").write_text(json.dumps(scene))
    (folder / f"{stem}.basis.navmesh").write_text(json.dumps({"rects": list(navmesh)}))
    if annotated:
        (folder / f"{stem}.semantic.glb").write_text("{}")
        (folder / f"{stem}.semantic.txt").write_text("")
        if dataset_config is not None:
            (root / "hm3d_annotated_basis.scene_dataset_config.json").write_text(dataset_config)
    return root


@pytest.fixture
def env(standin, tmp_path, small_camera):
    from efficienteqa.envs.habitat.env import open_habitat_scene

    with open_habitat_scene(write_scene(tmp_path), SCENE, START, small_camera) as env:
        yield env


@pytest.fixture
def open_env(standin, tmp_path, small_camera):
    """Opens the stand-in scene written with ``write_scene``'s options, the adapter's options."""
    from efficienteqa.envs.habitat.env import open_habitat_scene

    opened = []

    def _open(scene_options: dict | None = None, start=START, **options):
        root = write_scene(tmp_path / str(len(opened)), **(scene_options or {}))
        env = open_habitat_scene(root, SCENE, start, small_camera, **options)
        opened.append(env)
        return env

    yield _open
    for env in opened:
        env.close()


# -- frames -------------------------------------------------------------------------------
def test_habitat_and_canonical_points_round_trip():
    rng = np.random.default_rng(0)
    p = rng.normal(size=(50, 3)) * 5
    assert np.allclose(frames.to_habitat(frames.to_canonical(p, 0.7), 0.7), p)
    assert np.isclose(np.linalg.det(frames.HABITAT_TO_CANONICAL), 1.0)  # no mirror
    # Habitat up is canonical up; Habitat -z (where yaw 0 looks) is canonical +y.
    assert np.allclose(frames.to_canonical(np.array([0.0, 1.7, 0.0]), 0.7), [0, 0, 1.0])
    assert np.allclose(frames.to_canonical(np.array([0.0, 0.0, -1.0]), 0.0), [0, 1, 0])


@pytest.mark.parametrize("theta", [0.0, 0.4, math.pi / 2, -2.5, math.pi])
def test_yaw_round_trip_and_direction(theta):
    yaw = frames.yaw_to_canonical(theta)
    assert math.isclose(math.cos(frames.yaw_to_habitat(yaw) - theta), 1.0)
    forward_h = np.array([-math.sin(theta), 0.0, -math.cos(theta)])  # -z rotated about +y
    forward_c = frames.to_canonical(forward_h, 0.0)
    assert np.allclose(forward_c[:2], [math.cos(yaw), math.sin(yaw)])
    x, y, z, w = frames.yaw_quaternion(theta)
    assert (x, z) == (0.0, 0.0) and math.isclose(2 * math.atan2(y, w), theta)


@pytest.mark.parametrize("theta", [0.0, 1.1, -2.0])
def test_habitat_camera_pose_is_the_canonical_camera(theta):
    """Composed the Habitat way (agent yaw, sensor offset, pitch, GL->CV), the camera is the
    one ``geometry.camera_to_world`` puts at the canonical pose."""
    cam = CameraSpec()
    position_h = np.array([2.0, 0.4, -3.0])
    pose = frames.pose_to_canonical(position_h, theta, floor_y=0.4)
    assert (pose.x, pose.y) == (2.0, 3.0)
    got = frames.camera_to_world(position_h, theta, 0.4, cam)
    assert np.allclose(got, camera_to_world(pose, cam))


def test_floor_area_of_navmesh_triangles():
    square = np.array([[0, 0, 0], [2, 0, 0], [2, 0, 3], [0, 0, 0], [2, 0, 3], [0, 0, 3]], float)
    assert frames.triangle_area_m2(square) == pytest.approx(6.0)


# -- scene files and start poses -------------------------------------------------------------
def test_scene_path_convention(tmp_path):
    write_scene(tmp_path)
    files = find_scene(tmp_path, SCENE)
    folder = tmp_path / "val" / SCENE
    assert files.glb == folder / "TEEsavR23oF.basis.glb"
    assert files.navmesh == folder / "TEEsavR23oF.basis.navmesh"
    assert files.semantic == folder / "TEEsavR23oF.semantic.glb"
    assert files.dataset_config == tmp_path / "hm3d_annotated_basis.scene_dataset_config.json"


def test_scene_without_annotations_has_no_semantic_files(tmp_path):
    write_scene(tmp_path, annotated=False, split="")
    files = find_scene(tmp_path, SCENE)
    assert files.glb.parent == tmp_path / SCENE
    assert files.semantic is None and files.dataset_config is None


@pytest.mark.parametrize("scene, message", [("TEEsavR23oF", "not an HM3D scene name"),
                                            ("00801-NoSuchScene", "is not under")])
def test_bad_scenes_are_one_line_errors(tmp_path, scene, message):
    write_scene(tmp_path)
    with pytest.raises(EfficientEQAError, match=message) as err:
        find_scene(tmp_path, scene)
    assert "\n" not in str(err.value)


def test_missing_navmesh_is_named(tmp_path):
    write_scene(tmp_path)
    (tmp_path / "val" / SCENE / "TEEsavR23oF.basis.navmesh").unlink()
    with pytest.raises(EfficientEQAError, match="lacks TEEsavR23oF.basis.navmesh"):
        find_scene(tmp_path, SCENE)


def test_start_poses_of_known_hm_eqa_rows(hm_eqa_dir):
    """The first questions' starts are the numbers of their scene_init_poses.csv rows."""
    from efficienteqa.datasets import load_dataset

    with open(hm_eqa_dir / "scene_init_poses.csv", newline="", encoding="utf-8-sig") as f:
        rows = {r["scene_floor"]: r for r in csv.DictReader(f)}
    questions = load_dataset("hm-eqa", path=hm_eqa_dir, limit=5)
    for q in questions:
        row = rows[q.source["scene_floor"]]
        start = HabitatStart.from_source(q.source)
        assert start is not None
        assert start.position == tuple(float(row[k]) for k in ("init_x", "init_y", "init_z"))
        assert start.yaw_rad == float(row["init_angle"])
        assert q.scene == f"hm3d:{row['scene_floor'].rsplit('_', 1)[0]}"
    assert HabitatStart.from_source({"habitat_position": None, "habitat_yaw": None}) is None


# -- the environment on the stand-in -------------------------------------------------------
def test_missing_habitat_sim_is_a_one_line_error(monkeypatch, tmp_path):
    from efficienteqa.envs.habitat.env import HabitatEnv

    monkeypatch.setitem(sys.modules, "habitat_sim", None)  # import fails as when not installed
    with pytest.raises(EfficientEQAError, match="Habitat-Sim is not installed") as err:
        HabitatEnv(find_scene(write_scene(tmp_path), SCENE), START)
    assert "conda install" in err.value.fix and "\n" not in str(err.value)


MOVES = [Pose2D(1.0, 1.0, 0.3), Pose2D(3.5, 2.5, -1.0), Pose2D(0.5, -1.0, 2.0)]


@pytest.mark.parametrize("mount", ["body-tilt", "sensor-pitch"])
@pytest.mark.parametrize("moves", ["unchecked", "checked"])
def test_contract(open_env, mount, moves):
    env = open_env(camera_mount=mount, moves=moves)
    assert isinstance(env, Environment)
    check_habitat_env(env, MOVES)
    if mount == "sensor-pitch":  # the camera above the robot: the synthetic houses' contract too
        check_env(env, MOVES)


def test_start_floor_and_area(env):
    assert env.floor_y == FLOOR_Y
    assert env.start == Pose2D(0.0, 0.0, math.pi / 2)  # Habitat yaw 0 looks along canonical +y
    assert env.floor_area_m2 == pytest.approx(25.0)
    lo, hi = env.bounds
    assert np.allclose(lo, [-1.5, -2.5, 0.0]) and np.allclose(hi, [5.5, 4.5, 3.0])


@pytest.mark.parametrize("mount", ["body-tilt", "sensor-pitch"])
def test_every_pixel_lands_on_a_surface_of_the_room(open_env, mount):
    """Depth, intrinsics and cam_to_world together: back-projected points lie on the room's
    walls, floor and ceiling or on the table, all given in Habitat coordinates."""
    env = open_env(camera_mount=mount)
    lo, hi = frames.to_canonical(np.array([ROOM["min"], ROOM["max"]]), FLOOR_Y)
    lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    tlo, thi = frames.to_canonical(np.array([TABLE["min"], TABLE["max"]]), FLOOR_Y)
    tlo, thi = np.minimum(tlo, thi), np.maximum(tlo, thi)
    for pose in (env.start, Pose2D(2.0, 1.0, -math.pi / 2), Pose2D(3.0, 0.5, -2.0)):
        obs, *_ = env.step(pose)
        assert obs.invalid_fraction == 0.0
        pts = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world).reshape(-1, 3)
        on_room = np.min(np.minimum(np.abs(pts - lo), np.abs(pts - hi)), axis=1) < 0.02
        in_table = np.all((pts > tlo - 0.02) & (pts < thi + 0.02), axis=1)
        assert np.all(on_room | in_table)
        height = 1.5 if mount == "sensor-pitch" else 1.5 * math.cos(math.radians(30))
        assert np.allclose(obs.cam_to_world[2, 3], height)


def test_blocked_steps_leave_the_robot_in_place(open_env):
    env = open_env(moves="checked")
    obs, _, _, _, info = env.step(Pose2D(4.8, 0.0, 0.0))  # inside the room, off the navmesh
    assert info["blocked"] and obs.pose == env.start
    assert not env.is_navigable(4.8, 0.0) and env.is_navigable(4.0, 0.0)


def test_semantic_sensor_labels_the_table(env):
    obs, *_ = env.step(Pose2D(2.5, 0.5, math.pi / 2))  # the table is ahead, at y 2-3
    labels = env.scene_labels()
    assert labels.label(7).category == "table"
    ids = set(np.unique(obs.instance).tolist())
    assert 7 in ids and ids <= {0, 7}  # walls and floor are structure
    assert labels.room_at(0.0, 0.0) is None


def test_semantic_perception_reads_the_scene(env):
    from efficienteqa.stack import build_perception

    perception = build_perception("semantic", env)
    obs, *_ = env.step(Pose2D(2.5, 0.5, math.pi / 2))
    assert "table" in perception.relevancy_text(obs)


def test_without_annotations_semantic_perception_is_refused(standin, tmp_path, small_camera):
    from efficienteqa.envs.habitat.env import open_habitat_scene
    from efficienteqa.stack import build_perception

    root = write_scene(tmp_path, annotated=False)
    with open_habitat_scene(root, SCENE, START, small_camera) as env:
        assert env.observe().instance is None
        with pytest.raises(EfficientEQAError, match="semantic sensor"):
            build_perception("semantic", env)


def test_frames_without_geometry_are_invalid(standin, tmp_path, small_camera):
    """A scan with holes: with only the floor there, most pixels see nothing (depth 0, instance
    -1), so the frame counts as invalid (the agent keeps such frames from its models:
    tests/test_agent.py)."""
    from efficienteqa.envs.habitat.env import open_habitat_scene

    root = write_scene(tmp_path, faces=("floor",))
    with open_habitat_scene(root, SCENE, START, small_camera) as env:
        obs = env.observe()
        assert obs.invalid_fraction >= 0.5
        assert np.all(obs.instance[obs.depth_m == 0] == -1)


def test_a_start_off_the_navmesh_is_refused(standin, tmp_path):
    from efficienteqa.envs.habitat.env import open_habitat_scene

    with pytest.raises(EfficientEQAError, match="not on the navmesh"):
        open_habitat_scene(write_scene(tmp_path), SCENE, HabitatStart((4.9, FLOOR_Y, 0.0), 0.0))


def test_without_a_start_a_seeded_navigable_point_is_used(standin, tmp_path, small_camera):
    from efficienteqa.envs.habitat.env import open_habitat_scene

    root = write_scene(tmp_path)
    with open_habitat_scene(root, SCENE, None, small_camera, seed=3) as a, \
            open_habitat_scene(root, SCENE, None, small_camera, seed=3) as b:
        assert a.start == b.start and a.is_navigable(a.start.x, a.start.y)


def test_an_episode_in_a_habitat_scene(standin, tmp_path):
    """The whole agent in the stand-in scene: semantic-sensor perception over the Habitat
    semantic sensor, the stub VLM, and a record naming the Habitat back-end."""
    from efficienteqa.agent import AgentConfig
    from efficienteqa.ask import ask
    from efficienteqa.models.stub import StubChatModel
    from efficienteqa.relevancy.text import WordOverlapScorer
    from efficienteqa.scenes import open_scene
    from efficienteqa.stack import Stack
    from efficienteqa.stop import StopConfig

    model = StubChatModel(lambda msgs: "A: 80\nworth exploring: yes 70"
                          if msgs[-1].text.startswith("You guide") else "yes; 90\nno; 10")
    scene = open_scene(f"hm3d:{SCENE}", env="habitat", hm3d_root=write_scene(tmp_path), start=START)
    with scene.env:
        done = ask("Is there a table?", scene, tmp_path / "out", stack=Stack(grouping="rules"),
                   model=model, relevancy=WordOverlapScorer(),
                       config=AgentConfig.of(max_steps=4, answer="paper", gate="none",
                                          stop=StopConfig()))
    record = done.record
    assert record["backends"]["environment"] == "hm3d (habitat-sim)"
    assert record["scene"] == f"hm3d:{SCENE} (habitat-sim)"
    assert done.result.steps == 4 and done.result.answer == "yes"
    assert any("table" in r.messages[-1].text for r in model.requests)
    assert done.report_html is not None and done.report_html.is_file()


# -- fidelity to ExploreEQA (docs/habitat.md) ------------------------------------------------
UPSTAIRS = {"x": [-0.5, 8.5], "z": [-3.5, 1.5], "y": FLOOR_Y + 3.0}  # a second floor, 45 m^2


@pytest.mark.parametrize("budget_area, area, budget", [("navmesh-bbox", 45.0, 20),
                                                       ("floor", 25.0, 15)])
def test_the_step_budget_reads_the_navmesh_box_of_every_floor(open_env, budget_area, area, budget):
    """ExploreEQA's budget: int(sqrt(scene_size) * 3), scene_size the x-z box of the whole
    navmesh (PathFinder.get_bounds, both floors: 9 m x 5 m), not the start floor's 25 m^2."""
    from efficienteqa.stop.rules import env_step_budget

    env = open_env({"navmesh": (NAV, UPSTAIRS)}, budget_area=budget_area)
    assert env.floor_area_m2 == pytest.approx(25.0)
    assert env.navmesh_bbox_area_m2 == pytest.approx(45.0)
    assert env.budget_area_m2 == pytest.approx(area) and env_step_budget(env) == budget


def test_the_synthetic_houses_keep_their_floor_area_budget(env_seed3):
    from efficienteqa.stop.rules import env_step_budget, step_budget

    assert env_step_budget(env_seed3) == step_budget(env_seed3.floor_area_m2)


def test_an_episode_in_habitat_spends_the_navmesh_box_budget(standin, tmp_path):
    """The agent's budget goes through env_step_budget: 20 steps (45 m^2), not 15 (25 m^2)."""
    from efficienteqa.agent import AgentConfig
    from efficienteqa.ask import ask
    from efficienteqa.models.stub import StubChatModel
    from efficienteqa.relevancy.text import WordOverlapScorer
    from efficienteqa.scenes import open_scene
    from efficienteqa.stack import Stack
    from efficienteqa.stop import StopConfig

    root = write_scene(tmp_path, navmesh=(NAV, UPSTAIRS))
    model = StubChatModel(lambda msgs: "A: 80\nworth exploring: yes 70"
                          if msgs[-1].text.startswith("You guide") else "yes; 90\nno; 10")
    scene = open_scene(f"hm3d:{SCENE}", env="habitat", hm3d_root=root, start=START)
    with scene.env:
        done = ask("Is there a table?", scene, tmp_path / "out", stack=Stack(grouping="rules"),
                   model=model, relevancy=WordOverlapScorer(), report=False,
                   config=AgentConfig.of(answer="paper", gate="none", explorer="random",
                                      stop=StopConfig(enabled=False)))
    assert done.result.budget == 20


def test_body_tilt_puts_the_camera_where_explore_eqa_has_it(open_env):
    """ExploreEQA tilts the agent's body by -30 degrees and mounts the sensor 1.5 m up the
    tilted body: the camera is 1.5 cos 30 = 1.30 m high and 1.5 sin 30 = 0.75 m ahead,
    looking 30 degrees down. Habitat yaw 0 looks along canonical +y."""
    env = open_env()
    obs = env.observe()
    assert env.camera_mount == "body-tilt"
    assert np.allclose(obs.cam_to_world[:3, 3], [0.0, 0.75, 1.5 * math.cos(math.radians(30))])
    forward = obs.cam_to_world[:3, 2]  # OpenCV z: the optical axis
    assert np.allclose(forward, [0.0, math.cos(math.radians(30)), -0.5])
    up = open_env(camera_mount="sensor-pitch").observe()
    assert np.allclose(up.cam_to_world[:3, 3], [0.0, 0.0, 1.5])
    assert np.allclose(up.cam_to_world[:3, :3], obs.cam_to_world[:3, :3])  # the same view axis


def test_the_camera_pose_is_read_back_from_the_simulator(open_env):
    """Maps and back-projection get the pose Habitat-Sim rendered from (sensor_states), not
    one the adapter composes: move the depth sensor on its mount, and cam_to_world follows
    it, and the back-projected floor stays at z = 0."""
    env = open_env({"faces": ("floor",)})
    for spec in env.agent.config.sensor_specifications:
        spec.position = [0.0, 1.2, 0.0]
    obs, *_ = env.step(Pose2D(2.0, 0.0, math.pi / 2))
    state = env.agent.get_state().sensor_states["depth"]
    assert np.allclose(obs.cam_to_world, frames.sensor_to_world(state.position, state.rotation,
                                                                FLOOR_Y))
    assert np.isclose(obs.cam_to_world[2, 3], 1.2 * math.cos(math.radians(30)))
    pts = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[obs.depth_m > 0]
    on_table = (pts[:, 0] > 1.98) & (pts[:, 0] < 3.02) & (pts[:, 1] > 1.98) & (pts[:, 1] < 3.02)
    assert on_table.mean() < 0.5 and np.allclose(pts[~on_table, 2], 0.0, atol=1e-4)


def test_unchecked_moves_arrive_as_in_explore_eqa(open_env):
    """ExploreEQA sets the planned pose with no navmesh check: a pose off the navmesh is
    taken, on the start's floor, and never refused (so no step is spent on a refusal)."""
    env = open_env()
    assert env.moves == "unchecked" and not env.is_navigable(4.8, 0.0)
    obs, _, _, _, info = env.step(Pose2D(4.8, 0.0, 0.0))
    assert not info["blocked"] and obs.pose == Pose2D(4.8, 0.0, 0.0) and info["step"] == 1
    position = env.agent.get_state().position
    assert np.allclose(position, [4.8, FLOOR_Y, 0.0])


def test_observe_before_reset_sees_the_start(open_env):
    """Habitat-Sim's initialize_agent puts the agent at a random navigable pose; the first
    observation, before any reset, is still the one from the start pose."""
    env = open_env()
    first = env.observe()
    again, _ = env.reset()
    assert first.pose == again.pose == env.start
    assert np.allclose(first.cam_to_world, again.cam_to_world)
    assert np.array_equal(first.depth_m, again.depth_m)


def test_annotations_without_their_dataset_config_are_one_line_errors(open_env):
    """Without hm3d_annotated_basis.scene_dataset_config.json Habitat-Sim only warns and reads
    every object id as 0: semantic perception is refused, saying so, and asking for the
    semantic sensor fails at once."""
    from efficienteqa.stack import build_perception

    env = open_env({"dataset_config": None})
    assert env.observe().instance is None  # --perception rgb still runs
    with pytest.raises(EfficientEQAError, match="scene_dataset_config.json was found") as err:
        build_perception("semantic", env)
    assert "\n" not in str(err.value) and "hm3d_annotated_basis" in err.value.fix
    with pytest.raises(EfficientEQAError, match="every object id as 0"):
        open_env({"dataset_config": None}, semantic=True)


def test_a_dataset_config_without_the_scene_is_refused(open_env):
    with pytest.raises(EfficientEQAError, match="without its semantic annotations") as err:
        open_env({"dataset_config": json.dumps({"scenes": ["SomeOtherScene"]})})
    assert "\n" not in str(err.value)


def test_unknown_options_are_one_line_errors(open_env):
    with pytest.raises(EfficientEQAError, match="camera_mount 'tilted'"):
        open_env(camera_mount="tilted")


TALL = {"min": [-1.0, FLOOR_Y, -4.0], "max": [14.0, 5.5, 2.0]}  # 5.4 m high, 9.5 m past the navmesh


def test_the_habitat_check_takes_views_of_real_houses(open_env):
    """A double-height room that runs on beyond the navmesh (a view through an open door):
    points above one storey and past the floor's box are what HM3D views show. The synthetic
    houses' check refuses them; the Habitat check takes them and still catches a wrong pose."""
    east = [Pose2D(3.0, 0.5, 0.0)]  # looking along +x, at the far wall 11 m away
    upright = open_env({"room": TALL}, camera_mount="sensor-pitch")
    with pytest.raises(AssertionError, match="points outside bounds"):
        check_env(upright, east)  # the camera above the robot: it fails on the points alone
    check_habitat_env(upright, east)
    env = open_env({"room": TALL})
    check_habitat_env(env, east)
    obs, *_ = env.step(east[0])
    pts = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[obs.depth_m > 0]
    lo, hi = env.bounds
    assert np.any(pts[:, 2] > hi[2] + 0.3) and np.any(pts[:, 0] > hi[0] + 0.3)
    from efficienteqa.envs.habitat.checks import check_habitat_observation

    flipped = obs.cam_to_world.copy()
    flipped[:3, 1:3] *= -1  # a camera looking up: the y-down/z-forward mix-up
    with pytest.raises(AssertionError):
        check_habitat_observation(replace(obs, cam_to_world=flipped), env)


def test_habitat_scenes_need_the_habitat_env(tmp_path):
    from efficienteqa.scenes import open_scene

    with pytest.raises(EfficientEQAError, match="needs Habitat-Sim") as err:
        open_scene(f"hm3d:{SCENE}")
    assert "--scene.env habitat --scene.hm3d-root" in err.value.fix
    with pytest.raises(EfficientEQAError, match="not a Habitat scene"):
        open_scene("synthetic:0", env="habitat", hm3d_root=tmp_path)


# -- the real Habitat-Sim --------------------------------------------------------------------
def _real_habitat() -> str | None:
    try:
        import habitat_sim
    except ImportError:
        return "habitat_sim is not installed (conda)"
    if getattr(habitat_sim, "STANDIN", False):
        return "only the stand-in is importable"
    if not os.environ.get("EFFICIENTEQA_HM3D_ROOT"):
        return "EFFICIENTEQA_HM3D_ROOT is not set"
    return None


@pytest.mark.skipif(_real_habitat() is not None, reason=str(_real_habitat()))
def test_real_habitat_contract_on_an_hm_eqa_scene(hm_eqa_dir, small_camera):
    from efficienteqa.datasets import load_dataset
    from efficienteqa.envs.habitat.env import open_habitat_scene

    q = load_dataset("hm-eqa", path=hm_eqa_dir, limit=1)[0]
    root = Path(os.environ["EFFICIENTEQA_HM3D_ROOT"])
    with open_habitat_scene(root, q.scene.partition(":")[2],
                            HabitatStart.from_source(q.source), small_camera) as env:
        obs, _ = env.reset()
        assert obs.invalid_fraction < 0.5 and env.floor_area_m2 > 5
        assert env.navmesh_bbox_area_m2 >= env.floor_area_m2  # the box of every floor
        check_habitat_env(env, [])
        # ExploreEQA's body tilt, as Habitat-Sim reports the sensor: 1.30 m high, 0.75 m ahead.
        ahead = obs.cam_to_world[:2, 3] - [obs.pose.x, obs.pose.y]
        assert np.isclose(obs.cam_to_world[2, 3], 1.5 * math.cos(math.radians(30)), atol=1e-3)
        assert np.allclose(ahead, 0.75 * np.array([math.cos(obs.pose.yaw), math.sin(obs.pose.yaw)]),
                           atol=1e-3)
        # Looking 30 degrees down from 1.30 m, most of the bottom row sees the floor (z = 0):
        # the pitch sign, the y-up conversion and the floor height together.
        pts = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[-1]
        seen = obs.depth_m[-1] > 0
        assert np.mean(np.abs(pts[seen, 2]) < 0.15) > 0.5
