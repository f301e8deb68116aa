"""Visual prompting (DESIGN 3.3): pick up to three floor points in view and letter them on the frame.

Geometry only (``project_floor_points``, ``candidate_points``); drawing the letters on the frame is
``perception.image.draw_prompts`` (what a vision-language model sees). Points are kept apart in
the world (``merge_m``) and in the image (``min_px``): two floor points metres apart along one
line of sight project to nearly the same pixel, and a circle drawn there would hide the other's
letter, so a candidate whose circle would overlap a chosen one's is never chosen.
Pixels follow OpenCV: u right, v down, continuous, pixel (col k, row l) spans [k, k+1) x [l, l+1)
so its centre is (k + 0.5, l + 0.5) — the convention of ``geometry.backproject``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from efficienteqa.explore.settings import PROMPT_SETS
from efficienteqa.mapping.navgrid import OccupancyGrid
from efficienteqa.mapping.state import MapState
from efficienteqa.observation import PromptPoint
from efficienteqa.perception.image import CIRCLE_RADIUS_PX

LETTERS = "ABC"
# Centres of two lettered circles at least this far apart (pixels): the disks do not touch.
MIN_CIRCLE_GAP_PX = 2.0 * CIRCLE_RADIUS_PX + 4.0
_LOS_CHUNK = 2048  # candidates per vectorised line-of-sight batch (bounds memory)


@dataclass(frozen=True)
class PromptConfig:
    """Where candidate points may lie (see ``candidate_points``; metres, pixels).

    The defaults ask more often than DESIGN 3.3's points 2-10 m away, 1 m apart (``PAPER_PROMPTS``):
    in small rooms and doorways no two points 2 m off are in view, so only 60% of the steps
    of frontier-only episodes (training houses 0-7) offered directions; points from 1 m,
    0.75 m apart, raise that to 83%. Values can steer only the steps that ask.
    """

    radius_m: float = 0.2
    min_m: float = 1.0
    max_m: float = 10.0
    n: int = 3
    merge_m: float = 0.75
    margin_px: float = 20.0
    prefer_unexplored: bool = True
    min_px: float = MIN_CIRCLE_GAP_PX


PAPER_PROMPTS = PromptConfig(min_m=2.0, merge_m=1.0)
PROMPT_CONFIGS = dict(zip(PROMPT_SETS, (PromptConfig(), PAPER_PROMPTS), strict=True))


def project_floor_points(xy: np.ndarray, cam_to_world: np.ndarray, intrinsics: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (N, 2) of floor points xy (N, 2) metres at z = 0, and whether each is in front.

    ``cam_to_world`` is 4x4 with OpenCV camera axes; points behind the camera get NaN pixels.
    """
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    world = np.concatenate([p, np.zeros((len(p), 1))], axis=1)
    cam = (world - cam_to_world[:3, 3]) @ cam_to_world[:3, :3]  # R^T (p - t), row form
    in_front = cam[:, 2] > 1e-6
    z = np.where(in_front, cam[:, 2], np.nan)
    u = intrinsics[0, 0] * cam[:, 0] / z + intrinsics[0, 2]
    v = intrinsics[1, 1] * cam[:, 1] / z + intrinsics[1, 2]
    return np.stack([u, v], axis=-1), in_front


def _sampled_line_of_sight(free: np.ndarray, state: MapState, targets: np.ndarray) -> np.ndarray:
    """Fast pre-filter: every sample (spacing <= res/2) from the robot to each target is free."""
    spec, robot = state.spec, np.asarray(state.robot_xy, dtype=float)
    ok = np.zeros(len(targets), dtype=bool)
    if not len(targets):
        return ok
    longest = float(np.linalg.norm(targets - robot, axis=1).max())
    t = np.linspace(0.0, 1.0, int(np.ceil(longest / (spec.resolution_m / 2))) + 2)
    for s in range(0, len(targets), _LOS_CHUNK):
        seg = targets[s:s + _LOS_CHUNK] - robot
        pts = robot + t[None, :, None] * seg[:, None, :]
        i, j = spec.world_to_cell(pts)
        inside = spec.contains((i, j))
        hit = np.zeros_like(inside)
        hit[inside] = free[i[inside], j[inside]]
        ok[s:s + _LOS_CHUNK] = hit.all(axis=1)
    return ok


def candidate_points(state: MapState, obs_pose_cam_to_world: np.ndarray, intrinsics: np.ndarray,
                     image_size: tuple[int, int], rng_or_seed: np.random.Generator | int | None,
                     radius_m: float = 0.2, min_m: float = 2.0, max_m: float = 10.0, n: int = 3,
                     merge_m: float = 1.0, margin_px: float = 20.0,
                     prefer_unexplored: bool = True,
                     min_px: float = MIN_CIRCLE_GAP_PX) -> list[PromptPoint]:
    """Up to ``n`` lettered floor points to prompt the VLM with; [] unless at least 2 remain.

    Candidates are island cell centres navigable for a disk robot of ``radius_m`` in the robot's
    component, ``min_m``-``max_m`` metres (straight line) from ``state.robot_xy``, projecting at
    least ``margin_px`` inside the ``image_size`` = (w, h) frame, and in line of sight from the
    robot on ``state.free``. Farthest-point sampling starts from a candidate drawn uniformly with
    the seeded RNG (deterministic for a seed), then adds the candidate farthest from those chosen;
    a point within ``merge_m`` of an earlier one is dropped. A candidate projecting within
    ``min_px`` pixels of a chosen point (its lettered circle would overlap that one's) leaves the
    pool, and the sampling goes on with the next farthest. Letters A, B, C go left to right in
    the image: "A" is the leftmost point.

    With ``prefer_unexplored`` the candidates are the unexplored ones whenever at least 2 of
    them qualify: the prompt asks which direction to explore, and values painted where the
    robot has already looked sit away from every frontier, so they cannot steer (DESIGN 3.2
    weights frontiers by the value at and beyond them).
    """
    rng = np.random.default_rng(rng_or_seed)
    island = state.island_grid
    start = island.snap(state.robot_xy, radius_m)
    if start is None:
        return []
    labels, _ = island.components(radius_m)
    ii, jj = np.nonzero(labels == labels[start])
    xy = state.spec.cell_to_world(np.stack([ii, jj], axis=-1))
    dist = np.linalg.norm(xy - np.asarray(state.robot_xy, dtype=float), axis=1)
    xy = xy[(dist >= min_m) & (dist <= max_m)]
    uv, front = project_floor_points(xy, obs_pose_cam_to_world, intrinsics)
    w, h = image_size
    with np.errstate(invalid="ignore"):
        view = front & (uv[:, 0] >= margin_px) & (uv[:, 0] <= w - margin_px) & (
            uv[:, 1] >= margin_px) & (uv[:, 1] <= h - margin_px)
    xy, uv = xy[view], uv[view]
    sight = _sampled_line_of_sight(state.free, state, xy)
    xy, uv = xy[sight], uv[sight]
    if prefer_unexplored and len(xy):
        i, j = state.spec.world_to_cell(xy)
        fresh = ~state.explored[i, j]
        if fresh.sum() >= 2:
            xy, uv = xy[fresh], uv[fresh]
    chosen = _farthest_points(xy, OccupancyGrid(state.spec, state.free), state.robot_xy, n, rng,
                              uv=uv, min_px=min_px)
    kept: list[int] = []
    for k in chosen:
        if all(np.linalg.norm(xy[k] - xy[m]) >= merge_m for m in kept):
            kept.append(k)
    if len(kept) < 2:
        return []
    kept.sort(key=lambda k: uv[k, 0])
    return [PromptPoint(letter, (float(xy[k, 0]), float(xy[k, 1])),
                        (float(uv[k, 0]), float(uv[k, 1]))) for letter, k in zip(LETTERS, kept)]


def prompt_points(state: MapState, obs_pose_cam_to_world: np.ndarray, intrinsics: np.ndarray,
                  image_size: tuple[int, int], rng_or_seed: np.random.Generator | int | None,
                  config: PromptConfig = PromptConfig()) -> list[PromptPoint]:
    """``candidate_points`` with the limits of ``config``."""
    return candidate_points(state, obs_pose_cam_to_world, intrinsics, image_size, rng_or_seed,
                            **asdict(config))


def _farthest_points(xy: np.ndarray, free: OccupancyGrid, robot_xy: Sequence[float], n: int,
                     rng: np.random.Generator, uv: np.ndarray | None = None,
                     min_px: float = 0.0) -> list[int]:
    """Indices of up to n farthest-point samples; each pick is confirmed with the exact
    (conservative) ``line_of_sight``, and rejected picks leave the pool. With pixels ``uv``
    (N, 2), a pick within ``min_px`` of a chosen point's pixel is rejected too."""
    valid = np.ones(len(xy), dtype=bool)
    min_d = np.full(len(xy), np.inf)
    chosen: list[int] = []
    while len(chosen) < n and valid.any():
        if chosen:
            k = int(np.argmax(np.where(valid, min_d, -np.inf)))
        else:
            k = int(rng.choice(np.flatnonzero(valid)))
        valid[k] = False
        if uv is not None and chosen and np.linalg.norm(uv[chosen] - uv[k], axis=1).min() < min_px:
            continue
        if not free.line_of_sight(robot_xy, xy[k]):
            continue
        chosen.append(k)
        min_d = np.minimum(min_d, np.linalg.norm(xy - xy[k], axis=1))
    return chosen

