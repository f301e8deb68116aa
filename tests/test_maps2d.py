"""2-D maps from the TSDF volume: hand-made volumes, an analytic floor, one synthetic house."""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from conftest import needs_egl
from efficienteqa.geometry import CameraSpec, Pose2D, camera_to_world
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.maps2d import (
    Mapper,
    disk,
    explored_2d,
    free_and_occupied,
    island,
    unexplored_neighbours,
)
from efficienteqa.mapping.navgrid import OccupancyGrid, truncate_path
from efficienteqa.mapping.tsdf import TSDFVolume, VolumeSpec
from efficienteqa.observation import Observation


def room_volume() -> TSDFVolume:
    """6 x 8 cells, floor at z = 0, all observed: empty air over a floor, plus a wall column
    (column 0), a table top at 0.7 m over cells [2:4, 4:6], one never-observed cell [5, 7] and
    one cell [0, 7] whose floor was never seen."""
    vol = TSDFVolume(VolumeSpec((0.0, 0.0, -0.2), 0.1, (6, 8, 37)))
    z = vol.spec.origin[2] + (np.arange(37) + 0.5) * 0.1
    vol.tsdf[:] = np.clip(z / 0.5, -1, 1)  # signed height above the floor
    vol.weight[:] = 1
    vol.tsdf[:, 0, 2:20] = -0.2  # wall
    vol.tsdf[2:4, 4:6, vol.spec.z_index(0.7)] = -0.1  # table top
    vol.weight[5, 7] = 0
    vol.weight[0, 7, :3] = 0
    return vol


def test_free_and_occupied_from_hand_made_volume():
    free, occupied = free_and_occupied(room_volume(), floor_z=0.0)
    expected_occ = np.zeros((6, 8), bool)
    expected_occ[:, 0] = True
    expected_occ[2:4, 4:6] = True
    expected_free = ~expected_occ
    expected_free[5, 7] = expected_free[0, 7] = False
    np.testing.assert_array_equal(occupied, expected_occ)
    np.testing.assert_array_equal(free, expected_free)
    # A robot lower than the table fits under it.
    free_low, occ_low = free_and_occupied(room_volume(), floor_z=0.0, robot_height_m=0.5)
    assert free_low[2:4, 4:6].all() and not occ_low[2:4, 4:6].any()


def test_free_needs_the_whole_body_band_seen_empty():
    vol = room_volume()
    vol.tsdf[1, 3, vol.spec.z_index(0.2)] = -0.1  # a low obstacle at 0.2-0.3 m
    vol.weight[4, 3, vol.spec.z_index(1.2)] = 0  # never seen at 1.2 m: could be a shelf
    free, occupied = free_and_occupied(vol, floor_z=0.0)
    assert not free[1, 3] and occupied[1, 3]
    assert not free[4, 3] and not occupied[4, 3]
    assert free[4, 2]


def test_explored_2d_any_voxel_in_column():
    vol = room_volume()
    vol.explored[3, 2, 30] = True
    expected = np.zeros((6, 8), bool)
    expected[3, 2] = True
    np.testing.assert_array_equal(explored_2d(vol), expected)


def test_island_matches_occupancy_grid_components():
    rng = np.random.default_rng(0)
    free = rng.random((30, 40)) < 0.6
    free[10, 10] = free[11, 11] = True
    spec = GridSpec((0.0, 0.0), 0.1, free.shape)
    labels, _ = OccupancyGrid(spec, free).components(0.0)
    for cell in [tuple(c) for c in np.argwhere(free)[::37]]:
        np.testing.assert_array_equal(island(free, cell), labels == labels[cell])
    # Diagonal neighbours only: no corner cutting, two islands.
    diag = np.zeros((3, 3), bool)
    diag[0, 0] = diag[1, 1] = True
    assert island(diag, (0, 0)).sum() == 1
    assert not island(free & False, (10, 10)).any()
    assert not island(free, (-1, 5)).any()


def test_disk_counts_cell_centres():
    spec = GridSpec((0.0, 0.0), 0.1, (11, 11))
    mask = disk(spec, spec.cell_to_world((5, 5)), 0.25)
    assert mask.sum() == 21 and mask[5, 5] and mask[5, 7] and mask[6, 7] and not mask[7, 7]


def test_unexplored_neighbours_with_borders():
    unexplored = np.zeros((3, 4), bool)
    np.testing.assert_array_equal(unexplored_neighbours(unexplored),
                                  [[5, 3, 3, 5], [3, 0, 0, 3], [5, 3, 3, 5]])
    unexplored[1, 1] = True
    np.testing.assert_array_equal(unexplored_neighbours(unexplored),
                                  [[6, 4, 4, 5], [4, 0, 1, 3], [6, 4, 4, 5]])


def floor_observation(pose: Pose2D, camera: CameraSpec, wall_x: float = 7.5) -> Observation:
    """An empty room: the floor plane z = 0 and a wall plane x = wall_x (robot at x < wall_x),
    depth computed analytically along each pixel's ray (camera z = 1 in OpenCV axes)."""
    c2w = camera_to_world(pose, camera)
    u, v = np.meshgrid(np.arange(camera.width) + 0.5, np.arange(camera.height) + 0.5)
    k = camera.intrinsics
    rays = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones_like(u)], -1)
    world = rays @ c2w[:3, :3].T
    with np.errstate(divide="ignore"):
        to_floor = np.where(world[..., 2] < 0, -c2w[2, 3] / world[..., 2], np.inf)
        to_wall = np.where(world[..., 0] > 0, (wall_x - c2w[0, 3]) / world[..., 0], np.inf)
    depth = np.minimum(to_floor, to_wall)
    depth = np.where(np.isfinite(depth), depth, 0.0).astype(np.float32)
    return Observation(rgb=np.zeros(depth.shape + (3,), np.uint8), depth_m=depth,
                       cam_to_world=c2w, intrinsics=k, pose=pose)


def test_mapper_on_an_empty_floor():
    camera = CameraSpec(width=160, height=120)
    spec = VolumeSpec.around((0.0, 0.0), (8.0, 8.0), floor_z=0.0)
    mapper = Mapper(spec, floor_z=0.0, start_xy=(1.0, 4.0))
    state = mapper.update(floor_observation(Pose2D(1.0, 4.0, 0.0), camera))
    assert state.spec == spec.grid and state.robot_xy == (1.0, 4.0)
    wall = spec.grid.world_to_cell((7.55, 4.0))
    assert state.occupied[wall] and not state.free[wall]
    occupied_x = spec.grid.cell_to_world(np.argwhere(state.occupied))[:, 0]
    assert occupied_x.min() > 7.4  # the wall and the shell behind it, nothing in the room
    ahead = spec.grid.world_to_cell((7.0, 4.0))  # 6 m ahead: seen, beyond the window's 5.4 m reach
    near = spec.grid.world_to_cell((2.0, 4.0))  # ~1 m ahead: in the bottom-centre window
    behind = spec.grid.world_to_cell((0.0, 7.5))
    assert state.free[ahead] and state.island[ahead] and not state.explored[ahead]
    assert state.free[near] and state.explored[near]
    assert not state.free[behind] and not state.explored[behind]
    assert state.free[spec.grid.world_to_cell((1.0, 4.9))]  # start disk
    # The island plans directly.
    path = OccupancyGrid(state.spec, state.island).shortest_path((1.0, 4.0), (4.0, 4.0), 0.2)
    assert path is not None


def test_where_the_robot_stands_is_free_inside_a_disk_blocked_before():
    # A refused goal marks a disk; a later move that comes up short can end inside it. The
    # robot's own cell must stay free, or its island is empty and no frontier is left.
    camera = CameraSpec(width=160, height=120)
    spec = VolumeSpec.around((0.0, 0.0), (8.0, 8.0), floor_z=0.0)
    mapper = Mapper(spec, floor_z=0.0, start_xy=(1.0, 4.0))
    mapper.update(floor_observation(Pose2D(1.0, 4.0, 0.0), camera))
    mapper.block((3.0, 4.0), 0.3)
    before = mapper.state((1.0, 4.0))
    assert not before.free[spec.grid.world_to_cell((3.0, 4.0))]
    state = mapper.state((3.1, 4.0))  # the robot ended its move in the blocked disk
    here = spec.grid.world_to_cell((3.1, 4.0))
    assert state.free[here] and state.island[here] and not state.occupied[here]
    assert state.island.sum() > 1000  # the room, not an empty island


def test_mapper_skips_mostly_invalid_frames():
    camera = CameraSpec(width=160, height=120)
    spec = VolumeSpec.around((0.0, 0.0), (8.0, 8.0), floor_z=0.0)
    mapper = Mapper(spec, floor_z=0.0, start_xy=(1.0, 4.0))
    obs = floor_observation(Pose2D(5.0, 4.0, 0.0), camera)
    obs.depth_m[: camera.height * 3 // 5] = 0  # 60% invalid
    state = mapper.update(obs)
    assert (mapper.volume.weight == 0).all()
    np.testing.assert_array_equal(state.explored, mapper.start_disk)
    # The robot stands somewhere: its footprint is free, and is its own island.
    assert state.island.any() and state.island[spec.grid.world_to_cell((5.0, 4.0))]
    assert state.free.sum() == mapper.start_disk.sum() + state.island.sum()


def room_tour(env, steps: int) -> list[Pose2D]:
    """Up to ``steps`` poses 3 m apart along shortest paths to the room centres in turn, each
    facing the way its path goes on (as an explorer faces its target)."""
    from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M

    pose, grid = env.house.start, env.grid
    poses = [pose]
    for room in sorted(env.house.layout.rooms, key=lambda r: math.dist(r.centre, pose.xy)):
        path = grid.shortest_path(pose.xy, room.centre, ROBOT_RADIUS_M, snap_m=2.0)
        while path is not None and len(poses) < steps and math.dist(path[0], path[-1]) > 0.3:
            xy = truncate_path(path, 3.0)
            path = grid.shortest_path(xy, room.centre, ROBOT_RADIUS_M, snap_m=2.0)
            ahead = path[1] - path[0] if path is not None and len(path) > 1 else xy - pose.xy
            pose = Pose2D(float(xy[0]), float(xy[1]), math.atan2(ahead[1], ahead[0]))
            poses.append(pose)
    return poses


def ground_truth_on(spec: GridSpec, truth: OccupancyGrid) -> tuple[np.ndarray, np.ndarray]:
    """(all-free, all-occupied) per map cell from 2x2 blocks of the 0.05 m ground truth."""
    ratio = round(spec.resolution_m / truth.spec.resolution_m)
    off = np.round((np.subtract(truth.spec.origin_xy, spec.origin_xy)) / truth.spec.resolution_m)
    oj, oi = (int(v) for v in off)
    fine = np.zeros((spec.shape[0] * ratio, spec.shape[1] * ratio))
    fine[oi:oi + truth.free.shape[0], oj:oj + truth.free.shape[1]] = truth.free
    share = fine.reshape(spec.shape[0], ratio, spec.shape[1], ratio).mean(axis=(1, 3))
    return share == 1, share == 0


@needs_egl
def test_mapping_a_synthetic_house_matches_ground_truth():
    from efficienteqa.envs.synthetic.env import SyntheticEnv

    with SyntheticEnv.from_seed(3, assets="builtin") as env:
        poses = room_tour(env, 15)
        lo, hi = env.bounds
        spec = VolumeSpec.around(lo[:2], hi[:2], floor_z=0.0)
        mapper = Mapper(spec, floor_z=0.0, start_xy=env.house.start.xy)
        for pose in poses:
            state = mapper.update(env.observe(pose))
        truth = env.grid
    assert len(poses) == 15
    gt_free, gt_occupied = ground_truth_on(spec.grid, truth)
    observed = state.free | state.occupied
    iou = (state.free & gt_free).sum() / ((state.free | gt_free) & observed).sum()
    precision = (state.free & gt_free).sum() / state.free.sum()
    print(f"free IoU over observed cells {iou:.3f}, free precision {precision:.3f}, "
          f"observed {observed.sum()} cells")
    # Measured 0.772: the loss is the TSDF's 0.5 m negative shell behind walls and furniture,
    # observed as occupied until seen from the front. Free cells themselves are 98% right.
    assert iou >= 0.74
    assert precision >= 0.95
    deep_inside = ndimage.binary_erosion(gt_occupied, border_value=1)
    assert not (state.free & deep_inside).any()
    assert state.island[spec.grid.world_to_cell(poses[-1].xy)]
