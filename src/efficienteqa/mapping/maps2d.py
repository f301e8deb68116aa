"""From the TSDF volume to the 2-D maps every explorer reads (DESIGN 3.2).

All maps live on ``VolumeSpec.grid`` (row along y, column along x; see ``mapping.grid``), so
``OccupancyGrid(state.spec, state.island)`` plans on them directly. Heights are world metres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np
from scipy import ndimage

from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.state import MapState
from efficienteqa.mapping.tsdf import EXPLORED_WINDOW, TSDFVolume, VolumeSpec
from efficienteqa.observation import Observation

MAX_INVALID_FRACTION = 0.5  # DESIGN 3.1: frames with at least this share of no-depth pixels


class Voxels(Protocol):
    """What the 2-D maps read: a ``TSDFVolume`` or a window of its columns."""

    spec: VolumeSpec
    tsdf: np.ndarray
    weight: np.ndarray
    explored: np.ndarray


def free_and_occupied(volume: Voxels, floor_z: float, robot_height_m: float = 1.5,
                      free_z_m: float = 0.2, surface_tsdf: float = -0.3
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(free, occupied) bool masks (ny, nx); heights in world metres.

    free: every voxel of the column from floor_z + free_z_m up to floor_z + robot_height_m has
    been observed empty (weight > 0, tsdf > 0), and the floor below has been observed (some
    voxel from floor-0.2 m to floor+0.1 m has weight > 0). This extends DESIGN 3.2's "TSDF > 0
    at 0.2 m" with the robot's body height, so the planner never drives under tables or
    shelves, and keeps the reference's "unobserved counts as occupied" for the whole body band.
    occupied: some observed surface voxel (weight > 0, surface_tsdf <= tsdf <= 0: at most
    0.15 m behind a surface with the defaults) in that height band. Voxels deeper behind a
    surface were not really seen: around the view's edges past a door jamb they are mostly
    empty space, and counting them as obstacles walls off doorways and hides frontiers.
    Cells that are neither have not been observed enough to tell.
    """
    spec = volume.spec
    k_free = spec.z_index(floor_z + free_z_m)
    k_top = max(spec.z_index(floor_z + robot_height_m), k_free + 1)
    k_floor_lo, k_floor_hi = spec.z_index(floor_z - 0.2), spec.z_index(floor_z + 0.1)
    band_t, band_w = volume.tsdf[..., k_free:k_top], volume.weight[..., k_free:k_top]
    seen = band_w > 0
    occupied = np.any(seen & (band_t <= 0) & (band_t >= surface_tsdf), axis=2)
    empty = np.all(seen & (band_t > 0), axis=2)
    floor_seen = np.any(volume.weight[..., k_floor_lo:max(k_floor_hi, k_floor_lo + 1)] > 0, axis=2)
    return np.asarray(empty & floor_seen), np.asarray(occupied)


def explored_2d(volume: Voxels) -> np.ndarray:
    """Cells (ny, nx) with any explored voxel in their column."""
    return np.any(volume.explored, axis=2)


def island(free: np.ndarray, robot_cell: tuple[int, int]) -> np.ndarray:
    """The connected component of ``free`` holding robot_cell (row, col); empty if not free.

    4-connected labelling: it gives exactly the components of ``OccupancyGrid`` (8-connected
    without corner cutting), since an allowed diagonal step has a 4-connected detour.
    """
    i, j = robot_cell
    if not (0 <= i < free.shape[0] and 0 <= j < free.shape[1]) or not free[i, j]:
        return np.zeros(free.shape, dtype=bool)
    labels, _ = ndimage.label(free)
    return labels == labels[i, j]


def disk(spec: GridSpec, xy: Sequence[float], radius_m: float) -> np.ndarray:
    """Cells whose centre lies within radius_m metres of the world point xy."""
    xs, ys = spec.centres()
    return (xs - xy[0]) ** 2 + (ys - xy[1]) ** 2 <= radius_m ** 2


def unexplored_neighbours(unexplored: np.ndarray) -> np.ndarray:
    """Number (uint8, 0-8) of unexplored 8-neighbours of each cell; outside the grid counts
    as unexplored. Frontier cells have 3-4 (DESIGN 3.2)."""
    padded = np.pad(unexplored.astype(np.uint8), 1, constant_values=1)
    h, w = unexplored.shape
    count = np.zeros((h, w), dtype=np.uint8)
    for di in (0, 1, 2):
        for dj in (0, 1, 2):
            if di != 1 or dj != 1:
                count += padded[di:di + h, dj:dj + w]
    return count


class Mapper:
    """Fuses each observation into a TSDF volume and derives the 2-D maps of ``MapState``.

    The start clearance disk (start_radius_m around start_xy, metres) is free and explored
    (DESIGN 3.2). Every footprint the robot has stood on (robot_radius_m around each pose) is free
    too: the robot cannot see under itself, and without this its own cell may be unobserved
    after a step, leaving an empty island and nothing to plan on. The 2-D maps are recomputed
    only inside the grid window the frame touched, so the per-step cost follows what is in
    view, not the house or the episode length.
    """

    def __init__(self, spec: VolumeSpec, floor_z: float, start_xy: Sequence[float],
                 trunc_m: float = 0.5, start_radius_m: float = 1.0,
                 robot_height_m: float = 1.5, robot_radius_m: float = 0.2,
                 explored_window: tuple[float, float, float, float] = EXPLORED_WINDOW,
                 explored_depth_m: float = math.inf) -> None:
        self.volume = TSDFVolume(spec, trunc_m)
        self.explored_window = explored_window
        self.explored_depth_m = explored_depth_m
        self.floor_z = floor_z
        self.robot_height_m = robot_height_m
        self.robot_radius_m = robot_radius_m
        self.start_disk = disk(spec.grid, start_xy, start_radius_m)
        shape = spec.shape[:2]
        self._stood = np.zeros(shape, dtype=bool)  # free by fiat: the robot's footprints
        self._blocked = np.zeros(shape, dtype=bool)  # where a move failed: not free
        self._free = np.zeros(shape, dtype=bool)
        self._occupied = np.zeros(shape, dtype=bool)
        self._explored = np.zeros(shape, dtype=bool)
        self._dirty: list[tuple[slice, slice]] = []  # windows fused since the last state()

    @property
    def spec(self) -> GridSpec:
        return self.volume.spec.grid

    def update(self, obs: Observation) -> MapState:
        """Integrate obs (unless >= 50% of its depth is invalid) and return the 2-D maps."""
        self.integrate(obs)
        return self.state((obs.pose.x, obs.pose.y))

    def integrate(self, obs: Observation) -> bool:
        """Fuse obs into the volume; False (nothing fused) for frames that are >= 50% invalid."""
        if obs.invalid_fraction >= MAX_INVALID_FRACTION:
            return False
        region = self.volume.integrate(obs.depth_m, obs.intrinsics, obs.cam_to_world,
                                       window=self.explored_window,
                                       explored_depth_m=self.explored_depth_m)
        if region is not None:
            self._dirty.append(region)
        return True

    def state(self, robot_xy: Sequence[float]) -> MapState:
        """The 2-D maps with the robot at robot_xy (world metres), which becomes a footprint."""
        for region in self._dirty:
            self._refresh(region)
        self._dirty.clear()
        xy = (float(robot_xy[0]), float(robot_xy[1]))
        self._stood |= disk(self.spec, xy, self.robot_radius_m)
        # The start disk is free unless an obstacle was seen there (a wall within 1 m).
        start = self.start_disk & ~self._occupied
        # Where the robot stood is free, a disk marked blocked around it before or not: a move
        # that came up short can end inside the disk its refused goal marked.
        free = ((self._free | start) & ~self._blocked) | self._stood
        occupied = (self._occupied | self._blocked) & ~self._stood
        explored = self._explored | self.start_disk
        i, j = self.spec.world_to_cell(xy)
        return MapState(spec=self.spec, free=free, occupied=occupied, explored=explored,
                        island=island(free, (int(i), int(j))), robot_xy=xy)

    def block(self, xy: Sequence[float], radius_m: float) -> None:
        """Mark a disk (world metres) not free: the robot could not move there."""
        self._blocked |= disk(self.spec, xy, radius_m) & ~self._stood

    def _refresh(self, region: tuple[slice, slice]) -> None:
        """Recompute the cached 2-D maps on the (rows, cols) window the last frame visited."""
        sub = _SubVolume(self.volume, region)
        surface = -1.5 * self.volume.spec.voxel_m / self.volume.trunc_m  # 1.5 voxels behind
        free, occupied = free_and_occupied(sub, self.floor_z, self.robot_height_m,
                                           surface_tsdf=surface)
        self._free[region] = free
        self._occupied[region] = occupied
        self._explored[region] = explored_2d(sub)


class _SubVolume:
    """A view of a TSDFVolume's columns in a (rows, cols) window (same z layers)."""

    def __init__(self, volume: TSDFVolume, region: tuple[slice, slice]) -> None:
        self.spec = volume.spec
        self.tsdf = volume.tsdf[region]
        self.weight = volume.weight[region]
        self.explored = volume.explored[region]
