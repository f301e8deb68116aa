"""TSDF fusion against analytic depth: a camera looking straight at a wall plane."""

from __future__ import annotations

import numpy as np
import pytest

from efficienteqa.geometry import CameraSpec, Pose2D, camera_to_world
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.tsdf import BEHIND_WEIGHT, TSDFVolume, VolumeSpec

# 64x48 pinhole, 90 deg hfov: fx = fy = 32. The camera sits at (1.05, 2.05, 1.05), a voxel
# centre, and looks along +x, so the optical axis runs through voxels [20, ix, 10].
CAMERA = CameraSpec(width=64, height=48, hfov_deg=90.0, height_m=1.05, pitch_deg=0.0)
POSE = Pose2D(1.05, 2.05, 0.0)
VOLUME = VolumeSpec((0.0, 0.0, 0.0), 0.1, (40, 60, 20))  # x 0-6 m, y 0-4 m, z 0-2 m
AXIS_IY, AXIS_IZ = 20, 10


def wall_depth(wall_x: float) -> np.ndarray:
    """Depth (m, along the optical axis) of the plane x = wall_x, fronto-parallel: constant."""
    return np.full((CAMERA.height, CAMERA.width), wall_x - POSE.x, dtype=np.float32)


def fused(*depths: np.ndarray) -> TSDFVolume:
    vol = TSDFVolume(VOLUME, trunc_m=0.5)
    for depth in depths:
        vol.integrate(depth, CAMERA.intrinsics, camera_to_world(POSE, CAMERA))
    return vol


def test_volume_spec_around_and_grid():
    spec = VolumeSpec.around((0.0, 0.0), (13.5, 8.8), floor_z=0.0)
    assert spec.origin == pytest.approx((-0.5, -0.5, -0.2))
    assert spec.shape == (98, 145, 37)  # 9.8 x 14.5 m, floor-0.2 to floor+3.5 m
    assert spec.grid == GridSpec((-0.5, -0.5), 0.1, (98, 145))
    assert spec.z_index(0.2) == 4  # layer [0.2, 0.3): 0.4 / 0.1 must not round down to 3
    assert spec.z_index(-5.0) == 0 and spec.z_index(50.0) == 37


def test_wall_zero_crossing_signs_and_truncation():
    vol = fused(wall_depth(4.0))
    line, w = vol.tsdf[AXIS_IY, :, AXIS_IZ], vol.weight[AXIS_IY, :, AXIS_IZ]
    xs = (np.arange(VOLUME.shape[1]) + 0.5) * VOLUME.voxel_m
    k = int(np.nonzero((line[:-1] > 0) & (line[1:] <= 0) & (w[1:] > 0))[0][0])
    crossing = xs[k] + line[k] / (line[k] - line[k + 1]) * VOLUME.voxel_m
    assert crossing == pytest.approx(4.0, abs=VOLUME.voxel_m)
    assert line[39] == pytest.approx(0.05 / 0.5) and line[40] == pytest.approx(-0.05 / 0.5)
    assert (line[11:40] > 0).all() and (w[11:40] == 1).all()  # in front: weight 1 per frame
    assert w[40:45] == pytest.approx(np.full(5, BEHIND_WEIGHT))  # behind: down-weighted
    assert (line[40:45] < 0).all()
    assert (w[45:] == 0).all() and (line[45:] == 1).all()  # beyond trunc: untouched
    assert w[10] == 0  # the voxel holding the camera centre (z = 0) is not in view


def test_weighted_running_average_of_two_frames():
    vol = fused(wall_depth(4.0), wall_depth(4.2))
    line, w = vol.tsdf[AXIS_IY, :, AXIS_IZ], vol.weight[AXIS_IY, :, AXIS_IZ]
    assert line[39] == pytest.approx((0.1 + 0.5) / 2) and w[39] == 2  # sdf 0.05 then 0.25 m
    assert line[44] == pytest.approx((-0.9 - 0.5) / 2) and w[44] == pytest.approx(2 * BEHIND_WEIGHT)
    assert line[46] == pytest.approx(-0.9) and w[46] == pytest.approx(BEHIND_WEIGHT)  # 2nd only
    # A voxel behind the first wall but in front of the second (4.1 m): free-space evidence wins.
    mixed = fused(wall_depth(4.0), wall_depth(4.6)).tsdf[AXIS_IY, 41, AXIS_IZ]
    expected = (BEHIND_WEIGHT * (-0.15 / 0.5) + 1.0 * (0.45 / 0.5)) / (BEHIND_WEIGHT + 1.0)
    assert mixed == pytest.approx(expected, abs=1e-5) and mixed > 0


def test_depth_zero_changes_nothing():
    vol = fused(np.zeros((CAMERA.height, CAMERA.width), np.float32))
    assert (vol.weight == 0).all() and (vol.tsdf == 1).all() and not vol.explored.any()
    half = wall_depth(4.0)
    half[:, : CAMERA.width // 2] = 0  # left half of the image (world +y side) sees nothing
    vol = fused(half)
    assert (vol.weight[25:, 39, AXIS_IZ] == 0).all()  # y >= 2.5 m projects left of centre
    assert (vol.weight[5:20, 39, AXIS_IZ] == 1).all()


def test_beyond_max_depth_is_ignored():
    vol = TSDFVolume(VOLUME)
    assert vol.integrate(wall_depth(4.0), CAMERA.intrinsics, camera_to_world(POSE, CAMERA),
                         max_depth_m=2.0) is None
    assert (vol.weight == 0).all()


def test_explored_only_in_bottom_centre_window():
    vol = fused(wall_depth(4.0))
    # [20, 39, 5]: 0.5 m below the axis at 2.9 m depth -> row 29.5 of 48 (61%), centre column.
    assert vol.weight[20, 39, 5] == 1 and vol.explored[20, 39, 5]
    # Top half: observed but not explored.
    assert vol.weight[20, 39, 15] == 1 and not vol.explored[20, 39, 15]
    # On the optical axis: row 24 of 48 (50%) is inside the window (rows from 40% down).
    assert vol.weight[20, 39, AXIS_IZ] == 1 and vol.explored[20, 39, AXIS_IZ]
    # Bottom rows but 1.5 m to the left: column 15.4 of 64 (24%), outside the window.
    assert vol.weight[35, 39, 5] == 1 and not vol.explored[35, 39, 5]
    # Explored = observed, in the window, and in front of or at the surface.
    iy, ix, iz = np.nonzero(vol.weight > 0)
    centres = np.array(VOLUME.origin) + (np.stack([ix, iy, iz], axis=1) + 0.5) * VOLUME.voxel_m
    cam = (centres - camera_to_world(POSE, CAMERA)[:3, 3]) @ camera_to_world(POSE, CAMERA)[:3, :3]
    k = CAMERA.intrinsics
    u = k[0, 0] * cam[:, 0] / cam[:, 2] + k[0, 2]
    v = k[1, 1] * cam[:, 1] / cam[:, 2] + k[1, 2]
    inside = (u >= 0.25 * 64) & (u < 0.75 * 64) & (v >= 0.4 * 48) & (v < 48)
    at_or_before_surface = (4.0 - POSE.x) - cam[:, 2] >= -VOLUME.voxel_m  # deeper: not seen
    assert (vol.explored[iy, ix, iz] == (inside & at_or_before_surface)).all()
    assert (inside & ~at_or_before_surface).any()  # the band behind the wall is observed too


def test_explored_depth_limit():
    vol = TSDFVolume(VOLUME)
    vol.integrate(wall_depth(4.0), CAMERA.intrinsics, camera_to_world(POSE, CAMERA),
                  explored_depth_m=2.0)
    iy, ix, iz = np.nonzero(vol.explored)
    depth_along_axis = (ix + 0.5) * VOLUME.voxel_m - POSE.x  # the camera looks along +x
    assert len(ix) and depth_along_axis.max() <= 2.0 + 1e-6
    assert (vol.weight[:, 31:, :] > 0).any()  # deeper voxels are still fused, just not explored
