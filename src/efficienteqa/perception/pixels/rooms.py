"""The room type from what a room holds, voted in the map over one episode (DESIGN 9, learned
perception).

The network names a floor's room type from the floor it sees, but living room, dining room and
office share a wood floor and kitchen and bathroom share tiles. ``RoomVotes`` keeps, across the
frames of one episode, on a ROOM_CELL_M grid (the describer's): each cell's predicted floor
pixels per room type, the wall and door pixels that bound rooms, and the objects seen with
confidence. Rooms are *regions*: seen floor cells connected without crossing a wall or a door
(walls and doors seen, closed over doorway-wide gaps). A region's room type is the best sum of
its floor's evidence and of its objects' log prior ratios, log P(room | category) - log P(room);
an object votes for the region it stands in, grown OBJECT_REACH_M under furniture, or, where its
own cell is a wall's (a table's pixels taken for wall), for the commonest region within
OBJECT_NEAR_M.
The floor's evidence is FLOOR_WEIGHT x the mean over its predicted floor pixels of
log P(predicted type | room type): the network's floor confusions, so a floor it tells well (a
hallway's) holds against objects and a wood floor it confuses (living room, dining room, office)
lets them decide. Both tables are in ``RoomPrior``, counted, never written by hand: objects over
the perception training houses' labels, floor confusions over the agent's walks in the
validation houses (``experiments/room_votes.py prior`` and ``confusion``).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from efficienteqa.perception.floor import ROOM_CELL_M

PRIOR = Path(__file__).resolve().parent / "weights" / "room_prior.json"
# Chosen on the agent's walks in training houses 3000-3004 and validation houses 3900-3909 (2
# and 1 episodes each, 474 steps; `experiments/room_votes.py tune`); figures are floor points
# right: regions by floor alone 80.9%, with objects 87.1% at these values.
PRIOR_MIX = 0.1  # P(room | category) mixed with this share of P(room): a home may differ from
# the training houses, so no object rules a room out (0.02-0.3 measured the same, *)
FLOOR_MIX = 0.05  # P(predicted floor | room type) mixed with this share of uniform: no floor
# reading rules a room out (0.01-0.2 the same, *)
FLOOR_WEIGHT = 8.0  # how many independent readings a region's floor counts for: its confusions
# repeat in every view, so its evidence does not grow with the pixels seen (6: 86.7%, 12: 86.8%)
OBJECT_CONFIDENCE = 0.7  # an object votes when its region's mean probability reaches this
# (0.6: 86.8%, 0.8: 86.2%)
OBJECT_REACH_M = 1.0  # an object votes for a region this close, not across a wall (0.5-2 m the
# same, *)
OBJECT_NEAR_M = 0.3  # an object on a wall's or door's cell votes for the commonest region
# this close (agent's walks at 64713fd, floor of dining rooms right: 3900-3909 29.3 -> 38.0%,
# held-out 2000-2001 and 100-104 55.8 -> 65.4%; 0.5 the same; results/perception/room_votes.json)
OBJECT_MERGE_M = 0.5  # sightings of one category this close are one object (not tuned)
WALL_BAND_M = (0.1, 2.0)  # wall pixels at these heights bound rooms: not the floor, not the
# ceiling, not a doorway's lintel (not tuned)
GAP_CLOSE_M = 1.1  # gaps up to this wide in a line of wall or door cells are closed: doorways
# (1.0-1.4 m: 85.2-86.5%; 0.8 leaves doorways open, 70.4%; 1.6 joins walls, 77.9%, *)
# (*: measured at FLOOR_WEIGHT 4, OBJECT_CONFIDENCE 0.8)
ROOM_REACH_M = 1.0  # a point's room: the nearest region cell within this distance
_GROW_CELLS = 64  # the grid grows by at least this many cells on a side


@dataclass(frozen=True)
class RoomPrior:
    """log P(room type | category) for each counted category, and log P(room type)."""

    rooms: tuple[str, ...]
    log_room: np.ndarray  # (R,)
    log_given: dict[str, np.ndarray]  # category -> (R,)
    log_floor: np.ndarray  # (R true, R predicted) log P(predicted floor type | room type)

    def log_ratio(self, category: str) -> np.ndarray | None:
        """log P(room | category) - log P(room): what seeing one such object says."""
        given = self.log_given.get(category)
        return None if given is None else given - self.log_room

    @classmethod
    def from_counts(cls, rooms: Sequence[str], counts: dict[str, Sequence[float]],
                    floor: Sequence[Sequence[float]] | None = None, mix: float | None = None
                    ) -> RoomPrior:
        """From objects per category and room type, and floor pixels per (room type, predicted
        type) (None: a floor reading is taken as right with probability 1 - FLOOR_MIX)."""
        mix = PRIOR_MIX if mix is None else mix
        r = len(rooms)
        table = np.array([counts[c] for c in sorted(counts)], np.float64).reshape(-1, r)
        share = (table.sum(0) + 1.0) / (table.sum() + r)
        given = (1 - mix) * table / np.maximum(table.sum(1, keepdims=True), 1) + mix * share
        seen = np.eye(r) if floor is None else np.array(floor, np.float64).reshape(r, r)
        confusion = ((1 - FLOOR_MIX) * seen / np.maximum(seen.sum(1, keepdims=True), 1)
                     + FLOOR_MIX / r)
        return cls(tuple(rooms), np.log(share),
                   {c: np.log(row) for c, row in zip(sorted(counts), given)}, np.log(confusion))

    @classmethod
    def load(cls, path: Path = PRIOR) -> RoomPrior:
        record = json.loads(Path(path).read_text())
        floor = record.get("floor_confusion")
        return cls.from_counts(record["rooms"], record["counts"],
                               floor["counts"] if floor else None)


def count_prior(pairs: Iterable[tuple[str, str]], rooms: Sequence[str]) -> dict[str, list[int]]:
    """Objects per (category, room type) from (category, room type) pairs; other rooms are
    left out. Doors belong to two rooms and are left out too."""
    index = {r: k for k, r in enumerate(rooms)}
    counts: dict[str, list[int]] = {}
    for category, room in pairs:
        if category == "door" or room not in index:
            continue
        counts.setdefault(category, [0] * len(rooms))[index[room]] += 1
    return dict(sorted(counts.items()))


@dataclass(frozen=True)
class RoomMap:
    """One solution of the votes: the room index of each grid cell's region (-1 none) and,
    for every cell, the nearest region cell. Immutable, so a frame's labels keep answering
    as they did when the frame was read."""

    rooms: tuple[str, ...]
    origin: tuple[int, int]
    room: np.ndarray  # (H, W) room index per cell, -1 outside regions
    nearest: np.ndarray  # (2, H, W) indices of the nearest region cell
    distance_m: np.ndarray  # (H, W) distance to it

    def room_at(self, x: float, y: float) -> str | None:
        k = int(self.indices_at(np.array([[x, y]]))[0])
        return self.rooms[k] if k >= 0 else None

    def indices_at(self, xy: np.ndarray) -> np.ndarray:
        """The room index at each of (N, 2) points: its nearest region cell's within
        ROOM_REACH_M, else -1."""
        ij = np.floor(np.asarray(xy, np.float64) / ROOM_CELL_M).astype(np.int64) - self.origin
        h, w = self.room.shape
        inside = (ij[:, 0] >= 0) & (ij[:, 0] < h) & (ij[:, 1] >= 0) & (ij[:, 1] < w)
        i, j = np.where(inside, ij[:, 0], 0), np.where(inside, ij[:, 1], 0)
        k = self.room[self.nearest[0, i, j], self.nearest[1, i, j]]
        return np.where(inside & (self.distance_m[i, j] <= ROOM_REACH_M), k, -1)


@dataclass(frozen=True)
class Seen:
    """What one frame adds to the votes: world xy of predicted floor pixels and their room
    indices, of wall pixels in WALL_BAND_M and of door pixels, and the confident objects as
    (category, xy)."""

    floor_xy: np.ndarray
    floor_room: np.ndarray
    wall_xy: np.ndarray
    door_xy: np.ndarray
    objects: Sequence[tuple[str, tuple[float, float]]]


class RoomVotes:
    """Room evidence of one episode on a growing grid; ``reset`` between episodes."""

    def __init__(self, rooms: Sequence[str], prior: RoomPrior | None) -> None:
        self.rooms = tuple(rooms)
        self.prior = prior
        self._ratio: dict[str, np.ndarray | None] = {}
        r = len(self.rooms)
        self._log_floor = np.log((1 - FLOOR_MIX) * np.eye(r) + FLOOR_MIX / r)
        if prior is not None:  # the prior's rooms in this vocabulary's order
            if set(self.rooms) - set(prior.rooms):
                raise ValueError(f"the room prior has no {sorted(set(self.rooms) - set(prior.rooms))}")
            order = [prior.rooms.index(name) for name in self.rooms]
            for c in prior.log_given:
                ratio = prior.log_ratio(c)
                assert ratio is not None
                self._ratio[c] = ratio[order]
            self._log_floor = prior.log_floor[np.ix_(order, order)]
        self.reset()

    def reset(self) -> None:
        self._origin = (0, 0)
        self._floor: np.ndarray = np.zeros((len(self.rooms), 0, 0), np.float32)
        self._wall: np.ndarray = np.zeros((0, 0), np.float32)
        self._objects: dict[tuple[str, int, int], tuple[float, float]] = {}
        self._frames: set[tuple[int, ...]] = set()
        self._map: RoomMap | None = None

    def add(self, key: tuple[int, ...], seen: Seen) -> RoomMap:
        """Add a frame (once per ``key``: a frame read again adds nothing) and solve."""
        if key not in self._frames or self._map is None:
            self._frames.add(key)
            self._add(seen)
            self._map = self._solve()
        return self._map

    # -- accumulation ------------------------------------------------------------------------
    def _cells(self, xy: np.ndarray) -> np.ndarray:
        return np.floor(np.asarray(xy, np.float64).reshape(-1, 2) / ROOM_CELL_M).astype(np.int64)

    def _fit(self, cells: np.ndarray) -> None:
        """Grow the grid to hold ``cells`` (absolute indices)."""
        if not len(cells):
            return
        lo, hi = cells.min(0), cells.max(0) + 1
        h, w = self._wall.shape
        o = np.array(self._origin)
        if h and np.all(lo >= o) and np.all(hi <= o + (h, w)):
            return
        new_lo = np.minimum(lo, o) if h else lo
        new_hi = np.maximum(hi, o + (h, w)) if h else hi
        new_lo = new_lo - _GROW_CELLS
        new_hi = new_hi + _GROW_CELLS
        shape = tuple(int(v) for v in new_hi - new_lo)
        floor = np.zeros((len(self.rooms), *shape), np.float32)
        wall = np.zeros(shape, np.float32)
        if h:
            a, b = o - new_lo
            floor[:, a:a + h, b:b + w] = self._floor
            wall[a:a + h, b:b + w] = self._wall
        self._origin = (int(new_lo[0]), int(new_lo[1]))
        self._floor, self._wall = floor, wall

    def _add(self, seen: Seen) -> None:
        floor = self._cells(seen.floor_xy)
        bound = self._cells(np.concatenate([seen.wall_xy.reshape(-1, 2),
                                            seen.door_xy.reshape(-1, 2)]))
        self._fit(np.concatenate([floor, bound]))
        o = np.array(self._origin)
        r, h, w = self._floor.shape
        f, b = floor - o, bound - o
        flat = (np.asarray(seen.floor_room, np.int64) * h + f[:, 0]) * w + f[:, 1]
        for grid, index in ((self._floor, flat), (self._wall, b[:, 0] * w + b[:, 1])):
            cells, n = np.unique(index, return_counts=True)
            grid.reshape(-1)[cells] += n
        for category, xy in seen.objects:
            if self._ratio.get(category) is None:
                continue
            i, j = (int(v) for v in np.floor(np.asarray(xy) / OBJECT_MERGE_M))
            if not any((category, i + a, j + b) in self._objects
                       for a in (-1, 0, 1) for b in (-1, 0, 1)):
                self._objects[(category, i, j)] = (float(xy[0]), float(xy[1]))

    # -- solution --------------------------------------------------------------------------
    def _solve(self) -> RoomMap:
        reach_cells = int(round(OBJECT_REACH_M / ROOM_CELL_M))
        span = max(1, int(round(GAP_CLOSE_M / ROOM_CELL_M)))
        # the work is done on the part of the grid that holds what was seen, with room around
        # it for the reaches and the gap closing
        pad = max(reach_cells, int(np.ceil(ROOM_REACH_M / ROOM_CELL_M)), span) + 2
        any_seen = self._floor.any(0) | (self._wall > 0)
        rows, cols = np.flatnonzero(any_seen.any(1)), np.flatnonzero(any_seen.any(0))
        if not len(rows):
            empty = np.zeros((1, 1), np.int64)
            return RoomMap(self.rooms, self._origin, empty - 1, np.zeros((2, 1, 1), np.int64),
                           np.full((1, 1), np.inf))
        i0, j0 = max(rows[0] - pad, 0), max(cols[0] - pad, 0)
        crop = (slice(i0, rows[-1] + pad + 1), slice(j0, cols[-1] + pad + 1))
        counts, walls = self._floor[(slice(None), *crop)], self._wall[crop]
        origin = (self._origin[0] + int(i0), self._origin[1] + int(j0))
        seen = counts.sum(0) > 0
        bound = walls > 0
        for shape in ((span, 1), (1, span)):  # close doorway-wide gaps along wall lines
            bound |= ndimage.binary_closing(walls > 0, np.ones(shape, bool))
        free = seen & ~bound
        regions, n = ndimage.label(free)
        r = len(self.rooms)
        cells = np.flatnonzero(free)
        flat = regions.ravel()[cells]
        totals = np.stack([np.bincount(flat, weights=counts[t].ravel()[cells], minlength=n + 1)
                           for t in range(r)], axis=1)  # (n + 1, R)
        shares = totals / np.maximum(totals.sum(1, keepdims=True), 1.0)  # (n + 1, R predicted)
        score = FLOOR_WEIGHT * shares @ self._log_floor.T  # (n + 1, R true)
        distance, nearest = ndimage.distance_transform_edt(~free, return_indices=True)
        distance_m = distance * ROOM_CELL_M
        o = np.array(origin)
        h, w = free.shape
        reach = _grow(regions, bound, reach_cells)
        near_cells = int(round(OBJECT_NEAR_M / ROOM_CELL_M))
        for (category, _, _), xy in sorted(self._objects.items()):
            i, j = self._cells(np.array(xy))[0] - o
            region = _region_near(reach, i, j, near_cells)
            if region == 0:
                continue
            ratio = self._ratio[category]
            assert ratio is not None
            score[region] += ratio
        best = score.argmax(1)
        best[0] = -1  # not a region
        room = np.where(regions > 0, best[regions], -1)
        return RoomMap(self.rooms, origin, room, nearest, distance_m)


def _region_near(reach: np.ndarray, i: int, j: int, cells: int) -> int:
    """The region at cell (i, j) of ``reach`` or, where that cell is a wall's or a door's (a
    table's pixels the network took for wall, or the object's own middle), the commonest region
    within ``cells`` of it; 0 for none."""
    h, w = reach.shape
    if not (0 <= i < h and 0 <= j < w):
        return 0
    if reach[i, j] or not cells:
        return int(reach[i, j])
    window = reach[max(i - cells, 0):i + cells + 1, max(j - cells, 0):j + cells + 1]
    found = window[window > 0]
    return int(np.bincount(found).argmax()) if len(found) else 0


def _grow(regions: np.ndarray, bound: np.ndarray, cells: int) -> np.ndarray:
    """Regions grown ``cells`` steps into cells that are not walls or doors (where furniture
    hides the floor): an object's region is one it stands in without crossing a wall."""
    grown = regions.copy()
    open_cells = ~bound
    for _ in range(cells):
        spread = ndimage.grey_dilation(grown, size=(3, 3))
        grown = np.where((grown == 0) & open_cells, spread, grown)
    return grown


def describe_prior(prior: RoomPrior, categories: Sequence[str]) -> dict[str, Any]:
    """The most likely room of each category, for a reader's check of the prior."""
    out: dict[str, Any] = {}
    for c in categories:
        ratio = prior.log_given.get(c)
        if ratio is not None:
            out[c] = prior.rooms[int(np.argmax(ratio))]
    return out
