"""The synthetic houses as a Gymnasium environment (efficienteqa.gym): the docs' three lines make
and step it, Gymnasium's own checker passes, and nothing of the simulator's truth reaches the
agent before the episode's end."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import needs_egl

gym = pytest.importorskip("gymnasium")

ROBOT_KEYS = {"blocked", "short", "reached", "steps", "budget"}


@pytest.fixture(scope="module")
def env():
    import efficienteqa.gym  # noqa: F401  (registers the id)

    made = gym.make("EfficientEQA/SyntheticHouse-v1", limit=1)  # one question: one house
    yield made
    made.close()


@needs_egl
def test_the_checker_passes(env):
    from gymnasium.utils.env_checker import check_env

    check_env(env.unwrapped, skip_render_check=True)


@needs_egl
def test_an_episode_gives_what_a_robot_has_and_grades_at_the_end(env):
    from efficienteqa.envs.episode import answer, move

    obs, info = env.reset(seed=0)
    assert set(obs) == {"rgb", "depth", "intrinsics", "pose", "question"}
    assert obs["rgb"].shape == (480, 640, 3) and obs["rgb"].dtype == np.uint8
    assert obs["question"] == "What is on the bookshelf in the living room?"
    assert set(info) == {"budget", "question_id"} and info["budget"] > 1
    x, y = float(obs["pose"][0, 3]), float(obs["pose"][1, 3])
    obs2, reward, terminated, truncated, info = env.step(move(x + 0.3, y, 0.0))
    assert set(info) == ROBOT_KEYS and not (terminated or truncated) and reward == 0.0
    assert info["steps"] == 2 and not info["blocked"]  # the start view is step 1
    assert np.allclose(obs2["pose"][:2, 3], [x + 0.3, y], atol=0.02)
    _, _, _, _, info = env.step(move(1e3, 1e3, 0.0))  # far outside the house
    assert info["blocked"] and set(info) == ROBOT_KEYS
    _, reward, terminated, truncated, info = env.step(answer("a coffee maker"))
    assert terminated and not truncated and reward == 1.0
    grade = info["grade"]
    assert grade["correct"] and grade["reference"] == "a coffee maker" and grade["steps"] == 3
    assert grade["oracle_steps"] >= 1
    house = env.unwrapped._scene
    env.reset(seed=0)
    assert env.unwrapped._scene is house  # a question in the same house keeps it open
    _, reward, terminated, _, info = env.step(answer("a teddy bear"))
    assert terminated and reward == 0.0 and not info["grade"]["correct"]


@needs_egl
def test_the_budget_truncates_an_episode_that_never_answers(env):
    from efficienteqa.envs.episode import move

    obs, info = env.reset(seed=0)
    pose = obs["pose"]
    for _ in range(info["budget"] - 1):  # the start view is the first of the budget's steps
        _, reward, terminated, truncated, step_info = env.step(
            move(float(pose[0, 3]), float(pose[1, 3]), 0.0))
    assert truncated and not terminated and reward == 0.0
    assert step_info["grade"]["answer"] == "" and not step_info["grade"]["correct"]


@needs_egl
def test_a_move_goes_3_m_along_a_free_path_at_most(env):
    """No teleporting: a far goal ends short after 3 m of the shortest free path, the step the
    oracle's counts assume."""
    from efficienteqa.envs.episode import move

    obs, _ = env.reset(seed=0)
    house = env.unwrapped._scene.env
    x, y = float(obs["pose"][0, 3]), float(obs["pose"][1, 3])
    free = np.argwhere(house.grid.free)
    far = max((house.grid.spec.cell_to_world(c) for c in free[::50]),
              key=lambda p: np.hypot(p[0] - x, p[1] - y))
    assert np.hypot(far[0] - x, far[1] - y) > 4.0
    obs2, _, _, _, info = env.step(move(float(far[0]), float(far[1]), 0.0))
    moved = np.hypot(obs2["pose"][0, 3] - x, obs2["pose"][1, 3] - y)
    assert info["short"] and not info["blocked"] and 1.0 < moved <= 3.0 + 1e-6


def test_a_bad_action_fails_in_one_line():
    from efficienteqa.envs.episode import parse_action
    from efficienteqa.errors import EfficientEQAError

    with pytest.raises(EfficientEQAError, match="dict with 'kind'"):
        parse_action((1.0, 2.0, 0.0))
    with pytest.raises(EfficientEQAError, match="three finite numbers"):
        parse_action({"kind": 0, "goal": [1.0, float("nan"), 0.0]})


@needs_egl
@pytest.mark.parametrize("noise", ["none", "robot"])
def test_no_move_goes_farther_than_3_m_of_free_path_with_noise_or_without(noise):
    """The path limit holds under a robot's noise too (the goal is given in the drifted frame
    the robot reports; the path runs where the robot truly is)."""
    from efficienteqa.envs.synthetic.env import SyntheticEnv
    from efficienteqa.envs.synthetic.moves import path_moves
    from efficienteqa.envs.synthetic.noise import NoisyEnv, profile
    from efficienteqa.geometry import Pose2D

    house = SyntheticEnv.from_seed(1, "builtin")
    env = path_moves(NoisyEnv(house, profile(noise), seed=3) if noise != "none" else house)
    try:
        obs, _ = env.reset()
        free = np.argwhere(house.grid.free)[::40]
        rng = np.random.default_rng(0)
        shortened = 0
        for cell in rng.permutation(free)[:12]:
            x, y = house.grid.spec.cell_to_world(cell)
            before = house.pose
            obs, _, _, _, info = env.step(Pose2D(float(x), float(y), 0.0))
            moved = float(np.hypot(house.pose.x - before.x, house.pose.y - before.y))
            assert moved <= 3.0 + 1e-6 and set(info) >= {"blocked", "short", "reached"}
            shortened += moved > 2.9  # a goal farther off, cut at 3 m
        assert shortened >= 2  # the houses are wider than a step: the limit was tested
    finally:
        env.close()


@needs_egl
def test_a_robot_noise_profile_acts_and_an_unknown_one_is_refused():
    """``noise="robot"``: the observed pose is the drifted one the robot believes (the house's
    true pose is elsewhere after moves), and the depth has holes; a wrong name fails at once."""
    import efficienteqa.gym  # noqa: F401
    from efficienteqa.envs.episode import move
    from efficienteqa.errors import EfficientEQAError

    with pytest.raises(EfficientEQAError, match="unknown noise profile 'rbot'"):
        gym.make("EfficientEQA/SyntheticHouse-v1", limit=1, noise="rbot")
    noisy = gym.make("EfficientEQA/SyntheticHouse-v1", limit=1, noise="robot")
    try:
        obs, _ = noisy.reset(seed=0)
        assert np.mean(obs["depth"] == 0) > 0.005  # the profile's depth holes
        for dx in (1.0, -1.0, 1.0, -1.0):
            x, y = float(obs["pose"][0, 3]), float(obs["pose"][1, 3])
            obs, _, _, _, info = noisy.step(move(x + dx, y, 0.0))
        true = noisy.unwrapped._scene.env.env.pose
        believed = obs["pose"][:2, 3]
        assert float(np.hypot(true.x - believed[0], true.y - believed[1])) > 1e-3
    finally:
        noisy.close()
