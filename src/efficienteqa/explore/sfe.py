"""Semantic-value-weighted frontier exploration, SFE (DESIGN 3.2; paper "Exploration - SFE").

Each step: find the frontiers, weight them (semantic values optional), sample one in proportion
to its weight, stand ``backoff_m`` behind it along its normal, plan on the island grid for a disk
robot and move at most ``max_step_m`` along the path, facing the frontier. A chosen target is
kept across steps until reached, its frontier vanishes, or it becomes unreachable.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from efficienteqa.explore.base import Decision, Frontier
from efficienteqa.explore.frontiers import (
    frontier_cells,
    frontier_weights,
    frontiers_from_cells,
)
from efficienteqa.explore.settings import SFEConfig
from efficienteqa.geometry import Pose2D, wrap_angle
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.navgrid import OccupancyGrid, path_length, truncate_path
from efficienteqa.mapping.state import MapState


@dataclass
class _Target:
    frontier: Frontier
    stand_xy: np.ndarray
    radius_m: float  # the planning radius it was found reachable with


class FrontierExplorer:
    """SFE (``name`` "sfe") or, with ``use_values=False``, the "frontier-only" baseline."""

    def __init__(self, config: SFEConfig | None = None) -> None:
        self.config = config or SFEConfig()
        self.name = "sfe" if self.config.use_values else "frontier-only"
        # Beyond the paper (DESIGN 9): a factor per frontier multiplied into its weight, set by a wrapper
        # that knows more than the map (explore.target: the room a frontier lies in).
        self.prior: Callable[[list[Frontier]], np.ndarray] | None = None
        self.reset(0)

    def reset(self, seed: int) -> None:
        """Seed the sampling and forget the committed target."""
        self._rng = np.random.default_rng(seed)
        self._target: _Target | None = None
        self._looked: list[list] = []  # [frontier xy, times reached and looked at]

    def forget(self) -> None:
        """Drop the committed target: the next decision chooses among the frontiers afresh."""
        self._target = None

    def decide(self, state: MapState, pose: Pose2D, values: np.ndarray | None,
               step: int) -> Decision:
        """The next pose (see the module docstring); ``done`` when no frontier is reachable.

        With ``skip_idle``, a decision that would take the same view again (the robot stays
        within ``reached_m`` and turns less than ``idle_turn_deg``) counts as a look at its
        frontier and the choice is made again, at most ``idle_retries`` times."""
        decision = self._decide(state, pose, values, step)
        cfg = self.config
        for _ in range(cfg.idle_retries if cfg.skip_idle else 0):
            if decision.done or decision.frontier is None or not idle(decision.pose, pose,
                                                                      cfg.reached_m,
                                                                      cfg.idle_turn_deg):
                break
            self._record_look(decision.frontier.xy)
            self._target = None
            decision = self._decide(state, pose, values, step)
        return decision

    def _decide(self, state: MapState, pose: Pose2D, values: np.ndarray | None,
                step: int) -> Decision:
        cfg = self.config
        cells = frontier_cells(state.island, state.unexplored, cfg.frontier)
        frontiers = frontiers_from_cells(state, cells, cfg.frontier)
        values = values if cfg.use_values else None
        stay = Decision(pose, pose.xy[None, :].copy(), frontiers=frontiers, done=True)
        if not frontiers:
            self._target = None
            stay.weights = np.zeros(0)
            stay.reason = "no frontier"
            return stay
        looks = self._looks(np.array([f.xy for f in frontiers]))
        # Looked at once from the back-off point: one more look, from the frontier itself.
        backoff = np.where(looks == 0, cfg.backoff_m, 0.0)
        stay.weights = weights = self._weights(state, frontiers, pose, values, step, looks)
        grid = state.island_grid
        start = (pose.x, pose.y)

        reason = "committed"
        if self._target is not None:
            reachable, _ = self._reachable(grid, start, self._target.radius_m)
            if reachable is None or not self._keep_target(state, cells, reachable, pose):
                self._target = None
        if self._target is None:
            reason = "new frontier"
            # Through a doorway seen at an angle only a sliver of floor is mapped: when nothing
            # fresh is reachable at the planning radius, try the tight one (a wrong guess comes
            # back as a blocked move and is mapped).
            # Fresh frontiers first at the planning radius; then, at the tight radius, fresh
            # ones and second looks (which would otherwise be planned back to the same spot).
            # With approach_unreachable, last: any frontier, looked at or not, from the
            # reachable cell nearest its back-off point however far that is.
            tiers = [(cfg.robot_radius_m, looks == 0, cfg.max_stand_shift_m),
                     (cfg.tight_radius_m, looks < cfg.max_looks, cfg.max_stand_shift_m)]
            if cfg.approach_unreachable:
                tiers.append((cfg.tight_radius_m, looks >= 0, math.inf))
            for wanted, allowed, shift_m in tiers:
                reachable, radius = self._reachable(grid, start, wanted)
                if reachable is None:
                    continue
                stands, ok = self._standing_points(state, frontiers, reachable, backoff,
                                                   shift_m)
                ok &= allowed
                if ok.any():
                    k = sample_index(self._rng, np.where(ok, weights, 0.0), ok)
                    self._target = _Target(frontiers[k], stands[k], radius)
                    break
            else:
                stay.reason = "no reachable frontier"
                return stay

        target = self._target
        goal = (float(target.stand_xy[0]), float(target.stand_xy[1]))
        path = grid.shortest_path(start, goal, target.radius_m, cfg.snap_m)
        if path is None:  # the snapped robot cell and the target share a component: defensive
            self._target = None
            stay.reason = "no path"
            return stay
        if np.linalg.norm(path[0] - pose.xy) > 1e-9:
            path = np.vstack([pose.xy, path])
        path = settle(grid, cut_path(path, cfg.max_step_m), target.radius_m,
                      cfg.stop_clearance_m, cfg.settle_m, cfg.max_step_m, cfg.snap_m)
        yaw = self._facing(path, np.asarray(target.frontier.xy), pose.yaw)
        end = path[-1]
        if cfg.view_gain:
            yaw = view_yaw(state, end, yaw, cfg.view_range_m, cfg.view_half_deg,
                           cfg.view_keep_share)
        return Decision(Pose2D(float(end[0]), float(end[1]), yaw), path,
                        target_xy=goal, frontier=target.frontier, frontiers=frontiers,
                        weights=weights, reason=reason)

    def _reachable(self, grid: OccupancyGrid, start: tuple[float, float], radius_m: float
                   ) -> tuple[np.ndarray | None, float]:
        """(cells reachable from the robot, the radius used): radius 0 when the robot's own
        cell is too tight for ``radius_m``; None when no cell is reachable."""
        cfg = self.config
        if grid.snap(start, radius_m, cfg.snap_m) is None:
            radius_m = 0.0
        dist = grid.distance_field(start, radius_m, cfg.snap_m)
        reachable = grid.navigable(radius_m) & np.isfinite(dist)
        return (reachable if reachable.any() else None), radius_m

    # ----- helpers -------------------------------------------------------------------------
    def _weights(self, state: MapState, frontiers: list[Frontier], pose: Pose2D,
                 values: np.ndarray | None, step: int, looks: np.ndarray) -> np.ndarray:
        """DESIGN 3.2 weights (K,), x ``looked_factor`` for frontiers already looked at."""
        cfg = self.config
        weights = frontier_weights(state, frontiers, pose, values, step, cfg.frontier)
        if self.prior is not None:
            weights = weights * self.prior(frontiers)
        return np.where(looks == 0, weights, weights * cfg.looked_factor)

    def _keep_target(self, state: MapState, cells: np.ndarray, reachable: np.ndarray,
                     pose: Pose2D) -> bool:
        """Whether the committed target is still pending, alive and reachable."""
        t, cfg = self._target, self.config
        assert t is not None
        if np.linalg.norm(pose.xy - t.stand_xy) <= cfg.reached_m:
            self._record_look(t.frontier.xy)
            return False
        if not len(cells):
            return False
        cell_xy = state.spec.cell_to_world(cells)
        if np.linalg.norm(cell_xy - np.asarray(t.frontier.xy), axis=1).min() > cfg.vanish_m:
            return False
        i, j = state.spec.world_to_cell(t.stand_xy)
        return bool(state.spec.contains((i, j)) and reachable[i, j])

    def _looks(self, xy: np.ndarray) -> np.ndarray:
        """How often each frontier point (K, 2) was already reached and looked at."""
        if not self._looked or not len(xy):
            return np.zeros(len(xy), int)
        points = np.array([p for p, _ in self._looked])
        counts = np.array([c for _, c in self._looked])
        near = np.linalg.norm(xy[:, None] - points[None], axis=2) <= self.config.looked_m
        return np.where(near, counts[None], 0).max(axis=1)

    def _record_look(self, xy: tuple[float, float]) -> None:
        for entry in self._looked:
            if np.hypot(entry[0][0] - xy[0], entry[0][1] - xy[1]) <= self.config.looked_m:
                entry[1] += 1
                return
        self._looked.append([xy, 1])

    def _standing_points(self, state: MapState, frontiers: list[Frontier],
                         reachable: np.ndarray, backoff_m: np.ndarray, max_shift_m: float
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Standing points (K, 2) m, ``backoff_m`` (K,) behind each frontier against its normal.

        Where that point is not a reachable cell (outside the house past an oblique doorway,
        inside furniture), shorter back-offs are tried (2/3, 1/3, 0 of it); failing those, the
        reachable cell nearest the full back-off point, then the one nearest the frontier
        point. ok (K,) is False where no reachable cell lies within ``max_shift_m``."""
        spec = state.spec
        points = np.array([f.xy for f in frontiers])
        normals = np.array([f.normal for f in frontiers])

        def on_reachable(xy: np.ndarray) -> np.ndarray:
            i, j = spec.world_to_cell(xy)
            inside = spec.contains((i, j))
            out = np.zeros(len(xy), bool)
            out[inside] = reachable[i[inside], j[inside]]
            return out

        full = points - backoff_m[:, None] * normals
        i, j = spec.world_to_cell(full)
        i = np.clip(i, 0, spec.shape[0] - 1)
        j = np.clip(j, 0, spec.shape[1] - 1)
        _, (ni, nj) = ndimage.distance_transform_edt(~reachable, return_indices=True)
        stands = spec.cell_to_world(np.stack([ni[i, j], nj[i, j]], axis=-1))
        ok = np.linalg.norm(stands - full, axis=1) <= max_shift_m
        # Next: the reachable cell nearest the frontier point itself (an oblique doorway edge).
        fi, fj = (np.clip(a, 0, n - 1) for a, n in zip(spec.world_to_cell(points), spec.shape))
        near = spec.cell_to_world(np.stack([ni[fi, fj], nj[fi, fj]], axis=-1))
        use = ~ok & (np.linalg.norm(near - points, axis=1) <= max_shift_m)
        stands[use], ok = near[use], ok | use
        for fraction in (0.0, 1 / 3, 2 / 3, 1.0):  # the longest back-off that works wins
            xy = points - fraction * backoff_m[:, None] * normals
            hit = on_reachable(xy)
            stands[hit] = xy[hit]
            ok |= hit
        if not self.config.stand_in_sight:
            return stands, ok
        # the same order, each standing point also in sight of its frontier; a frontier with
        # no such point keeps the one above
        seen = np.zeros(len(points), bool)
        clear = stands.copy()
        close = np.linalg.norm(near - points, axis=1) <= max_shift_m
        for xy, fits in ((near, close), *((points - f * backoff_m[:, None] * normals, True)
                                          for f in (0.0, 1 / 3, 2 / 3, 1.0))):
            hit = fits & on_reachable(xy) & in_sight(state.occupied, spec, xy, points)
            clear[hit] = xy[hit]
            seen |= hit
        return np.where(seen[:, None], clear, stands), ok | seen

    def _facing(self, path: np.ndarray, frontier_xy: np.ndarray, yaw: float) -> float:
        """Yaw (rad) from the path end towards the frontier; the last path direction when the
        frontier is closer than ``face_min_m``; the current yaw if the path has no length."""
        d = frontier_xy - path[-1]
        if np.linalg.norm(d) >= self.config.face_min_m:
            return math.atan2(d[1], d[0])
        seg = np.diff(path, axis=0)
        seg = seg[np.linalg.norm(seg, axis=1) > 1e-9]
        return math.atan2(seg[-1][1], seg[-1][0]) if len(seg) else yaw


def in_sight(occupied: np.ndarray, spec: GridSpec, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(K,) whether the segments a[k] -> b[k] (metres) cross no ``occupied`` cell (sampled
    every half cell; cells off the grid are not obstacles)."""
    if not len(a):
        return np.zeros(0, bool)
    n = max(2, int(np.ceil(np.linalg.norm(b - a, axis=1).max() / (spec.resolution_m / 2))) + 1)
    t = np.linspace(0.0, 1.0, n)
    pts = a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]
    i, j = spec.world_to_cell(pts.reshape(-1, 2))
    inside = spec.contains((i, j))
    hit = np.zeros(len(i), bool)
    hit[inside] = occupied[i[inside], j[inside]]
    return np.asarray(~hit.reshape(len(a), n).any(axis=1))


def ray_gain(state: MapState, xy: np.ndarray, range_m: float, n_rays: int = 360
             ) -> np.ndarray:
    """Unexplored cells (n_rays,) a ray from ``xy`` (m) passes, every cell size out to
    ``range_m``, before its first occupied cell; ray k points at yaw 2 pi k / n_rays."""
    spec = state.spec
    angles = 2 * np.pi * np.arange(n_rays) / n_rays
    steps = np.arange(1, int(range_m / spec.resolution_m) + 1) * spec.resolution_m
    pts = np.asarray(xy, float)[None, None, :] + steps[None, :, None] * np.stack(
        [np.cos(angles), np.sin(angles)], axis=-1)[:, None, :]
    i, j = spec.world_to_cell(pts)
    inside = spec.contains((i, j))
    i, j = np.clip(i, 0, spec.shape[0] - 1), np.clip(j, 0, spec.shape[1] - 1)
    open_ = np.cumprod(inside & ~state.occupied[i, j], axis=1).astype(bool)
    return (open_ & state.unexplored[i, j]).sum(axis=1)


def view_yaw(state: MapState, xy: np.ndarray, facing: float, range_m: float, half_deg: float,
             keep_share: float) -> float:
    """The yaw (rad) whose view wedge (+-``half_deg``, ``range_m``) holds the most unexplored
    cells in sight from ``xy``; ``facing`` unless that one holds less than ``keep_share`` of
    the best."""
    gain = ray_gain(state, xy, range_m).astype(float)
    n = len(gain)
    half = int(round(half_deg * n / 360))
    wedge = np.sum([np.roll(gain, k) for k in range(-half, half + 1)], axis=0)
    k_face = int(round(facing * n / (2 * np.pi))) % n
    best = int(np.argmax(wedge))
    if wedge[best] <= 0 or wedge[k_face] >= keep_share * wedge[best]:
        return facing
    return float(wrap_angle(2 * np.pi * best / n))


def idle(new: Pose2D, pose: Pose2D, within_m: float, turn_deg: float) -> bool:
    """Whether ``new`` is within ``within_m`` metres of ``pose`` and turned less than
    ``turn_deg`` degrees from it (wrapped): the same view again."""
    turn = abs(float(wrap_angle(new.yaw - pose.yaw)))
    return bool(np.hypot(new.x - pose.x, new.y - pose.y) <= within_m
                and turn < math.radians(turn_deg))


def sample_index(rng: np.random.Generator, weights: np.ndarray,
                 allowed: np.ndarray | None = None) -> int:
    """An index drawn with probability proportional to ``weights`` (one draw from ``rng``);
    uniform over ``allowed`` (default: all) when the weights do not sum to a positive number."""
    w = np.asarray(weights, dtype=float)
    total = w.sum()
    if np.isfinite(total) and total > 0:
        p = w / total
    else:
        ok = np.ones(len(w), bool) if allowed is None else np.asarray(allowed, bool)
        p = ok / ok.sum()
    return int(rng.choice(len(p), p=p))


def settle(grid: OccupancyGrid, path: np.ndarray, radius_m: float, clearance_m: float,
           within_m: float, max_step_m: float, snap_m: float) -> np.ndarray:
    """``path`` (K, 2), from the robot, with its end moved where the map leaves room to stand.

    An end whose cell has less than ``clearance_m`` of clearance on ``grid`` moves to the
    nearest cell within ``within_m`` of it that has that much, reachable at ``radius_m`` within
    ``max_step_m`` of path; failing that, to the roomiest such cell if it is roomier. The new
    path is planned to it and cut at ``max_step_m``. ``clearance_m`` 0: the path unchanged."""
    end = path[-1]
    spec = grid.spec
    i, j = spec.world_to_cell(end)
    inside = bool(spec.contains((i, j)))
    room = grid.clearance()
    here = float(room[i, j]) if inside else 0.0
    if clearance_m <= 0 or here >= clearance_m:
        return path
    start = (float(path[0][0]), float(path[0][1]))
    # the window of cells around the end
    reach = int(math.ceil(within_m / spec.resolution_m))
    i0, j0 = max(int(i) - reach, 0), max(int(j) - reach, 0)
    i1, j1 = min(int(i) + reach + 1, spec.shape[0]), min(int(j) + reach + 1, spec.shape[1])
    if i0 >= i1 or j0 >= j1:
        return path
    dist = grid.distance_field(start, radius_m, snap_m)[i0:i1, j0:j1]
    ii, jj = np.mgrid[i0:i1, j0:j1]
    xy = spec.cell_to_world(np.stack([ii, jj], axis=-1))
    gap = np.linalg.norm(xy - end, axis=-1)
    # the robot stands up to half a cell diagonal off its cell's centre
    ok = (gap <= within_m) & (dist <= max_step_m - spec.resolution_m * math.sqrt(0.5))
    cell_room = room[i0:i1, j0:j1]
    if not ok.any():
        return path
    roomy = ok & (cell_room >= clearance_m)
    if roomy.any():
        k = np.unravel_index(np.argmin(np.where(roomy, gap, np.inf)), gap.shape)
    else:
        k = np.unravel_index(np.argmax(np.where(ok, cell_room, -np.inf)), gap.shape)
        if cell_room[k] <= here:
            return path
    goal = (float(xy[k][0]), float(xy[k][1]))
    moved = grid.shortest_path(start, goal, radius_m, snap_m)
    if moved is None:
        return path
    if np.linalg.norm(moved[0] - path[0]) > 1e-9:
        moved = np.vstack([path[0], moved])
    return cut_path(moved, max_step_m)


def cut_path(path: np.ndarray, max_m: float) -> np.ndarray:
    """The first ``max_m`` metres of a polyline (K, 2): its waypoints up to there plus the end
    point ``truncate_path`` gives."""
    path = np.asarray(path, dtype=float)
    if path_length(path) <= max_m:
        return path
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    return np.vstack([path[cum < max_m], truncate_path(path, max_m)])
