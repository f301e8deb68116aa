"""Where the agent's map lies: a square around the start, on the world's voxel lattice.

A robot knows no house box, so the map cannot be sized to the scene: it is a square of side
``size_m`` centred on the start pose, the floor at z = 0 of the canonical frame. Its corner is
snapped to a multiple of the voxel size, so a voxel covers the same world cells whatever the
start (and the same as a map laid over a box with a corner on that lattice).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the configuration reads the constants without numba
    from efficienteqa.mapping.tsdf import VolumeSpec

MAP_SIZE_M = 40.0  # holds a house reaching 20 m from the start in every direction
MIN_MAP_RADIUS_M = 2.0


def volume_around(start_xy: Sequence[float], size_m: float = MAP_SIZE_M,
                  voxel_m: float = 0.1, floor_z: float = 0.0) -> VolumeSpec:
    """The voxel volume of a ``size_m`` square centred on ``start_xy`` (metres), heights as
    ``VolumeSpec.around`` gives them."""
    from efficienteqa.mapping.tsdf import VolumeSpec

    if not size_m >= 2 * MIN_MAP_RADIUS_M:
        raise ValueError(f"a map needs a side of at least {2 * MIN_MAP_RADIUS_M:g} m, not {size_m}")
    n = math.ceil(size_m / voxel_m - 1e-9)
    corner = [math.floor((float(c) - size_m / 2) / voxel_m + 1e-9) for c in start_xy[:2]]
    lo = (corner[0] * voxel_m, corner[1] * voxel_m)
    return VolumeSpec.around(lo, (lo[0] + n * voxel_m, lo[1] + n * voxel_m), floor_z,
                             voxel_m=voxel_m, margin_m=0.0)
