"""``check_env``: the environment contract every adapter must pass (run by the tests)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from efficienteqa.envs.base import Environment, Observation, SimulatedScene
from efficienteqa.geometry import Pose2D, backproject


def check_arrays(obs: Observation, env: Environment) -> None:
    """What every adapter's frame must be: shapes, dtypes, finite depth, the camera's
    intrinsics and a rotation in ``cam_to_world``."""
    cam = env.camera
    h, w = cam.height, cam.width
    assert obs.rgb.shape == (h, w, 3) and obs.rgb.dtype == np.uint8, "rgb must be (H, W, 3) uint8"
    assert obs.depth_m.shape == (h, w) and obs.depth_m.dtype == np.float32, "depth_m (H, W) f32"
    assert np.all(np.isfinite(obs.depth_m)) and np.all(obs.depth_m >= 0), "depth finite, >= 0"
    if obs.instance is not None:
        assert obs.instance.shape == (h, w) and obs.instance.dtype == np.int32, "instance (H, W) i32"
    assert np.allclose(obs.intrinsics, cam.intrinsics), "intrinsics must match the camera"
    rot = obs.cam_to_world[:3, :3]
    assert np.allclose(rot @ rot.T, np.eye(3), atol=1e-6) and np.isclose(np.linalg.det(rot), 1.0)


def check_observation(obs: Observation, env: SimulatedScene) -> None:
    """A synthetic frame: the camera straight above the robot, every point in the house's box."""
    check_arrays(obs, env)
    assert np.allclose(obs.cam_to_world[:3, 3][:2], [obs.pose.x, obs.pose.y], atol=1e-6)
    lo, hi = env.bounds
    valid = obs.depth_m > 0
    if valid.any():
        pts = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[valid]
        slack = 0.3  # walls are thick; surfaces lie on the scene's bounding box
        assert np.all(pts >= lo - slack) and np.all(pts <= hi + slack), "points outside bounds"


def check_env(env: SimulatedScene, moves: list[Pose2D],
              check: Callable[[Observation, SimulatedScene], None] = check_observation) -> None:
    """Reset, observe, and step through ``moves`` (navigable poses), checking every frame with
    ``check`` (an adapter whose frames differ in kind passes its own)."""
    obs, info = env.reset(seed=0)
    check(obs, env)
    assert isinstance(info, dict)
    start = obs.pose
    assert env.is_navigable(start.x, start.y), "the start pose must be navigable"
    assert env.floor_area_m2 > 0
    for pose in moves:
        obs, reward, terminated, truncated, info = env.step(pose)
        check(obs, env)
        assert isinstance(reward, float) and isinstance(terminated, bool)
        assert isinstance(truncated, bool) and isinstance(info, dict)
        assert (obs.pose.x, obs.pose.y) == (pose.x, pose.y), "a navigable move must arrive"
    again, _ = env.reset(seed=0)
    assert again.pose == start, "reset must return to the start"
