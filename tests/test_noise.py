"""A robot's imperfections in the synthetic houses (envs/synthetic/noise.py): each one acts as
named, the perfect profile changes nothing, and a run names its profile."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from conftest import needs_egl
from efficienteqa.config.run import NOISE_PROFILES, SceneConfig
from efficienteqa.envs.synthetic.noise import (
    PROFILES,
    ROBOT,
    NoiseProfile,
    NoisyEnv,
    compose,
    inverse,
    noisy_depth,
    profile,
)
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D


def test_the_profiles_the_configuration_names_are_the_ones_that_exist():
    assert tuple(PROFILES) == NOISE_PROFILES
    assert PROFILES["none"].perfect and not ROBOT.perfect
    # each single-imperfection profile is a part of the robot profile
    for name in NOISE_PROFILES[2:]:
        part = PROFILES[name]
        assert not part.perfect
        assert all(getattr(part, k) in (0.0, getattr(ROBOT, k)) for k in vars(part))
    with pytest.raises(EfficientEQAError, match="unknown noise profile"):
        profile("bumpy")
    with pytest.raises(ValueError, match="noise must be one of"):
        SceneConfig(noise="bumpy")


def test_poses_compose_and_invert():
    a, b = Pose2D(1.0, 2.0, 0.7), Pose2D(-0.3, 0.5, -1.2)
    back = compose(inverse(a), compose(a, b))
    assert (back.x, back.y, back.yaw) == pytest.approx((b.x, b.y, b.yaw))


def test_depth_noise_grows_with_range_and_holes_cover_their_share():
    rng = np.random.default_rng(0)
    near, far = np.full((480, 640), 1.0, np.float32), np.full((480, 640), 4.0, np.float32)
    p = NoiseProfile(depth_sigma_per_m2=0.003)
    assert np.std(noisy_depth(near, p, rng) - 1.0) == pytest.approx(0.003, rel=0.05)
    assert np.std(noisy_depth(far, p, rng) - 4.0) == pytest.approx(0.048, rel=0.05)
    holes = noisy_depth(near, NoiseProfile(depth_holes=0.03), rng)
    assert 0.015 < np.mean(holes == 0) < 0.05
    assert np.all(noisy_depth(near, NoiseProfile(), rng) == near)  # perfect: untouched


@pytest.fixture
def house(env_seed3):
    yield env_seed3


@needs_egl
def test_the_perfect_profile_is_the_simulator(house):
    noisy = NoisyEnv(house, PROFILES["none"])
    obs, _ = noisy.reset()
    plain, _ = house.reset()
    assert obs.pose == plain.pose and np.array_equal(obs.depth_m, plain.depth_m)
    assert np.allclose(obs.cam_to_world, plain.cam_to_world)


def _moves(env: NoisyEnv, n: int = 30, metres: float = 0.5) -> list[tuple[Pose2D, Pose2D, dict]]:
    """``n`` moves back and forth along the start's heading: (goal, reported, info)."""
    obs, _ = env.reset()
    out = []
    for k in range(n):
        ahead = metres if k % 2 == 0 else -metres
        goal = Pose2D(obs.pose.x + ahead * math.cos(obs.pose.yaw),
                      obs.pose.y + ahead * math.sin(obs.pose.yaw), obs.pose.yaw)
        obs, _, _, _, info = env.step(goal)
        out.append((goal, obs.pose, info))
    return out


@needs_egl
def test_moves_fail_and_fall_short_in_their_shares_and_say_so(house):
    env = NoisyEnv(house, NoiseProfile(fail_share=0.2, short_share=0.3), seed=1)
    moves = _moves(env, 40, metres=1.5)
    failed = [m for m in moves if m[2]["blocked"]]
    short = [m for m in moves if m[2]["short"]]
    assert 3 <= len(failed) <= 14 and 5 <= len(short) <= 20
    for goal, reached, _ in short:  # it moved, but not all the way
        assert 0.25 < math.dist((goal.x, goal.y), (reached.x, reached.y)) < 1.5


@needs_egl
def test_odometry_drifts_from_the_true_pose_with_distance(house):
    env = NoisyEnv(house, NoiseProfile(drift_m_per_m=0.05, drift_rad_per_m=0.02), seed=2)
    _moves(env, 30)
    reported, true = env.observe().pose, env.pose
    assert math.dist((reported.x, reported.y), (true.x, true.y)) > 0.01
    # the frame the robot reports is its own: the camera where the reported pose puts it
    assert np.allclose(env.observe().cam_to_world[:2, 3], [reported.x, reported.y])


@needs_egl
def test_a_miscalibrated_camera_sees_another_frame_than_its_pose_says(house):
    plain = NoisyEnv(house, PROFILES["none"]).reset()[0]
    tilted = NoisyEnv(house, PROFILES["robot-camera"]).reset()[0]
    assert np.allclose(plain.cam_to_world, tilted.cam_to_world)  # what the robot believes
    assert not np.array_equal(plain.depth_m, tilted.depth_m)  # what the camera saw


@needs_egl
def test_an_episode_is_repeatable_and_the_seed_changes_it(house):
    def walk(seed: int) -> list:
        env = NoisyEnv(house, replace(ROBOT), seed=seed)
        return [(r.x, r.y, i["blocked"], i["short"]) for _, r, i in _moves(env, 12)]

    assert walk(0) == walk(0) != walk(5)


def test_a_run_under_noise_is_labelled_and_identified_so():
    from efficienteqa.eval.records import SCENE_IDENTITY
    from efficienteqa.eval.run_labels import settings_label

    assert "noise" in SCENE_IDENTITY
    assert settings_label("efficienteqa", {"noise": "robot"}, baseline={}) == (
        "efficienteqa noise=robot")
    assert settings_label("efficienteqa", {"noise": "none"}, baseline={}) == "efficienteqa"


def test_noise_is_refused_where_it_cannot_act():
    from efficienteqa.scenes import open_scene

    with pytest.raises(EfficientEQAError, match="for the synthetic houses"):
        open_scene("hm3d:abc", env="habitat", hm3d_root="/nowhere", noise="robot")


@needs_egl
def test_a_question_of_the_split_is_asked_in_its_house_under_noise():
    from efficienteqa.datasets import load_dataset
    from efficienteqa.datasets.synthetic import check_question
    from efficienteqa.scenes import open_scene

    q = load_dataset("synthetic", limit=1)[0]
    scene = open_scene(q.scene, oracle=False, noise="robot")
    try:
        check_question(scene, q)  # the same house, the same question: no error
    finally:
        scene.env.close()
