"""Frontiers on the 2-D maps and their weights (DESIGN 3.2): pure functions on (ny, nx) arrays.

Cells follow ``efficienteqa.mapping.grid``: ``(i, j)`` is row ``i`` along y, column ``j`` along x.
World vectors are (x, y) metres; a cell offset ``(di, dj)`` is the world direction ``(dj, di)``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from efficienteqa.explore.base import Frontier
from efficienteqa.explore.settings import FrontierConfig
from efficienteqa.geometry import Pose2D, wrap_angle
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.state import MapState

_FOUR_CONNECTED = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=bool)
_EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)
# ----- detection ----------------------------------------------------------------------------


def unexplored_neighbour_count(unexplored: np.ndarray) -> np.ndarray:
    """Number (0-8) of unexplored 8-neighbours of each cell; cells outside the grid count."""
    pad = np.pad(unexplored.astype(np.int8), 1, constant_values=1)
    ny, nx = unexplored.shape
    count = np.zeros((ny, nx), dtype=np.int8)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                count += pad[1 + di:1 + di + ny, 1 + dj:1 + dj + nx]
    return count


def frontier_cells(island: np.ndarray, unexplored: np.ndarray,
                   config: FrontierConfig = FrontierConfig()) -> np.ndarray:
    """(K, 2) int cells (i, j): island cells with 3 or 4 unexplored 8-neighbours, row-major."""
    count = unexplored_neighbour_count(unexplored)
    mask = island & (count >= config.min_unexplored_neighbours) & (
        count <= config.max_unexplored_neighbours)
    return np.argwhere(mask)


def cluster(cells: np.ndarray, config: FrontierConfig = FrontierConfig()) -> list[np.ndarray]:
    """Frontiers as index arrays into ``cells`` (distinct (K, 2) int cells).

    More than ``cluster_above_cells`` cells: DBSCAN with eps = ``cluster_eps_cells`` and
    min_samples = 2, computed exactly as connected groups of at least two cells: 4-connected
    for eps in [1, sqrt 2), 8-connected for eps in [sqrt 2, 2). Proof: distinct integer cells lie
    within eps iff they are neighbours in that sense, so a cell is a core point iff it has a
    neighbour in the set; a border point would be within eps of a core point, hence have a
    neighbour, hence be core itself; so there are no border points, the clusters are the
    connected components of core cells, and every isolated cell is noise (dropped).
    With at most ``cluster_above_cells`` cells every cell is its own frontier.
    """
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    if len(cells) <= config.cluster_above_cells:
        return [np.array([k]) for k in range(len(cells))]
    lo = cells.min(axis=0)
    local = cells - lo
    image = np.zeros(tuple(local.max(axis=0) + 1), dtype=bool)
    image[local[:, 0], local[:, 1]] = True
    if not 1.0 <= config.cluster_eps_cells < 2.0:
        raise ValueError("cluster_eps_cells must be in [1, 2)")
    eight = config.cluster_eps_cells >= math.sqrt(2)
    labels, count = ndimage.label(image, structure=_EIGHT_CONNECTED if eight else _FOUR_CONNECTED)
    member = labels[local[:, 0], local[:, 1]]
    order = np.argsort(member, kind="stable")
    groups = np.split(order, np.cumsum(np.bincount(member, minlength=count + 1))[:-1])[1:]
    return [g for g in groups if len(g) >= 2]


def boundary_groups(cells: np.ndarray, island: np.ndarray, unexplored: np.ndarray,
                    members: np.ndarray | None = None) -> list[np.ndarray]:
    """Index arrays into ``cells`` (K, 2): the ``members`` (indices, default all) grouped by
    the stretch of the island's boundary they lie on, groups of one dropped.

    The boundary is the island cells with an unexplored 8-neighbour, and a stretch is one of
    its 8-connected components: a boundary slanted at any angle is one stretch, whereas its
    frontier cells (3-4 unexplored neighbours) may lie several cells apart. Cells off the
    boundary are in no group.
    """
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    index = np.arange(len(cells)) if members is None else np.asarray(members, dtype=np.int64)
    if not len(index):
        return []
    boundary = island & (unexplored_neighbour_count(unexplored) > 0)
    labels, _ = ndimage.label(boundary, structure=_EIGHT_CONNECTED)
    stretch = labels[cells[index, 0], cells[index, 1]]
    on = stretch > 0
    index, stretch = index[on], stretch[on]
    order = np.argsort(stretch, kind="stable")
    index, stretch = index[order], stretch[order]
    groups = np.split(index, np.flatnonzero(np.diff(stretch)) + 1)
    return [g for g in groups if len(g) >= 2]


def representative(cells: np.ndarray) -> int:
    """Index of the member of ``cells`` (K, 2) nearest their mean (first one on ties)."""
    cells = np.asarray(cells, dtype=float)
    return int(np.argmin(((cells - cells.mean(axis=0)) ** 2).sum(axis=1)))


def outward_normal(cells: np.ndarray, unexplored: np.ndarray, window_cells: int = 2) -> np.ndarray:
    """Unit world (x, y) vectors (K, 2) from each cell towards the unexplored side.

    Definition: the normalised mean offset from the cell to the unexplored cells of the square
    window of half-size ``window_cells`` around it (cells outside the grid count as unexplored).
    (0, 0) where that mean vanishes (no unexplored cell, or a symmetric window).
    """
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    w = window_cells
    pad = np.pad(unexplored, w, constant_values=True)
    grid_i, grid_j = np.meshgrid(np.arange(-w, w + 1), np.arange(-w, w + 1), indexing="ij")
    di, dj = grid_i.ravel(), grid_j.ravel()
    hits = pad[cells[:, :1] + w + di, cells[:, 1:] + w + dj]  # (K, window)
    mean = np.stack([(hits * dj).sum(axis=1), (hits * di).sum(axis=1)], axis=-1) / di.size
    norm = np.linalg.norm(mean, axis=1, keepdims=True)
    return np.where(norm > 1e-9, mean / np.maximum(norm, 1e-9), 0.0)


def frontiers_from_cells(state: MapState, cells: np.ndarray,
                         config: FrontierConfig = FrontierConfig()) -> list[Frontier]:
    """Cluster frontier cells and describe each cluster by its representative and normal.

    With ``isolated_along_boundary``, the cells clustering drops as noise are grouped by the
    stretch of the island's boundary they lie on (``boundary_groups``), and each group of two
    or more is a frontier as well."""
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    groups = cluster(cells, config)
    if config.isolated_along_boundary and len(cells) > config.cluster_above_cells:
        clustered = np.zeros(len(cells), dtype=bool)
        for g in groups:
            clustered[g] = True
        groups += boundary_groups(cells, state.island, state.unexplored,
                                  np.flatnonzero(~clustered))
    if not groups:
        return []
    reps = np.array([cells[g[representative(cells[g])]] for g in groups])
    normals = outward_normal(reps, state.unexplored, config.normal_window_cells)
    xys = state.spec.cell_to_world(reps)
    return [Frontier((int(c[0]), int(c[1])), (float(p[0]), float(p[1])),
                     (float(n[0]), float(n[1])), len(g))
            for c, p, n, g in zip(reps, xys, normals, groups)]


def extract_frontiers(state: MapState, config: FrontierConfig = FrontierConfig()) -> list[Frontier]:
    """The frontiers of ``state``: detect cells, cluster, pick representatives and normals."""
    return frontiers_from_cells(state, frontier_cells(state.island, state.unexplored, config), config)


# ----- weights ------------------------------------------------------------------------------
def sample_along(spec: GridSpec, start_xy: np.ndarray, direction: np.ndarray, length_m: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cells sampled every cell size along rays: (i, j, inside), each (K, S).

    Samples lie at distances res, 2 res, ..., length_m (metres) from each start (K, 2) along
    each direction (K, 2); ``inside`` tells which samples fall in the grid (others clipped).
    """
    res = spec.resolution_m
    steps = np.arange(1, max(1, round(length_m / res)) + 1) * res
    pts = np.asarray(start_xy, float)[:, None, :] + np.asarray(direction, float)[:, None, :] * \
        steps[None, :, None]
    i, j = spec.world_to_cell(pts)
    inside = spec.contains((i, j))
    return np.clip(i, 0, spec.shape[0] - 1), np.clip(j, 0, spec.shape[1] - 1), inside


def ray_features(state: MapState, xy: np.ndarray, normals: np.ndarray, values: np.ndarray | None,
                 config: FrontierConfig = FrontierConfig()) -> dict[str, np.ndarray]:
    """Per frontier (K,): r_unexplored (share of unexplored samples over ``unexplored_ray_m``;
    outside the grid counts as unexplored), r_free (share of free samples over ``free_ray_m``),
    and, with a value map, value (V at the frontier cell) and dir_value (mean of the positive
    values sampled over ``value_ray_m``, 0 if none)."""
    spec, k = state.spec, len(xy)
    i, j, inside = sample_along(spec, xy, normals, config.unexplored_ray_m)
    out = {"r_unexplored": np.where(inside, state.unexplored[i, j], True).mean(axis=1)}
    i, j, inside = sample_along(spec, xy, normals, config.free_ray_m)
    out["r_free"] = np.where(inside, state.free[i, j], False).mean(axis=1)
    out["value"], out["dir_value"] = np.zeros(k), np.zeros(k)
    if values is not None and k:
        ci, cj = spec.world_to_cell(xy)
        out["value"] = values[np.clip(ci, 0, spec.shape[0] - 1), np.clip(cj, 0, spec.shape[1] - 1)]
        i, j, inside = sample_along(spec, xy, normals, config.value_ray_m)
        v = np.where(inside, values[i, j], 0.0)
        pos = v > 0
        out["dir_value"] = np.where(pos, v, 0.0).sum(axis=1) / np.maximum(pos.sum(axis=1), 1)
    return out


def close_and_facing(xy: np.ndarray, normals: np.ndarray, pose: Pose2D,
                     config: FrontierConfig = FrontierConfig()) -> np.ndarray:
    """(K,) bool: frontier closer than ``close_m`` metres (Euclidean) whose normal is within
    ``facing_deg`` of the robot's yaw (wrapped angle difference)."""
    xy, normals = np.asarray(xy, float).reshape(-1, 2), np.asarray(normals, float).reshape(-1, 2)
    close = np.linalg.norm(xy - pose.xy, axis=1) < config.close_m
    diff = wrap_angle(np.arctan2(normals[:, 1], normals[:, 0]) - pose.yaw)
    has_normal = np.linalg.norm(normals, axis=1) > 0
    return close & has_normal & (np.abs(diff) < math.radians(config.facing_deg))


def frontier_weight(r_unexplored: np.ndarray, r_free: np.ndarray, value: np.ndarray,
                    dir_value: np.ndarray, distance_m: np.ndarray, penalised: np.ndarray,
                    config: FrontierConfig = FrontierConfig()) -> np.ndarray:
    """DESIGN 3.2: exp(r_u/0.2) exp(r_f/2) exp(V/0.5) exp(v_dir/0.5) exp(-d/10), x1e-3 if penalised."""
    c = config
    w = np.exp(np.asarray(r_unexplored, float) / c.temp_unexplored
               + np.asarray(r_free, float) / c.temp_free
               + np.asarray(value, float) / c.temp_value
               + np.asarray(dir_value, float) / c.temp_dir_value
               - np.asarray(distance_m, float) / c.distance_scale_m)
    return np.where(penalised, w * c.close_facing_factor, w)


def frontier_weights(state: MapState, frontiers: list[Frontier], pose: Pose2D,
                     values: np.ndarray | None, step: int,
                     config: FrontierConfig = FrontierConfig()) -> np.ndarray:
    """Weights (K,) of ``frontiers``; d is the Euclidean distance from the robot to each
    frontier point. Value terms are off when ``values`` is None or step <= value_off_steps."""
    if not frontiers:
        return np.zeros(0)
    xy = np.array([f.xy for f in frontiers], dtype=float)
    normals = np.array([f.normal for f in frontiers], dtype=float)
    use_values = values is not None and step > config.value_off_steps
    feats = ray_features(state, xy, normals, values if use_values else None, config)
    distance = np.linalg.norm(xy - pose.xy, axis=1)
    return frontier_weight(feats["r_unexplored"], feats["r_free"], feats["value"],
                           feats["dir_value"], distance, close_and_facing(xy, normals, pose, config),
                           config)
