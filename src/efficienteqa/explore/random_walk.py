"""The random-walk reference explorer: a uniformly random reachable cell within one step."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from efficienteqa.explore.base import Decision
from efficienteqa.explore.settings import SFEConfig
from efficienteqa.explore.sfe import cut_path, settle
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.state import MapState


@dataclass(frozen=True)
class RandomConfig:
    """Random-walk constants (metres)."""

    max_step_m: float = 3.0  # goal within this path distance
    robot_radius_m: float = 0.25  # as in SFEConfig
    snap_m: float = 0.5
    stop_clearance_m: float = SFEConfig.stop_clearance_m
    settle_m: float = 0.25


class RandomExplorer:
    """Baseline: each step go to a uniformly random reachable island cell within ``max_step_m``
    of path distance, facing the direction of travel. Never ``done``."""

    name = "random"

    def __init__(self, config: RandomConfig | None = None) -> None:
        self.config = config or RandomConfig()
        self.reset(0)

    def reset(self, seed: int) -> None:
        self._rng = np.random.default_rng(seed)

    def decide(self, state: MapState, pose: Pose2D, values: np.ndarray | None,
               step: int) -> Decision:
        cfg = self.config
        grid = state.island_grid
        start = (pose.x, pose.y)
        radius = cfg.robot_radius_m if grid.snap(start, cfg.robot_radius_m, cfg.snap_m) else 0.0
        dist = grid.distance_field(start, radius, cfg.snap_m)
        # the goal cell centre is within max_step_m of the robot's (snapped) cell centre; keep a
        # margin of one cell diagonal for the robot's offset from that centre
        margin = state.spec.resolution_m * math.sqrt(2)
        ii, jj = np.nonzero((dist > 0) & (dist <= cfg.max_step_m - margin))
        if not len(ii):
            return Decision(pose, pose.xy[None, :].copy(), reason="stuck")
        k = int(self._rng.integers(len(ii)))
        goal = state.spec.cell_to_world((ii[k], jj[k]))
        path = grid.shortest_path(start, (float(goal[0]), float(goal[1])), radius, cfg.snap_m)
        if path is None:  # defensive: the goal was reachable by construction
            return Decision(pose, pose.xy[None, :].copy(), reason="stuck")
        if np.linalg.norm(path[0] - pose.xy) > 1e-9:
            path = np.vstack([pose.xy, path])
        path = settle(grid, cut_path(path, cfg.max_step_m), radius, cfg.stop_clearance_m,
                      cfg.settle_m, cfg.max_step_m, cfg.snap_m)
        d = path[-1] - path[-2]
        yaw = math.atan2(d[1], d[0]) if np.linalg.norm(d) > 1e-9 else pose.yaw
        return Decision(Pose2D(float(path[-1][0]), float(path[-1][1]), yaw), path,
                        target_xy=(float(goal[0]), float(goal[1])), reason="random cell")
