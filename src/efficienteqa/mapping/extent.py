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
VOXEL_M = 0.1
MAP_LAYERS = 37  # VolumeSpec.around's heights: 0.2 m below to 3.5 m above the floor, in voxels
# What the map takes, per voxel: the TSDF volume's distance and weight (float32) and its
# explored flag; per column of the floor: the 2-D maps, their per-step copies and the report's
# picture of them (measured: an ask of 3 to 10 steps peaks at 520-550 bytes per 0.1 m column
# with 37 layers, at 80 and 120 m, of which 333 are the volume).
BYTES_PER_VOXEL = 4 + 4 + 1
BYTES_PER_COLUMN = 220
# The map's memory is bounded, and refused beyond (a 500 m map asked for 13 GiB and ended in
# MemoryError after 3.9 GB). 2 GiB is a side of about 200 m: a reach of 100 m from the start in
# every direction, so any house, the start anywhere in it, with room; and it leaves most of a
# robot's 8 GB computer to the renderer and the models. The default, 40 m, takes 85 MB.
MAX_MAP_BYTES = 2 * 2**30


def map_bytes(size_m: float, voxel_m: float = VOXEL_M) -> int:
    """About how many bytes an episode's map of a ``size_m`` square takes (``BYTES_PER_*``)."""
    n = math.ceil(size_m / voxel_m - 1e-9)
    layers = round(MAP_LAYERS * VOXEL_M / voxel_m)
    return n * n * (layers * BYTES_PER_VOXEL + BYTES_PER_COLUMN)


def max_map_size_m(voxel_m: float = VOXEL_M) -> float:
    """The largest side (whole metres) whose map stays within ``MAX_MAP_BYTES``."""
    per_m2 = map_bytes(1.0, voxel_m)
    return float(math.floor(math.sqrt(MAX_MAP_BYTES / per_m2)))


def check_map_size(size_m: float, voxel_m: float = VOXEL_M) -> None:
    """ValueError, before anything is allocated, for a side the map cannot have: below
    ``2 * MIN_MAP_RADIUS_M`` (or not a number), or a map beyond ``MAX_MAP_BYTES``."""
    if not size_m >= 2 * MIN_MAP_RADIUS_M:
        raise ValueError(f"map_size_m must be at least {2 * MIN_MAP_RADIUS_M:g}, not {size_m}")
    need = map_bytes(size_m, voxel_m) if math.isfinite(size_m) else math.inf
    if need > MAX_MAP_BYTES:
        gib = need / 2**30
        shown = ("unbounded memory" if not math.isfinite(gib) else
                 f"about {gib:.2f} GiB" if gib < 10 else f"about {gib:,.0f} GiB")
        side = max_map_size_m(voxel_m)
        raise ValueError(f"map_size_m {size_m:g} would need {shown} for the map, beyond "
                         f"its bound of {MAX_MAP_BYTES / 2**30:g} GiB (a side of at most "
                         f"{side:g} m, {side / 2:g} m from the start each way: more than any "
                         "house)")


def volume_around(start_xy: Sequence[float], size_m: float = MAP_SIZE_M,
                  voxel_m: float = 0.1, floor_z: float = 0.0) -> VolumeSpec:
    """The voxel volume of a ``size_m`` square centred on ``start_xy`` (metres), heights as
    ``VolumeSpec.around`` gives them."""
    from efficienteqa.mapping.tsdf import VolumeSpec

    check_map_size(size_m, voxel_m)
    n = math.ceil(size_m / voxel_m - 1e-9)
    corner = [math.floor((float(c) - size_m / 2) / voxel_m + 1e-9) for c in start_xy[:2]]
    lo = (corner[0] * voxel_m, corner[1] * voxel_m)
    return VolumeSpec.around(lo, (lo[0] + n * voxel_m, lo[1] + n * voxel_m), floor_z,
                             voxel_m=voxel_m, margin_m=0.0)
