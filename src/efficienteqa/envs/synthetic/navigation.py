"""Ground-truth 2-D occupancy of a synthetic house's floor, start poses and oracle moves.

Walls, floors and furniture footprints are rasterised onto a ``GridSpec``; planning on the
result is ``efficienteqa.mapping.navgrid``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D, wrap_angle
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.navgrid import OccupancyGrid, path_length


def _paint(mask: np.ndarray, spec: GridSpec, box: tuple[float, float, float, float],
           inside: Callable[[np.ndarray, np.ndarray], np.ndarray], value: bool) -> None:
    """Set mask to value where inside(X, Y) holds, testing only centres within box (m)."""
    (i0, j0), (i1, j1) = (np.array(spec.world_to_cell(np.array(p))) for p in (box[:2], box[2:]))
    i0, j0 = max(int(i0) - 1, 0), max(int(j0) - 1, 0)
    i1, j1 = min(int(i1) + 2, spec.shape[0]), min(int(j1) + 2, spec.shape[1])
    if i0 >= i1 or j0 >= j1:
        return
    res, (ox, oy) = spec.resolution_m, spec.origin_xy
    xs = ox + (np.arange(j0, j1) + 0.5) * res
    ys = oy + (np.arange(i0, i1) + 0.5) * res
    xg, yg = np.meshgrid(xs, ys)
    sub = mask[i0:i1, j0:j1]
    sub[inside(xg, yg)] = value


def _oriented_box(cx: float, cy: float, half_u: float, half_v: float, yaw: float
                  ) -> tuple[tuple[float, float, float, float],
                             Callable[[np.ndarray, np.ndarray], np.ndarray]]:
    """Bounding box (m) and inside test of a rectangle with half sizes along its rotated axes."""
    c, s = math.cos(yaw), math.sin(yaw)
    ex, ey = abs(c) * half_u + abs(s) * half_v, abs(s) * half_u + abs(c) * half_v

    def inside(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        dx, dy = x - cx, y - cy
        return (np.abs(dx * c + dy * s) <= half_u) & (np.abs(-dx * s + dy * c) <= half_v)

    return (cx - ex, cy - ey, cx + ex, cy + ey), inside


def rasterise(spec: GridSpec, floor_rects: Sequence[Sequence[float]],
              wall_segments: Sequence[Sequence[float]],
              footprints: Sequence[Sequence[float]]) -> OccupancyGrid:
    """The occupancy grid: a cell is free iff its centre is on floor and in no wall or footprint.

    floor_rects: (x0, y0, x1, y1) metres, axis-aligned, closed. wall_segments: (x0, y0, x1, y1,
    thickness_m); a wall covers points within thickness/2 of the segment whose projection falls
    on it (no end caps). Walls are never rasterised thinner than one cell (one cell diagonal for
    slanted walls) so they cannot leak. footprints: (cx, cy, width_m, depth_m, yaw_rad): width
    along the object's local x axis, depth along its local y, yaw counter-clockwise from +x.
    """
    free = np.zeros(spec.shape, dtype=bool)
    for x0, y0, x1, y1 in floor_rects:
        box, inside = _oriented_box((x0 + x1) / 2, (y0 + y1) / 2, abs(x1 - x0) / 2,
                                    abs(y1 - y0) / 2, 0.0)
        _paint(free, spec, box, inside, True)
    res = spec.resolution_m
    for x0, y0, x1, y1, thickness in wall_segments:
        length = math.hypot(x1 - x0, y1 - y0)
        yaw = math.atan2(y1 - y0, x1 - x0)
        slanted = abs(math.sin(2 * yaw)) > 1e-9
        half_t = max(thickness / 2, res * (math.sqrt(0.5) if slanted else 0.5) * (1 + 1e-6))
        box, inside = _oriented_box((x0 + x1) / 2, (y0 + y1) / 2, length / 2, half_t, yaw)
        _paint(free, spec, box, inside, False)
    for cx, cy, width, depth, yaw in footprints:
        box, inside = _oriented_box(cx, cy, width / 2, depth / 2, yaw)
        _paint(free, spec, box, inside, False)
    return OccupancyGrid(spec, free)


def sample_start_pose(grid: OccupancyGrid, rng: np.random.Generator, radius_m: float,
                      clearance_m: float = 1.0, score: Callable[[Pose2D], float] | None = None,
                      tries: int = 16, n_yaws: int = 16) -> Pose2D:
    """A start pose: navigable, >= clearance_m (m) of free space around, in the largest component.

    The yaw (rad) faces open space: among n_yaws directions, the one whose free ray length
    averaged with its two neighbours is longest (a wedge, not a slit). With ``score``, ``tries``
    candidates are drawn and the best-scoring one is returned; otherwise the first draw.
    """
    labels, count = grid.components(radius_m)
    ok = (labels == 1) & (grid.clearance() >= clearance_m - 1e-9) if count else labels > 0
    cells = np.argwhere(ok)
    if len(cells) == 0:
        raise EfficientEQAError(
            f"no start pose with {clearance_m} m clearance for a robot of radius {radius_m} m",
            fix="use a larger house, a smaller clearance_m, or fewer obstacles")
    picks = rng.choice(len(cells), size=min(tries if score else 1, len(cells)), replace=False)
    yaws = np.arange(n_yaws) * (2 * math.pi / n_yaws)
    poses = []
    for xy in grid.spec.cell_to_world(cells[picks]):
        rays = grid.ray_length(xy, yaws)
        wedge = (rays + np.roll(rays, 1) + np.roll(rays, -1)) / 3
        poses.append(Pose2D(float(xy[0]), float(xy[1]),
                            float(wrap_angle(yaws[int(np.argmax(wedge))]))))
    if score is None:
        return poses[0]
    return poses[int(np.argmax([score(p) for p in poses]))]


def oracle_moves(grid: OccupancyGrid, start_xy: Sequence[float],
                 goal_poses_xy: Sequence[Sequence[float]], radius_m: float,
                 step_m: float = 3.0, snap_m: float = 0.5) -> int | None:
    """Fewest moves of at most step_m metres along shortest paths to reach any goal position.

    ceil(path length / step_m) with the line-of-sight-shortened path; 0 when a goal lies in the
    start cell; None if no goal is reachable.
    """
    s_cell = grid.snap(start_xy, radius_m, snap_m)
    if s_cell is None:
        return None
    field_m = grid.distance_field(start_xy, radius_m, snap_m)
    found: list[tuple[float, Sequence[float]]] = []
    for goal in goal_poses_xy:
        g_cell = grid.snap(goal, radius_m, snap_m)
        if g_cell is None or not np.isfinite(field_m[g_cell]):
            continue
        if g_cell == s_cell:
            return 0
        found.append((float(field_m[g_cell]), goal))
    if not found:
        return None
    best = min(d for d, _ in found)
    lengths = []
    for d, goal in found:  # the grid metric overestimates by at most 8.3 %
        if d <= best * 1.0824 + grid.spec.resolution_m:
            path = grid.shortest_path(start_xy, goal, radius_m, snap_m)
            if path is not None:
                lengths.append(path_length(path))
    return max(1, math.ceil(min(lengths) / step_m - 1e-9))
