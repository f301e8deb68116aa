"""From the network's per-pixel classes to what the semantic describer reads (DESIGN 9,
learned perception).

The pixel network gives, at half the frame's size, a category per pixel (nothing, wall, the floor
of a room type, a door or an object category), a colour and a state. This module turns them into
the two things the label-reading describer (``perception.semantic``) takes: an instance buffer at
full size (-1 nothing, 0 walls and floors, 1.. objects) and ``SceneLabels`` that answer only from
this frame: each predicted object's category, colour, state, room and, for doors, the rooms on
either side; the room at a floor point from the floor the frame shows. Pure numpy and scipy.

Instances are the connected regions of one object category, cut where depth jumps (two chairs
side by side are two chairs when one stands behind the other), then regions of one category
whose centres lie within FRAGMENT_MERGE_M joined again (a chair's back and seat are one
chair). A region the network is unsure of is left out: its confidence, the mean probability of
its category over the region, must reach a threshold per category recorded with the weights
(``perception.pixels.thresholds``; none is recorded: see DESIGN 9), MIN_CONFIDENCE otherwise.
(The mean over the region's interior, its rim left out, traded found for right along the same
curve on validation houses 3900-3909: no better, so the whole region it is.) Colour and state
are the majority of the pixels' predictions inside a region; the room of an object is the room
of the predicted floor nearest to it; a door's near side is the room of the floor in front of
it, its far side the room of the floor seen beyond it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from efficienteqa.envs.base import DoorSides, ObjectLabel
from efficienteqa.geometry import backproject
from efficienteqa.perception.floor import FLOOR_TOLERANCE_M, ROOM_CELL_M  # as the describer
from efficienteqa.perception.pixels.fusion import FUSED_MIN, ObjectEvidence, cell_keys
from efficienteqa.perception.pixels.rooms import (
    OBJECT_CONFIDENCE,
    WALL_BAND_M,
    RoomMap,
    RoomVotes,
    Seen,
)

FLOOR_PREFIX = "floor:"  # the network's floor categories: "floor:<room type>"
ROOM_REACH_M = 1.0  # a point's room: the predicted floor within this distance
DEPTH_JUMP = 0.15  # neighbours whose depths differ by more than this share are two objects
MIN_CONFIDENCE = 0.6  # regions whose mean category probability is lower are dropped
# (both chosen on validation houses 3900-3909, 60 frames, for the best balance of objects found
# and right: 0.0 / 0.08 found 69% and 40% right, 0.6 / 0.08 63% and 67%, 0.6 / 0.15 65% and 68%)
FRAGMENT_MERGE_M = 0.35  # same-category regions whose centres are this close are one object
# (validation houses 3900-3909, 100 frames: off / 0.25 / 0.35 / 0.5 m found 71.8 / 72.6 / 72.6 /
# 72.6%, right 71.9 / 71.4 / 73.0 / 75.5%, chairs miscounted per frame 1.00 / 0.87 / 0.80 / 0.87)
UNSURE_MIN = 0.3  # regions this sure, though too unsure to describe, go to the instance map
FULL_PIXELS = 600  # at 640x480: a region this large counts its whole confidence in the map
MAP_DEPTH_M = 0.75  # a region's points in the map: this close to their median point (or twice
# their median distance from it)
MIN_REGION_PIXELS = 6  # at half size: smaller regions are noise (the describer lists >= 150/4)
DOOR_BEYOND_M = (0.5, 1.0, 2.0, 3.0)  # a door's far side: the first other room's floor this
# far beyond it, along the line from the camera


@dataclass(frozen=True)
class PixelClasses:
    """The network's reading of one frame at half size: ``category`` (h, w) indices into
    ``categories``, ``colour`` (h, w) indices into ``colours``, ``state`` (h, w) 0 for none,
    else 1 + an index into ``states``."""

    category: np.ndarray
    colour: np.ndarray
    state: np.ndarray
    categories: Sequence[str]
    colours: Sequence[str]
    states: Sequence[str]
    confidence: np.ndarray | None = None  # (h, w) the category's probability, when known
    # a region's least confidence per category (``thresholds``), MIN_CONFIDENCE for the others
    min_confidence: Mapping[str, float] = field(default_factory=dict)


class FrameLabels:
    """``SceneLabels`` read off one frame: the predicted objects' labels, and the room at a point
    from the floor the frame shows (the nearest predicted floor cell within ROOM_REACH_M), or,
    given ``votes``, from the episode's room map as it stood after this frame."""

    def __init__(self, labels: dict[int, ObjectLabel], cells: np.ndarray, rooms: list[str],
                 votes: RoomMap | None = None,
                 objects: Callable[[], list[MapObject]] | None = None) -> None:
        self._labels = labels
        self._rooms = rooms
        self._tree = cKDTree(cells) if len(cells) else None
        self._votes = votes
        self._objects = objects
        self._made: list[MapObject] | None = None

    @property
    def objects(self) -> list[MapObject]:
        """The frame's objects for the instance map (``MapObject``), made when first asked
        for (only count questions read the map)."""
        if self._made is None:
            self._made = self._objects() if self._objects is not None else []
        return self._made

    def label(self, instance_id: int) -> ObjectLabel | None:
        return self._labels.get(int(instance_id))

    def room_at(self, x: float, y: float) -> str | None:
        if self._votes is not None:
            return self._votes.room_at(x, y)
        if self._tree is None:
            return None
        distance, k = self._tree.query((x, y), distance_upper_bound=ROOM_REACH_M)
        return self._rooms[int(k)] if np.isfinite(distance) else None


def read_frame(classes: PixelClasses, depth_m: np.ndarray, intrinsics: np.ndarray,
               cam_to_world: np.ndarray, votes: RoomVotes | None = None,
               evidence: ObjectEvidence | None = None) -> tuple[np.ndarray, FrameLabels]:
    """The full-size instance buffer and the frame's labels from the network's classes.
    ``depth_m``, ``intrinsics`` and ``cam_to_world`` are the frame's own (full size). With
    ``votes`` (the episode's), the frame is added to them and rooms are named by their map;
    ``evidence``, the episode's objects fused over views, gains this frame's regions and keeps
    those that the views together are sure of."""
    h, w = depth_m.shape
    small = classes.category
    sh, sw = small.shape
    fy, fx = h // sh, w // sw
    if (sh * fy, sw * fx) != (h, w):
        raise ValueError(f"classes {small.shape} do not tile a {h}x{w} frame")
    depth_small = depth_m[fy // 2::fy, fx // 2::fx]
    names = list(classes.categories)
    is_floor = np.array([n.startswith(FLOOR_PREFIX) for n in names])
    first_object = names.index("door")
    floor_points = _floor_points(small, is_floor, depth_m, intrinsics, cam_to_world, fy, fx)
    cells, rooms = _floor_cells(*floor_points, names)

    instance_small = np.where(small == 0, -1, 0).astype(np.int32)
    instance_small[depth_small <= 0] = -1
    proposed = regions_of(small, depth_small, first_object, classes.confidence)
    points = backproject(depth_small, scaled_intrinsics(intrinsics, fy, fx), cam_to_world)
    fused = fused_support(proposed, points, evidence)
    kept = [sure >= classes.min_confidence.get(names[category], MIN_CONFIDENCE)
            or together >= FUSED_MIN for (category, _, sure), together in zip(proposed, fused)]
    regions = merge_fragments([(category, mask) for (category, mask, _), keep
                               in zip(proposed, kept) if keep], points, door=first_object)
    room_map = None
    if votes is not None:
        seen = _seen(classes, names, depth_small, points, floor_points, regions)
        key = tuple(np.round(cam_to_world[:3] * 1000).astype(np.int64).ravel().tolist())
        room_map = votes.add(key, seen)
    room_of = FrameLabels({}, cells, rooms, room_map)
    camera_xy = np.array([cam_to_world[0, 3], cam_to_world[1, 3]])
    labels: dict[int, ObjectLabel] = {}
    for k, (category, mask) in enumerate(regions, start=1):
        instance_small[mask] = k
        xy = np.median(points[mask][:, :2], axis=0)
        colour = _majority(classes.colour[mask], len(classes.colours))
        state = _majority(classes.state[mask], len(classes.states) + 1)
        name = names[category]
        door = None
        if name == "door":
            door = _door_sides(xy, camera_xy, room_of)
            room = door.rooms[0]
        else:
            room = room_of.room_at(float(xy[0]), float(xy[1]))
        labels[k] = ObjectLabel(name, classes.colours[colour] if colour is not None else None,
                                classes.states[state - 1] if state else None, room, door)
    instance = np.repeat(np.repeat(instance_small, fy, axis=0), fx, axis=1)
    instance[depth_m <= 0] = -1
    def objects() -> list[MapObject]:
        return map_objects(classes, [(c, m, sure) for (c, m, sure) in proposed
                                     if sure >= UNSURE_MIN], points, instance_small, room_of,
                           fy * fx, first_object)

    return instance, FrameLabels(labels, cells, rooms, room_map, objects)


@dataclass(frozen=True)
class MapObject:
    """One object of a frame as the instance map takes it (``mapping.instances.Region``):
    its category, world points (at half size, within MAP_DEPTH_M of the region's median depth
    from the camera), confidence (the mean probability of its category over its pixels, times
    its size up to FULL_PIXELS), colour, room (at its place, as the frame's labels name rooms),
    whether the frame's edge cuts it, and the instance id the frame's description gives it
    (None where the description leaves it out as too unsure)."""

    category: str
    points: np.ndarray = field(repr=False, compare=False)
    confidence: float
    colour: str | None
    room: str | None
    cut: bool
    described: int | None


def map_objects(classes: PixelClasses, proposed: Sequence[tuple[int, np.ndarray, float]],
                points: np.ndarray, described: np.ndarray, rooms: FrameLabels, scale: int,
                door: int) -> list[MapObject]:
    """The frame's regions for the instance map: every region from UNSURE_MIN, fragments
    joined as the description joins them (``merge_fragments``), each weighed by its size
    (regions under FULL_PIXELS at 640x480 are often not the object: on validation walks half
    the chair regions under 150 px lie on walls and floors, 42 of 49 over 600 px on chairs).
    ``described``: the description's instance buffer at half size; ``scale`` the frame's
    pixels per half-size pixel."""
    if not proposed:
        return []
    h, w = classes.category.shape
    full = FULL_PIXELS * h * w * scale / (640 * 480)
    names = list(classes.categories)
    out = []
    for category, mask in merge_fragments([(c, m) for c, m, _ in proposed], points, door):
        sure = (float(classes.confidence[mask].mean()) if classes.confidence is not None
                else 1.0)
        p = _near_part(points[mask])
        xy = np.median(p[:, :2], axis=0)
        colour = _majority(classes.colour[mask], len(classes.colours))
        ids = described[mask]
        ids = ids[ids > 0]
        own = int(np.bincount(ids).argmax()) if len(ids) * 2 >= int(mask.sum()) else None
        rows, cols = np.nonzero(mask)
        out.append(MapObject(
            names[category], p, sure * min(1.0, int(mask.sum()) * scale / full),
            classes.colours[colour] if colour is not None else None,
            rooms.room_at(float(xy[0]), float(xy[1])),
            bool(cols.min() == 0 or cols.max() == w - 1 or rows.min() == 0), own))
    return out


def _near_part(region: np.ndarray) -> np.ndarray:
    """A region's world points within MAP_DEPTH_M (or twice their median distance) of their
    median point: its rim's pixels that took the wall behind it are left out."""
    centre = np.median(region, axis=0)
    d = np.linalg.norm(region - centre, axis=1)
    kept = region[d <= max(MAP_DEPTH_M, float(np.median(d)) * 2)]
    return kept if len(kept) else region


def _seen(classes: PixelClasses, names: list[str], depth: np.ndarray, points: np.ndarray,
          floor: tuple[np.ndarray, np.ndarray], regions: list[tuple[int, np.ndarray]]) -> Seen:
    """What the frame adds to the room votes (``rooms.Seen``), at half size."""
    is_floor = np.array([n.startswith(FLOOR_PREFIX) for n in names])
    floor_index = np.where(is_floor, np.cumsum(is_floor) - 1, -1)  # category -> floor type
    valid = depth > 0
    z = points[..., 2]
    wall = valid & (classes.category == names.index("wall")) & (z > WALL_BAND_M[0]) & (
        z < WALL_BAND_M[1])
    door = valid & (classes.category == names.index("door")) & (z < WALL_BAND_M[1])
    objects = []
    for category, mask in regions:
        sure = (float(classes.confidence[mask].mean()) if classes.confidence is not None
                else 1.0)
        if names[category] != "door" and sure >= OBJECT_CONFIDENCE:
            xy = np.median(points[mask][:, :2], axis=0)
            objects.append((names[category], (float(xy[0]), float(xy[1]))))
    return Seen(floor[0], floor_index[floor[1]], points[wall][:, :2], points[door][:, :2], objects)


def floor_types(categories: Sequence[str]) -> list[str]:
    """The room types of the network's floor classes, in its order."""
    return [n[len(FLOOR_PREFIX):] for n in categories if n.startswith(FLOOR_PREFIX)]


def scaled_intrinsics(intrinsics: np.ndarray, fy: int, fx: int) -> np.ndarray:
    k = intrinsics.astype(np.float64).copy()
    k[0] /= fx
    k[1] /= fy
    return k


def _floor_points(small: np.ndarray, is_floor: np.ndarray, depth_m: np.ndarray,
                  intrinsics: np.ndarray, cam_to_world: np.ndarray, fy: int, fx: int
                  ) -> tuple[np.ndarray, np.ndarray]:
    """World xy and category of each predicted floor pixel at floor height (half size)."""
    depth_small = depth_m[fy // 2::fy, fx // 2::fx]
    points = backproject(depth_small, scaled_intrinsics(intrinsics, fy, fx), cam_to_world)
    floor = is_floor[small] & (depth_small > 0) & (np.abs(points[..., 2]) < FLOOR_TOLERANCE_M)
    return points[floor][:, :2], small[floor]


def _floor_cells(xy: np.ndarray, category: np.ndarray, names: list[str]
                 ) -> tuple[np.ndarray, list[str]]:
    """One room per ROOM_CELL_M cell of predicted floor: its pixels' majority room type."""
    if not len(xy):
        return np.zeros((0, 2)), []
    cells = np.floor(xy / ROOM_CELL_M).astype(np.int64)
    key = (cells[:, 0] << 32) + (cells[:, 1] & 0xFFFFFFFF)
    order = np.lexsort((category, key))
    key, category, cells = key[order], category[order], cells[order]
    pairs, starts, counts = np.unique(np.stack([key, category], 1), axis=0, return_index=True,
                                      return_counts=True)
    best: dict[int, tuple[int, int, int]] = {}  # cell key -> (count, category, row)
    for (cell, cat), start, n in zip(pairs.tolist(), starts.tolist(), counts.tolist()):
        if cell not in best or n > best[cell][0]:
            best[cell] = (n, cat, start)
    rows = [row for _, _, row in best.values()]
    centres = (cells[rows] + 0.5) * ROOM_CELL_M
    return centres, [names[cat][len(FLOOR_PREFIX):] for _, cat, _ in best.values()]


def regions_of(small: np.ndarray, depth: np.ndarray, first_object: int,
               confidence: np.ndarray | None = None) -> list[tuple[int, np.ndarray, float]]:
    """Connected regions of each object category (doors included), cut at depth jumps, of at
    least MIN_REGION_PIXELS; each as (category, mask at half size, confidence), largest first
    within a category. The confidence is the mean probability over the region (1.0 without
    ``confidence``)."""
    jump = np.zeros(small.shape, bool)
    rel = DEPTH_JUMP * np.maximum(depth, 1e-3)
    jump[:, 1:] |= np.abs(np.diff(depth, axis=1)) > rel[:, 1:]
    jump[1:, :] |= np.abs(np.diff(depth, axis=0)) > rel[1:, :]
    out: list[tuple[int, np.ndarray, float]] = []
    for category in np.unique(small[small >= first_object]).tolist():
        mask = (small == category) & (depth > 0)
        cores, n = ndimage.label(mask & ~jump)
        if n == 0:
            continue
        # pixels on a jump join the region nearest to them (within the category's mask)
        _, (ri, ci) = ndimage.distance_transform_edt(cores == 0, return_indices=True)
        grown = np.where(mask, cores[ri, ci], 0)
        sizes = np.bincount(grown.ravel(), minlength=n + 1)
        for k in np.argsort(-sizes[1:], kind="stable") + 1:
            if sizes[k] >= MIN_REGION_PIXELS:
                region = grown == k
                sure = 1.0 if confidence is None else float(confidence[region].mean())
                out.append((int(category), region, sure))
    return out


def merge_fragments(regions: Sequence[tuple[int, np.ndarray]], points: np.ndarray,
                    door: int) -> list[tuple[int, np.ndarray]]:
    """Regions of one category whose centres (median world xy) lie within FRAGMENT_MERGE_M
    are one object: a chair's back, seat and legs, cut apart where depth jumps between them,
    counted one chair (doors are never merged: two leaves of a double door are two doors)."""
    if FRAGMENT_MERGE_M <= 0:
        return list(regions)
    centres = [np.median(points[mask][:, :2], axis=0) for _, mask in regions]
    parent = list(range(len(regions)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(len(regions)):
        for j in range(i + 1, len(regions)):
            if (regions[i][0] == regions[j][0] and regions[i][0] != door
                    and float(np.hypot(*(centres[i] - centres[j]))) < FRAGMENT_MERGE_M):
                parent[root(j)] = root(i)
    merged: dict[int, tuple[int, np.ndarray]] = {}
    for i, (category, mask) in enumerate(regions):
        r = root(i)
        merged[r] = (category, mask | merged[r][1]) if r in merged else (category, mask.copy())
    return [merged[r] for r in sorted(merged)]


def fused_support(regions: Sequence[tuple[int, np.ndarray, float]], points: np.ndarray,
                  evidence: ObjectEvidence | None) -> list[float]:
    """Add the regions (category, mask, confidence) of one view, with the frame's world
    ``points`` at the masks' size, to ``evidence``; then each region's fused evidence (0 for
    every region without ``evidence``)."""
    if evidence is None:
        return [0.0] * len(regions)
    keys = [cell_keys(points[mask], category) for category, mask, _ in regions]
    evidence.add_view([(k, sure) for k, (_, _, sure) in zip(keys, regions)])
    return [evidence.support(k) for k in keys]


def _majority(values: np.ndarray, n: int) -> int | None:
    """The commonest value of a region's pixels (None for an empty region)."""
    if not values.size:
        return None
    return int(np.bincount(values.ravel().astype(np.int64), minlength=n).argmax())


def _door_sides(xy: np.ndarray, camera_xy: np.ndarray, rooms: FrameLabels) -> DoorSides:
    """A door's sides as the frame shows them: the room of the floor between the camera and the
    door (rooms[0]), and of the floor beyond it; the wall line faces the camera."""
    toward = camera_xy - xy
    norm = float(np.hypot(*toward))
    normal = toward / norm if norm > 1e-6 else np.array([1.0, 0.0])
    near = rooms.room_at(*(xy + 0.5 * normal))
    beyond = (rooms.room_at(*(xy - t * normal)) for t in DOOR_BEYOND_M)
    far = next((r for r in beyond if r is not None and r != near), None)
    return DoorSides((near, far), float(xy[0]), float(xy[1]), (float(normal[0]),
                                                                float(normal[1])))
