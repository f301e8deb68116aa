"""``check_habitat_env``: the environment contract as a real HM3D scene can meet it.

``envs.checks.check_env`` holds the synthetic houses to two things a Habitat scene does not
give: the camera straight above the robot (ExploreEQA's body-tilt mount puts it about 0.75 m
ahead) and every back-projected point inside the floor's box (a stairwell shows the floor
below, a double-height room its ceiling, an open door or a window what lies beyond the
navmesh). Here the camera must be the pose Habitat-Sim rendered from and within its mount's
reach of the robot, and most of a frame (``MIN_POINTS_IN_BOUNDS``) must lie in the box: a wrong
pitch sign, axis or floor height still puts most points outside it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from efficienteqa.envs.checks import check_arrays, check_env
from efficienteqa.geometry import Pose2D, backproject
from efficienteqa.observation import Observation

if TYPE_CHECKING:
    from efficienteqa.envs.habitat.env import HabitatEnv

MIN_POINTS_IN_BOUNDS = 0.5
SLACK_M = 0.3  # walls are thick; surfaces lie on the bounding box


def check_habitat_observation(obs: Observation, env: HabitatEnv) -> None:
    check_arrays(obs, env)
    assert np.allclose(obs.cam_to_world, env.camera_pose(), atol=1e-6), \
        "cam_to_world must be the sensor pose Habitat-Sim reports"
    offset = np.hypot(obs.cam_to_world[0, 3] - obs.pose.x, obs.cam_to_world[1, 3] - obs.pose.y)
    assert offset <= env.camera.height_m + 1e-6, "the camera must be within its mount's reach"
    lo, hi = env.bounds
    assert lo[2] < obs.cam_to_world[2, 3] < hi[2], "the camera must be above the floor, below a storey"
    valid = obs.depth_m > 0
    if valid.any():
        pts = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[valid]
        inside = np.all((pts >= lo - SLACK_M) & (pts <= hi + SLACK_M), axis=1)
        assert inside.mean() >= MIN_POINTS_IN_BOUNDS, \
            f"only {inside.mean():.0%} of the points lie in the floor's bounds"


def check_habitat_env(env: HabitatEnv, moves: list[Pose2D]) -> None:
    """``check_env`` with Habitat's frame check, and a budget area."""
    assert env.budget_area_m2 > 0
    check_env(env, moves, check=check_habitat_observation)  # type: ignore[arg-type]
