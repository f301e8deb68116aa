"""What the robot knows after a step: the 2-D maps every explorer reads."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.navgrid import OccupancyGrid


@dataclass
class MapState:
    """2-D maps on ``spec`` (arrays (rows along y, cols along x), see ``mapping.grid``).

    free: observed free floor where the robot body fits (no obstacle voxel up to its height).
    occupied: observed obstacles (walls, furniture) at body height.
    explored: seen in the bottom-centre window of some frame (DESIGN 3.2), plus the start disk.
    island: the connected free component that contains the robot.
    Cells that are neither free nor occupied have not been observed.
    """

    spec: GridSpec
    free: np.ndarray
    occupied: np.ndarray
    explored: np.ndarray
    island: np.ndarray
    robot_xy: tuple[float, float]

    @cached_property
    def island_grid(self) -> OccupancyGrid:
        """The island as a planning grid, built once per state: its clearance and reachability
        are memoised, so visual prompting and the explorer share them within a step."""
        return OccupancyGrid(self.spec, self.island)

    @property
    def unexplored(self) -> np.ndarray:
        return ~self.explored

    def explored_floor_share(self, floor: np.ndarray) -> float:
        """Share of the true free floor (same grid) that is explored: the coverage metric."""
        total = int(floor.sum())
        return float((self.explored & floor).sum() / total) if total else 0.0
