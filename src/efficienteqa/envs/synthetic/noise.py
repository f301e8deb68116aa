"""A robot's imperfections in a synthetic house: named noise profiles and the environment that
applies them.

A perfect simulator gives exact depth, an exact pose, and moves that land where they were sent.
A robot gives none of these. ``NoisyEnv`` wraps a ``SyntheticEnv`` and adds, as a profile says:

- **depth noise and holes**: Gaussian noise growing with the square of the range (as
  structured-light and stereo sensors do), and blocks of pixels with no depth;
- **odometry drift**: the pose the robot reports is the true pose moved by a drift that random-walks
  with every metre travelled; the agent sends goals in its own (drifted) frame;
- **moves that fall short or fail**: a share of moves stop part of the way (the navigation
  stack gave up), a share fail (the robot stays);
- **a camera that is not where the pose says**: a fixed mounting error (offset and tilt) between
  where the camera is and where the robot's model puts it.

Each episode's noise is drawn from a generator seeded by the house and the start pose, so a run
is repeatable. The scene's oracles (navigability, floor area, bounds) stay the simulator's: the
evaluation reads them, never the agent.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, fields, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from efficienteqa.envs.base import move_info
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D, camera_to_world
from efficienteqa.observation import Observation

if TYPE_CHECKING:
    from efficienteqa.envs.synthetic.env import SyntheticEnv


@dataclass(frozen=True)
class NoiseProfile:
    """How imperfect the robot is. Every field at 0 is the perfect simulator."""

    depth_sigma_per_m2: float = 0.0  # depth noise std (m) per m^2 of range: k * d^2
    depth_holes: float = 0.0  # share of the frame in blocks with no depth
    drift_m_per_m: float = 0.0  # odometry drift std (m) per metre moved
    drift_rad_per_m: float = 0.0  # heading drift std (rad) per metre moved
    fail_share: float = 0.0  # moves that fail: the robot stays
    short_share: float = 0.0  # moves that stop part of the way
    short_reach: tuple[float, float] = (0.4, 0.9)  # how much of the way a short move goes
    camera_offset_m: float = 0.0  # the camera's mounting error, metres (forward and up)
    camera_tilt_deg: float = 0.0  # and its tilt error, degrees (pitch down, yaw left)

    @property
    def perfect(self) -> bool:
        return all(getattr(self, f.name) == 0.0 for f in fields(self) if f.name != "short_reach")


# A mobile base with an RGB-D camera indoors: about 1.2 cm of depth noise at 2 m, 3% of the frame
# without depth, 2 cm and 0.6 degrees of drift per metre, 5% of moves failed and 15% short, and a
# camera mounted 3 cm and 1.5 degrees off its calibration.
ROBOT = NoiseProfile(depth_sigma_per_m2=0.003, depth_holes=0.03, drift_m_per_m=0.02,
                     drift_rad_per_m=0.01, fail_share=0.05, short_share=0.15,
                     camera_offset_m=0.03, camera_tilt_deg=1.5)
PROFILES: dict[str, NoiseProfile] = {
    "none": NoiseProfile(),
    "robot": ROBOT,
    # The robot's imperfections one at a time, to see which costs most.
    "robot-depth": NoiseProfile(depth_sigma_per_m2=ROBOT.depth_sigma_per_m2,
                                depth_holes=ROBOT.depth_holes),
    "robot-odometry": NoiseProfile(drift_m_per_m=ROBOT.drift_m_per_m,
                                   drift_rad_per_m=ROBOT.drift_rad_per_m),
    "robot-moves": NoiseProfile(fail_share=ROBOT.fail_share, short_share=ROBOT.short_share),
    "robot-camera": NoiseProfile(camera_offset_m=ROBOT.camera_offset_m,
                                 camera_tilt_deg=ROBOT.camera_tilt_deg),
}
HOLE_BLOCK_PX = 16  # holes come in blocks of this many pixels a side (at 640 px wide)


def profile(name: str) -> NoiseProfile:
    """The named profile, or a one-line error naming the known ones."""
    if name not in PROFILES:
        raise EfficientEQAError(f"unknown noise profile {name!r}",
                                fix=f"use one of {', '.join(PROFILES)}")
    return PROFILES[name]


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """``a`` then ``b`` as rigid motions of the floor (``b`` expressed in ``a``'s frame)."""
    c, s = math.cos(a.yaw), math.sin(a.yaw)
    return Pose2D(a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y,
                  float(math.remainder(a.yaw + b.yaw, math.tau)))


def inverse(a: Pose2D) -> Pose2D:
    c, s = math.cos(a.yaw), math.sin(a.yaw)
    return Pose2D(-(c * a.x + s * a.y), s * a.x - c * a.y, -a.yaw)


def noisy_depth(depth_m: np.ndarray, p: NoiseProfile, rng: np.random.Generator) -> np.ndarray:
    """``depth_m`` with range-squared Gaussian noise and blocks of holes (0 = no depth)."""
    out = depth_m.astype(np.float32, copy=True)
    valid = out > 0
    if p.depth_sigma_per_m2 > 0:
        noise = rng.standard_normal(out.shape).astype(np.float32)
        out[valid] += (p.depth_sigma_per_m2 * out[valid] ** 2) * noise[valid]
        out[valid] = np.maximum(out[valid], 0.01)
    if p.depth_holes > 0:
        block = max(2, round(HOLE_BLOCK_PX * out.shape[1] / 640))
        coarse = rng.random((math.ceil(out.shape[0] / block), math.ceil(out.shape[1] / block)))
        holes = np.repeat(np.repeat(coarse < p.depth_holes, block, axis=0), block, axis=1)
        out[holes[: out.shape[0], : out.shape[1]]] = 0.0
    return out


class NoisyEnv:
    """A ``SyntheticEnv`` as an imperfect robot sees it (see the module's docstring). Poses
    the agent sends and receives are in the robot's own frame: the true pose plus drift."""

    def __init__(self, env: SyntheticEnv, noise: NoiseProfile, seed: int = 0) -> None:
        self.env, self.noise, self.seed = env, noise, seed
        self.camera = env.camera
        self.drift = Pose2D(0.0, 0.0, 0.0)  # reported = drift o true
        self.rng = np.random.default_rng(seed)
        tilt = math.radians(noise.camera_tilt_deg)
        self._mount = _mount_error(noise.camera_offset_m, tilt)

    # -- the robot's contract ------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Observation, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        start = self.env.pose
        key = f"{self.seed}:{start.x:.3f}:{start.y:.3f}:{start.yaw:.3f}".encode()
        self.rng = np.random.default_rng([self.seed, zlib.crc32(key)])
        self.drift = Pose2D(0.0, 0.0, 0.0)
        return self.observe(), info

    def step(self, action: Pose2D) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        before = self.env.pose
        goal = compose(inverse(self.drift), action)  # the goal where it truly lies
        draw = self.rng.random()
        if draw < self.noise.fail_share:
            goal = before
        elif draw < self.noise.fail_share + self.noise.short_share:
            goal = self._short_of(before, goal, self.rng.uniform(*self.noise.short_reach))
        blocked = goal == before or not self.env.is_navigable(goal.x, goal.y)
        if not blocked:  # moved (rendered once, below, with the noise)
            self.env.pose = goal
            self._drift_by(math.dist((before.x, before.y), (goal.x, goal.y)))
        self.env.steps += 1
        obs = self.observe()
        return obs, 0.0, False, False, {"step": self.env.steps, "pose": obs.pose,
                                        **move_info(action, obs.pose, blocked)}

    def observe(self) -> Observation:
        true = self.env.pose
        reported = compose(self.drift, true)
        truth = camera_to_world(true, self.camera) @ self._mount  # where the camera really is
        frame = self.env.renderer.render(truth)
        depth = noisy_depth(frame.depth_m, self.noise, self.rng)
        instance = None if frame.instance is None else np.where(depth > 0, frame.instance, -1)
        return Observation(rgb=frame.rgb, depth_m=depth,
                           cam_to_world=camera_to_world(reported, self.camera),
                           intrinsics=self.camera.intrinsics, pose=reported,
                           instance=None if instance is None else instance.astype(np.int32))

    def close(self) -> None:
        self.env.close()

    # -- what the evaluation reads: the simulator's truth --------------------------------
    def __getattr__(self, name: str) -> Any:
        if name in ("is_navigable", "floor_area_m2", "bounds", "house", "grid", "start",
                    "scene_labels", "renderer", "steps"):
            return getattr(self.env, name)
        raise AttributeError(name)

    @property
    def pose(self) -> Pose2D:
        """The true pose (the evaluation's; the agent reads the reported one)."""
        return self.env.pose

    # -- the imperfections ---------------------------------------------------------------
    def _short_of(self, here: Pose2D, goal: Pose2D, reach: float) -> Pose2D:
        """``reach`` of the way from ``here`` to ``goal``, facing the goal's heading; the
        farthest navigable point along the way if that one is not."""
        for f in (reach, reach * 0.75, reach * 0.5, reach * 0.25):
            p = replace(goal, x=here.x + f * (goal.x - here.x), y=here.y + f * (goal.y - here.y))
            if self.env.is_navigable(p.x, p.y):
                return p
        return here

    def _drift_by(self, metres: float) -> None:
        n = self.noise
        if metres <= 0 or (n.drift_m_per_m == 0 and n.drift_rad_per_m == 0):
            return
        dx, dy = self.rng.normal(0.0, n.drift_m_per_m * metres, 2)
        dyaw = self.rng.normal(0.0, n.drift_rad_per_m * metres)
        self.drift = compose(self.drift, Pose2D(float(dx), float(dy), float(dyaw)))


def _mount_error(offset_m: float, tilt_rad: float) -> np.ndarray:
    """A 4x4 camera-frame motion (OpenCV axes: x right, y down, z forward): ``offset_m`` forward
    and up, and ``tilt_rad`` about the camera's x axis (pitch) and y axis (yaw)."""
    cp, sp = math.cos(tilt_rad), math.sin(tilt_rad)
    pitch = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
    yaw = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    out = np.eye(4)
    out[:3, :3] = yaw @ pitch
    out[:3, 3] = [0.0, -offset_m, offset_m]
    return out
