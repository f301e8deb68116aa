"""Semantic-sensor perception (DESIGN 5): the instance buffer of a frame as short factual text.

No image model's weights can be installed here, so the offline default lets a text-only language
model read what a frame shows instead of its pixels: the visible objects (category, colour,
state, bearing, distance), the room the robot stands in and the rooms seen through doorways, and
what lies towards each lettered prompt point. Everything is deterministic for a given frame.

The text says only what a camera at that pose shows. A room is "in view" when enough of its
floor is (structure pixels at floor height, named by the scene's floor plan). The robot's room
is named when its floor or its furniture is in view; any other room, the room of an object or of
a lettered point, and the rooms a door joins only when that room's floor is in view (for a
point: near the point). A closed door names at most the room on the camera's side of it.

Bearings come from the pixel column of an object's centroid (degrees, positive = left of the
optical axis); distances are the median depth of its pixels (metres along the optical axis).

The frame text lists the visible objects near to far, each with what it stands on when the frame
shows that ("a white desk lamp (on) on the brown nightstand, slightly left, 1.2 m"; the support's
own entry says it the other way round, "..., with a white desk lamp on it", which a small model
finds next to the furniture a question names), and counts
identical objects (same category, colour, state, support and place) as one entry ("four black
chairs on the left to ahead, 1.4-2.2 m"), so that questions such as "What is on the nightstand?"
or "How many chairs are in the dining room?" can be answered from the words. The support relation
is as honest as the rest: it is read off the frame alone, never off the scene's own records. Each
object's pixels are back-projected to 3D (depth, intrinsics, pose); A stands on B when both are
visible, A's lowest points lie within SUPPORT_GAP_M of B's highest points (or of a shelf or
worktop below B's top: SURFACE_SHARE of B's points at that height), A's median horizontal
position lies within B's visible horizontal extent and A is no wider than B (both with
SUPPORT_MARGIN_M to spare); of several such B, the one whose top is closest to A's bottom. A is
"in" B ("a coffee maker in the white bookshelf", "..., with a grey coffee maker in it") when
it lies wholly within B's height, its median inside B's extent, and B has INSIDE_SHARE times
its pixels: on a shelf whose board A hides (then no "on" B was found). Doors and objects whose
lowest points are near the floor stand on nothing, and a support hidden from the camera is
never named. The answerability gate reads this same relation (``VisibleObject.support_id``),
never one of its own: what it passes is what the model is told (with a VLM over images the
relation is the VLM's own sentence, judged by ``stop.gate``'s model gate). Tuned on the oracle
frames of training houses 0-20: every "What is on ...?" item (28/28) is said to stand on its
surface; 1 of 101 stated relations is wrong. On 1008 frames of random poses of the same houses
(``experiments/relation_bench.py``, objects listed from 60 px), 4 of 339 stated relations are
wrong (2 "on", 2 "in"), all of items over 400 px; at 150-250 px 37 right, none wrong.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from efficienteqa.envs.base import ObjectLabel, SceneLabels
from efficienteqa.geometry import backproject
from efficienteqa.mapping.instances import FrameInstances, InstanceMap, Region
from efficienteqa.perception.base import ExploreRequest, Modality, Sighting, Sightings
from efficienteqa.question import Target

if TYPE_CHECKING:
    from efficienteqa.observation import Observation, PromptPoint

REFERENCE_AREA_PX = 640 * 480
REFERENCE_MIN_PIXELS = 150  # at 640x480; scaled with image area
MAX_OBJECTS = 12
AHEAD_DEG = 10.0  # |bearing| up to this is "ahead"
SLIGHTLY_DEG = 30.0  # then "slightly left/right" up to this, "on the left/right" beyond
FLOOR_TOLERANCE_M = 0.05  # structure pixels this close to z = 0 are floor
ROOM_CELL_M = 0.1  # floor points are grouped on this grid before looking up their room
WINDOW_FRACTION = 0.05  # half-width of the pixel window around a prompt point, share of width
_NUMBER_WORDS = ("zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine")
_DISPLAY = {"tv": "TV", "tv stand": "TV stand"}
_CELL_OFFSET = 1 << 20  # keeps cell indices non-negative for the 1-D cell key
SUPPORT_GAP_M = 0.08  # A's bottom within this of B's top: A stands on B
SUPPORT_MARGIN_M = 0.1  # A's centre may lie this far outside B's visible horizontal extent
SURFACE_SHARE = 0.1  # or when this share of B's points lies at A's bottom (a shelf, a worktop)
INSIDE_SHARE = 4  # A is "in" B (within B's height and extent) when B has this many times its pixels
ON_FLOOR_M = 0.1  # an object whose bottom is this low stands on the floor
_LOW_PCT, _HIGH_PCT = 2.0, 98.0  # robust "lowest" and "highest" of an object's visible points
SIGHTING_STRIDE = 4  # floor and object points of a sighting: every 4th pixel each way
GLIMPSE_PIXELS = 20  # at 640x480: an object of the target this large is a sighting
STRIDE_WIDTH = 320  # the support test reads every (width // this)-th pixel each way: fewer
# points on large frames (a quarter at 640x480), all of them on small ones


@dataclass(frozen=True)
class NoiseConfig:
    """A crude detector-noise model for robustness studies: each listed object is dropped with
    probability ``miss_rate`` and otherwise gets a wrong palette colour with probability
    ``wrong_colour_rate``. Draws are seeded by (seed, robot pose, instance id), so a frame is
    always described the same way."""

    miss_rate: float = 0.0
    wrong_colour_rate: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("miss_rate", "wrong_colour_rate"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")


@dataclass(frozen=True)
class VisibleObject:
    """One object in a frame: its label, pixel count, centroid (u, v) in pixels, bearing in
    degrees (positive = left), the bearing in words and the median depth in metres."""

    instance_id: int
    label: ObjectLabel
    pixels: int
    centroid_px: tuple[float, float]
    bearing_deg: float
    bearing: str
    distance_m: float
    where: str | None = None  # "in the hallway", "between the kitchen and the hallway": only
    # what the frame shows (set by describe_frame)
    on: str | None = None  # what it stands on as the frame shows it, "the brown nightstand"
    carries: str | None = None  # what stands on it, "a beige desk lamp" (the converse of on)
    holds: str | None = None  # what stands in it, "a grey coffee maker" (the converse of "in")
    relation: str = "on"  # how it stands on ``on``: "on" it, or "in" it (``Support``)
    support_id: int | None = None  # the instance id of ``on`` in this frame

    def phrase(self, robot_room: str | None = None) -> str:
        """E.g. "a lamp (on) on the left, 3.4 m, in the hallway" or "a white cup on the brown
        table, ahead, 1.2 m"; the place is left out when it is the robot's own room."""
        return _entry_phrase([self], robot_room)


@dataclass(frozen=True)
class FrameDescription:
    """A frame in words (``text``) and as structure (near-to-far ``objects``). ``room`` is the
    robot's room when the frame shows it (None otherwise); ``rooms_in_view`` every room whose
    floor is in view, nearest first."""

    text: str
    room: str | None
    objects: tuple[VisibleObject, ...]
    rooms_through_doorways: tuple[str, ...]
    rooms_in_view: tuple[str, ...] = ()


@dataclass(frozen=True)
class FloorView:
    """The floor a frame shows: ``rooms`` (names), ``room_index`` (H, W) the index in ``rooms``
    of each floor pixel's room (-1: not floor, or floor of no room) and ``depth_m`` the median
    depth of each room's floor pixels."""

    rooms: tuple[str, ...]
    room_index: np.ndarray
    depth_m: tuple[float, ...]

    def pixels(self, mask: np.ndarray | None = None) -> dict[str, int]:
        """Floor pixels per room (within ``mask`` when given)."""
        index = self.room_index if mask is None else self.room_index[mask]
        counts = np.bincount(index[index >= 0].ravel(), minlength=len(self.rooms))
        return {name: int(n) for name, n in zip(self.rooms, counts)}

    def in_view(self, min_pixels: int, mask: np.ndarray | None = None) -> tuple[str, ...]:
        """Rooms with at least ``min_pixels`` floor pixels (within ``mask``), nearest first."""
        counts = self.pixels(mask)
        near_first = sorted(zip(self.depth_m, self.rooms))
        return tuple(name for _, name in near_first if counts[name] >= min_pixels)


def scaled_min_pixels(height: int, width: int) -> int:
    """REFERENCE_MIN_PIXELS at 640x480, proportional to image area, at least 1."""
    return max(1, round(REFERENCE_MIN_PIXELS * height * width / REFERENCE_AREA_PX))


def bearing_words(bearing_deg: float) -> str:
    side = "left" if bearing_deg > 0 else "right"
    if abs(bearing_deg) <= AHEAD_DEG:
        return "ahead"
    if abs(bearing_deg) <= SLIGHTLY_DEG:
        return f"slightly {side}"
    return f"on the {side}"


def visible_objects(obs: Observation, labels: SceneLabels, min_pixels: int | None = None,
                    noise: NoiseConfig | None = None) -> list[VisibleObject]:
    """Labelled objects with at least ``min_pixels`` pixels (default: scaled with image area)
    and valid depth, near to far (ties by instance id), after the optional noise model."""
    if obs.instance is None:
        raise ValueError("semantic perception needs an instance buffer (Observation.instance)")
    h, w = obs.depth_m.shape
    threshold = scaled_min_pixels(h, w) if min_pixels is None else min_pixels
    valid = (obs.instance > 0) & (obs.depth_m > 0)
    ids = obs.instance[valid]
    rows, cols = np.nonzero(valid)
    depths = obs.depth_m[valid]
    order = np.argsort(ids, kind="stable")
    ids, rows, cols, depths = ids[order], rows[order], cols[order], depths[order]
    unique, starts, counts = np.unique(ids, return_index=True, return_counts=True)
    fx, cx = float(obs.intrinsics[0, 0]), float(obs.intrinsics[0, 2])
    found = []
    for inst, s, n in zip(unique.tolist(), starts.tolist(), counts.tolist()):
        label = labels.label(inst)
        if n < threshold or label is None:
            continue
        u = float(cols[s:s + n].mean()) + 0.5
        v = float(rows[s:s + n].mean()) + 0.5
        bearing = -math.degrees(math.atan((u - cx) / fx))
        distance = round(float(np.median(depths[s:s + n])), 1)
        found.append(VisibleObject(inst, label, n, (u, v), bearing, bearing_words(bearing),
                                   distance))
    found.sort(key=lambda o: (o.distance_m, o.instance_id))
    return _apply_noise(found, noise, obs) if noise is not None else found


def describe_frame(obs: Observation, labels: SceneLabels, min_pixels: int | None = None,
                   max_objects: int = MAX_OBJECTS, noise: NoiseConfig | None = None
                   ) -> FrameDescription:
    """The frame as a compact paragraph, e.g. "You are in the kitchen. Visible: a grey
    refrigerator ahead, 2.1 m; a white cup on the grey table, slightly left, 1.2 m; two brown
    chairs slightly left to ahead, 1.4-1.6 m; a lamp (on) on the left, 3.4 m. Through a doorway:
    the hallway." At most ``max_objects`` entries (a group of identical objects is one), the
    nearest; ``objects`` holds the individual objects of those entries."""
    seen = visible_objects(obs, labels, min_pixels, noise)
    h, w = obs.depth_m.shape
    threshold = scaled_min_pixels(h, w) if min_pixels is None else min_pixels
    points = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)
    in_view = floor_view(obs, labels, points).in_view(threshold)
    here = labels.room_at(obs.pose.x, obs.pose.y)
    furnished = any(o.label.door is None and o.label.room == here for o in seen)
    room = here if here is not None and (here in in_view or furnished) else None
    camera_xy = (float(obs.cam_to_world[0, 3]), float(obs.cam_to_world[1, 3]))
    supports = _supports(obs, points, seen)
    # support id -> relation -> what stands on or in it, near to far
    loads: dict[int, dict[str, list[ObjectLabel]]] = {}
    for o in seen:
        if o.instance_id in supports:
            below = supports[o.instance_id]
            loads.setdefault(below.thing.instance_id, {}).setdefault(below.relation,
                                                                     []).append(o.label)
    groups: dict[tuple[object, ...], list[VisibleObject]] = {}
    for o in seen:  # near to far, so groups are in order of their nearest member
        s = supports.get(o.instance_id)
        carried = loads.get(o.instance_id, {})
        o = replace(o, where=_where(o.label, set(in_view), room, camera_xy),
                    on=_support_name(s.thing.label) if s else None,
                    relation=s.relation if s else "on",
                    support_id=s.thing.instance_id if s else None,
                    carries=_listed(carried.get("on")), holds=_listed(carried.get("in")))
        groups.setdefault((o.label.category, o.label.colour, o.label.state, o.where, o.on,
                           o.relation, o.carries, o.holds), []).append(o)
    entries = list(groups.values())[:max_objects]
    objects = tuple(o for group in entries for o in group)
    others = tuple(r for r in in_view if r != here)
    parts = [f"You are in the {room}." if room else "The room you are in is not in view."]
    if objects:
        parts.append("Visible: " + "; ".join(_entry_phrase(g, room) for g in entries) + ".")
    else:
        parts.append("Visible: nothing but walls and floor.")
    if others:
        lead = "Through a doorway" if len(others) == 1 else "Through doorways"
        parts.append(f"{lead}: " + ", ".join(f"the {r}" for r in others) + ".")
    return FrameDescription(" ".join(parts), room, objects, others, in_view)


def describe_directions(obs: Observation, prompts: Sequence[PromptPoint], labels: SceneLabels,
                        radius_m: float = 1.5, min_pixels: int | None = None,
                        max_groups: int = 6, noise: NoiseConfig | None = None) -> dict[str, str]:
    """For each lettered point, the room there, its distance from the robot and the objects seen
    near it, e.g. {"A": "towards the dining room, 4.2 m away; a brown table, two brown chairs."}

    A pixel is near a point when it back-projects within ``radius_m`` (on the floor plane) of the
    point, or lies in a small pixel window around the point's pixel. An object is near when some
    of its pixels are; the point's room is named only when enough of that room's floor is near,
    and so is every other room whose floor is near ("floor of the hallway in view"). An open
    door near the point says where it leads ("an open door to the hallway") when that room's
    floor is in the frame; a closed door says nothing of what lies behind it.
    """
    objects = visible_objects(obs, labels, min_pixels, noise)
    floor = floor_view(obs, labels)
    h, w = obs.depth_m.shape
    threshold = scaled_min_pixels(h, w) if min_pixels is None else min_pixels
    xy = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[..., :2]
    rows, cols = np.mgrid[0:h, 0:w]
    half = max(2.0, WINDOW_FRACTION * w)
    min_near = max(1, scaled_min_pixels(h, w) // 5)
    robot_room = labels.room_at(obs.pose.x, obs.pose.y)
    frame_rooms = floor.in_view(threshold)
    camera_xy = (float(obs.cam_to_world[0, 3]), float(obs.cam_to_world[1, 3]))
    out = {}
    for p in prompts:
        px, py = float(p.xy[0]), float(p.xy[1])
        planar = np.hypot(xy[..., 0] - px, xy[..., 1] - py)
        near = (planar <= radius_m) | ((np.abs(cols + 0.5 - p.pixel[0]) <= half)
                                       & (np.abs(rows + 0.5 - p.pixel[1]) <= half))
        near &= obs.depth_m > 0
        hits = []
        for o in objects:
            mask = near & (obs.instance == o.instance_id)
            if int(mask.sum()) >= min(min_near, o.pixels):
                hits.append((float(np.median(planar[mask])), o.instance_id, o.label))
        hits.sort(key=lambda t: (t[0], t[1]))
        here = floor.in_view(threshold, near)  # rooms whose floor this part shows, near first
        room = labels.room_at(px, py)
        if room not in here:
            room = None  # that room's floor is not in view there
        where = "" if room is None else (f"in the {room}, " if room == robot_room
                                         else f"towards the {room}, ")
        others = [r for r in here if r != room]
        if others:
            where += "floor of " + _and_list([f"the {r}" for r in others]) + " in view, "
        distance = math.hypot(px - obs.pose.x, py - obs.pose.y)
        seen = _group_phrases([label for _, _, label in hits], max_groups)
        leads = _open_door_leads([label for _, _, label in hits], set(frame_rooms), camera_xy)
        out[p.letter] = (f"{where}{distance:.1f} m away; "
                         + (", ".join(seen) if seen else "no objects seen there")
                         + "".join(f"; an open door to the {r}" for r in leads) + ".")
    return out


# -- helpers ---------------------------------------------------------------------------------
def floor_view(obs: Observation, labels: SceneLabels, points: np.ndarray | None = None
               ) -> FloorView:
    """The rooms whose floor the frame shows: structure pixels (instance 0) at floor height,
    each named by ``labels.room_at`` at the centre of its ROOM_CELL_M cell. ``points``: the
    frame's back-projection, when the caller has it."""
    h, w = obs.depth_m.shape
    if points is None:
        points = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)
    floor = (obs.depth_m > 0) & (np.abs(points[..., 2]) < FLOOR_TOLERANCE_M)
    if obs.instance is not None:
        floor &= obs.instance == 0
    index = np.full((h, w), -1, np.int64)
    if not floor.any():
        return FloorView((), index, ())
    cells = np.floor(points[floor][:, :2] / ROOM_CELL_M).astype(np.int64) + _CELL_OFFSET
    unique, inverse = np.unique(cells[:, 0] * (2 * _CELL_OFFSET) + cells[:, 1],
                                return_inverse=True)  # one int key per cell: a fast 1-D unique
    i, j = np.divmod(unique, 2 * _CELL_OFFSET)
    names = [labels.room_at((a - _CELL_OFFSET + 0.5) * ROOM_CELL_M,
                            (b - _CELL_OFFSET + 0.5) * ROOM_CELL_M) for a, b in zip(i, j)]
    rooms = tuple(sorted({n for n in names if n is not None}))
    code = {name: k for k, name in enumerate(rooms)}
    per_cell = np.array([code[n] if n is not None else -1 for n in names], np.int64)
    index[floor] = per_cell[inverse.ravel()]
    depth = obs.depth_m[floor]
    medians = tuple(float(np.median(depth[index[floor] == k])) for k in range(len(rooms)))
    return FloorView(rooms, index, medians)


def _where(label: ObjectLabel, in_view: set[str], robot_room: str | None,
           camera_xy: tuple[float, float]) -> str | None:
    """Where an object is, in words the frame supports: a door by the rooms it joins whose floor
    is in view (a closed door only by the room on the camera's side), anything else by its room
    when that room's floor is in view or it is the robot's room the frame shows."""
    sides = label.door
    if sides is not None:
        if label.state == "open":
            rooms = [r for r in sides.rooms if r is not None and r in in_view]
        else:
            near = sides.side(*camera_xy)
            rooms = [near] if near is not None and near in in_view else []
        if len(rooms) == 2:
            return f"between the {rooms[0]} and the {rooms[1]}"
        return f"in a wall of the {rooms[0]}" if rooms else None
    room = label.room
    if room is not None and (room in in_view or room == robot_room):
        return f"in the {room}"
    return None


@dataclass(frozen=True)
class Support:
    """What an object stands on (``thing``) and how: "on" its top, a shelf or a worktop seen at
    the object's bottom, or "in" it (within its height and horizontal extent, on a shelf the
    object hides)."""

    thing: VisibleObject
    relation: str


def _supports(obs: Observation, points: np.ndarray, objects: list[VisibleObject]
              ) -> dict[int, Support]:
    """What each object stands on, as the frame shows it: instance id -> the visible support.
    Only the back-projected pixels of the visible objects are read (see the module docstring)."""
    if obs.instance is None or len(objects) < 2:
        return {}
    k = max(1, obs.depth_m.shape[1] // STRIDE_WIDTH)
    instance, depth, points = obs.instance[::k, ::k], obs.depth_m[::k, ::k], points[::k, ::k]
    valid = (depth > 0) & np.isin(instance, [o.instance_id for o in objects])
    ids, xyz = instance[valid], points[valid]
    order = np.argsort(ids, kind="stable")
    unique, starts = np.unique(ids[order], return_index=True)
    slices = dict(zip(unique.tolist(), np.split(xyz[order], starts[1:])))
    stats = {}  # id -> (z, bottom, top, median xy, min xy, max xy) of its visible points
    objects = [o for o in objects if o.instance_id in slices]  # a sliver may miss the stride
    for o in objects:
        p = slices[o.instance_id]
        bottom, top = np.percentile(p[:, 2], (_LOW_PCT, _HIGH_PCT))
        stats[o.instance_id] = (p[:, 2], float(bottom), float(top), np.median(p[:, :2], axis=0),
                                p[:, :2].min(axis=0), p[:, :2].max(axis=0))
    out: dict[int, Support] = {}
    for a in objects:
        _, bottom, a_top, centre, a_lo, a_hi = stats[a.instance_id]
        if a.label.door is not None or bottom < ON_FLOOR_M:
            continue
        best: tuple[float, VisibleObject, str] | None = None
        for b in objects:
            bz, _, top, _, lo, hi = stats[b.instance_id]
            if (b is a or b.label.door is not None or top < bottom - SUPPORT_GAP_M
                    or np.any(centre < lo - SUPPORT_MARGIN_M) or np.any(centre > hi + SUPPORT_MARGIN_M)
                    or np.any(a_hi - a_lo > hi - lo + 2 * SUPPORT_MARGIN_M)):
                continue  # B is too low, A's centre is not over B, or A is wider than B
            gap, relation = abs(bottom - top), "on"
            if gap > SUPPORT_GAP_M:  # or a shelf or worktop of B below its top, at A's bottom
                if np.mean(np.abs(bz - bottom) <= SUPPORT_GAP_M / 2) >= SURFACE_SHARE:
                    gap = SUPPORT_GAP_M
                elif (float(bz.min()) <= bottom and a_top <= top + SUPPORT_GAP_M
                      and a.pixels * INSIDE_SHARE <= b.pixels
                      and np.all(centre >= lo) and np.all(centre <= hi)):
                    gap, relation = 2 * SUPPORT_GAP_M, "in"  # within B's height: on a shelf
                    # whose board the item hides (a coffee maker in a bookshelf)
                else:
                    continue
            if best is None or gap < best[0]:
                best = (gap, b, relation)
        if best is not None:
            out[a.instance_id] = Support(best[1], best[2])
    return out


def _support_name(label: ObjectLabel) -> str:
    """ "the brown nightstand": colour and category, without the state."""
    noun = _DISPLAY.get(label.category, label.category)
    return f"the {label.colour} {noun}" if label.colour else f"the {noun}"


def _entry_phrase(group: list[VisibleObject], robot_room: str | None) -> str:
    """One entry of the frame text: an object, or identical objects counted ("four black chairs
    on the left to ahead, 1.4-2.2 m"; bearings from leftmost to rightmost, distances near-far)."""
    first = group[0]
    text = _noun_phrase(first.label, len(group))
    if first.on:
        text += f" {first.relation} {first.on},"
    by_bearing = sorted(group, key=lambda o: -o.bearing_deg)
    left, right = by_bearing[0].bearing, by_bearing[-1].bearing
    text += f" {left}" if left == right else f" {left} to {right}"
    near, far = min(o.distance_m for o in group), max(o.distance_m for o in group)
    text += f", {near:.1f} m" if near == far else f", {near:.1f}-{far:.1f} m"
    if first.where and not (robot_room and first.where == f"in the {robot_room}"):
        text += f", {first.where}"
    pronoun = "it" if len(group) == 1 else "them"
    loads = [f"{things} {relation} {pronoun}" for things, relation
             in ((first.carries, "on"), (first.holds, "in")) if things]
    if loads:  # "with a lamp on it", "with a book on it and a vase in it"
        text += ", with " + " and ".join(loads)
    return text


def _listed(labels: list[ObjectLabel] | None) -> str | None:
    """ "a lamp and two cups", or None for no labels."""
    return _and_list(_group_phrases(labels, len(labels))) if labels else None


def _and_list(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _open_door_leads(labels: list[ObjectLabel], in_view: set[str],
                     camera_xy: tuple[float, float]) -> list[str]:
    """Where the open doors among ``labels`` lead: the room beyond each (the side away from the
    camera), when that room's floor is in the frame; a closed door leads nowhere in view."""
    leads: list[str] = []
    for label in labels:
        sides = label.door
        if sides is None or label.state != "open":
            continue
        near = sides.side(*camera_xy)
        beyond = [r for r in sides.rooms if r is not None and r != near and r in in_view]
        leads += [r for r in beyond if r not in leads]
    return leads


def _apply_noise(objects: list[VisibleObject], noise: NoiseConfig, obs: Observation
                 ) -> list[VisibleObject]:
    from efficienteqa.envs.synthetic.colours import PALETTE

    frame_key = zlib.crc32(f"{obs.pose.x:.3f},{obs.pose.y:.3f},{obs.pose.yaw:.3f}".encode())
    out = []
    for o in objects:
        rng = np.random.default_rng([noise.seed, frame_key, o.instance_id])
        missed, recolour = rng.random() < noise.miss_rate, rng.random() < noise.wrong_colour_rate
        if missed:
            continue
        if recolour:
            choices = sorted(c for c in PALETTE if c != o.label.colour)
            colour = choices[int(rng.integers(len(choices)))]
            o = replace(o, label=replace(o.label, colour=colour))
        out.append(o)
    return out


def _noun_phrase(label: ObjectLabel, count: int) -> str:
    noun = _DISPLAY.get(label.category, label.category)
    words = ([label.colour] if label.colour else []) + [noun if count == 1 else _plural(noun)]
    text = " ".join(words)
    if count == 1:
        text = ("an " if text[0].lower() in "aeiou" else "a ") + text
    else:
        text = f"{_NUMBER_WORDS[count] if count < len(_NUMBER_WORDS) else count} {text}"
    return f"{text} ({label.state})" if label.state else text


def _plural(noun: str) -> str:
    if noun.endswith("shelf"):
        return noun[:-1] + "ves"
    if noun.endswith(("s", "sh", "ch", "x")):
        return noun + "es"
    if noun.endswith("y") and noun[-2:-1] not in tuple("aeiou"):
        return noun[:-1] + "ies"
    return noun + "s"


def _group_phrases(labels: list[ObjectLabel], max_groups: int) -> list[str]:
    """Identical labels (category, colour, state) counted together, in order of first sight."""
    counts: dict[tuple[str, str | None, str | None], int] = {}
    first: dict[tuple[str, str | None, str | None], ObjectLabel] = {}
    for label in labels:
        key = (label.category, label.colour, label.state)
        counts[key] = counts.get(key, 0) + 1
        first.setdefault(key, label)
    return [_noun_phrase(first[k], n) for k, n in list(counts.items())[:max_groups]]


class SemanticPerception:
    """Semantic-sensor perception as a ``Perception`` back-end: frames and lettered directions
    as text from the scene's labels (no pixels are read)."""

    name = "semantic-sensor"
    modality: Modality = "text"

    def __init__(self, labels: SceneLabels, noise: NoiseConfig | None = None) -> None:
        self.labels, self.noise = labels, noise
        self._last: tuple[Observation, FrameDescription] | None = None
        self._seen: tuple[Observation, Target, Sightings] | None = None
        self.instances = InstanceMap()  # the episode's objects (``instances_seen``)
        self._added: tuple[Observation, FrameInstances] | None = None

    def reset(self) -> None:
        """A new episode: nothing carries over (the descriptions cached for the last frame go,
        the instance map starts empty)."""
        self._last = None
        self._seen = None
        self.instances.reset()
        self._added = None

    def instances_seen(self, obs: Observation, target: Target | None = None) -> FrameInstances:
        """The frame's objects added to the episode's instance map (once per observation) and
        which instances they are (``mapping.instances``). The semantic sensor's object ids are
        instances already: one per id."""
        if self._added is None or self._added[0] is not obs:
            self._added = (obs, self.instances.add(self.regions(obs)))
        return self._added[1]

    def regions(self, obs: Observation) -> list[Region]:
        """The frame's objects as regions of the instance map, keyed by their ids."""
        seen, labels = self.read(obs)
        return object_regions(seen, labels, self.describe(obs), noise=self.noise)

    def read(self, obs: Observation) -> tuple[Observation, SceneLabels]:
        """The frame and labels the describer reads: the scene's own here. A perception that
        predicts them from pixels (``perception.pixels``) overrides this, and only this."""
        return obs, self.labels

    def describe(self, obs: Observation) -> FrameDescription:
        if self._last is None or self._last[0] is not obs:  # described once per observation
            self._last = (obs, describe_frame(*self.read(obs), noise=self.noise))
        return self._last[1]

    def frame(self, obs: Observation) -> str:
        return self.describe(obs).text

    def relevancy_text(self, obs: Observation) -> str:
        """One line per object in view, "a blue stool in the kitchen": the regions an image
        matcher would weigh, without the bearings and distances that only the planner needs."""
        d = self.describe(obs)
        lines = [f"{_noun_phrase(o.label, 1)} {o.where or ''}".strip() for o in d.objects]
        return "\n".join(lines) or (f"walls and floor in the {d.room}" if d.room else "walls and floor")

    def explore_request(self, obs: Observation, prompts: Sequence[PromptPoint]) -> ExploreRequest:
        seen, labels = self.read(obs)
        return ExploreRequest(self.frame(obs),
                              describe_directions(seen, prompts, labels, noise=self.noise))

    def sightings(self, obs: Observation, target: Target) -> Sightings:
        """The floor of each room in view and the target's things in view (see ``sightings``);
        computed once per observation and target (the explorer and the gate both read them)."""
        if self._seen is None or self._seen[0] is not obs or self._seen[1] != target:
            seen, labels = self.read(obs)
            self._seen = (obs, target, sightings(seen, labels, target, self.noise))
        return self._seen[2]


def object_regions(obs: Observation, labels: SceneLabels, described: FrameDescription,
                   confidence: dict[int, float] | None = None, keyed: bool = True,
                   noise: NoiseConfig | None = None) -> list[Region]:
    """The frame's objects of at least GLIMPSE_PIXELS (scaled), as the sightings take them, as
    regions of an instance map (``mapping.instances``): world points of every
    SIGHTING_STRIDE-th pixel each way, the room where the frame shows it (as the text says),
    its colour, what the text says it stands on (``described``), whether the frame cuts it,
    ``confidence`` per instance id (default 1) and, when ``keyed``, its id as the key."""
    if obs.instance is None:
        return []
    h, w = obs.depth_m.shape
    k = SIGHTING_STRIDE
    glimpse = max(1, round(GLIMPSE_PIXELS * h * w / REFERENCE_AREA_PX))
    found = visible_objects(obs, labels, glimpse, noise)
    if not found:
        return []
    intrinsics = obs.intrinsics.astype(np.float64).copy()
    intrinsics[:2] /= k
    points = backproject(obs.depth_m[k // 2::k, k // 2::k], intrinsics, obs.cam_to_world)
    small = obs.instance[k // 2::k, k // 2::k]
    valid = obs.depth_m[k // 2::k, k // 2::k] > 0
    boxes = ndimage.find_objects(np.where(obs.instance > 0, obs.instance, 0))
    rooms = set(described.rooms_in_view)
    camera_xy = (float(obs.cam_to_world[0, 3]), float(obs.cam_to_world[1, 3]))
    order = {o.instance_id: n for n, o in enumerate(found)}
    under = {o.instance_id: o.support_id for o in described.objects}
    out = []
    for o in found:
        mask = (small == o.instance_id) & valid
        if mask.any():
            p = points[mask]
        else:  # a sliver between the strided pixels: all of its own
            full = (obs.instance == o.instance_id) & (obs.depth_m > 0)
            p = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[full]
        box = boxes[o.instance_id - 1]
        cut = box is not None and (box[1].start == 0 or box[1].stop == w or box[0].start == 0)
        where = _where(o.label, rooms, described.room, camera_xy)
        support = under.get(o.instance_id)
        out.append(Region(o.label.category, p,
                          1.0 if confidence is None else confidence.get(o.instance_id, 1.0),
                          o.label.colour,
                          where[len("in the "):] if where and where.startswith("in the ") else None,
                          o.instance_id if keyed else None,
                          order.get(support) if support is not None else None, cut))
    return out


def sightings(obs: Observation, labels: SceneLabels, target: Target,
              noise: NoiseConfig | None = None) -> Sightings:
    """What the frame shows of the rooms (floor points per room, as ``floor_view`` names them),
    of the target's things (objects whose category the question names, from GLIMPSE_PIXELS
    scaled) and of the doors (where each is; no room through it: the floor beyond says):
    only what the frame shows, like the text."""
    h, w = obs.depth_m.shape
    k = SIGHTING_STRIDE
    points = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)
    view = floor_view(obs, labels, points)
    index = view.room_index[::k, ::k]
    xy = points[::k, ::k, :2]
    floor = {room: xy[index == n] for n, room in enumerate(view.rooms) if (index == n).any()}
    things: list[Sighting] = []
    doors: list[Sighting] = []
    wanted = target.things
    if obs.instance is not None:
        glimpse = max(1, round(GLIMPSE_PIXELS * h * w / REFERENCE_AREA_PX))
        rooms = set(view.in_view(scaled_min_pixels(h, w)))
        here = labels.room_at(obs.pose.x, obs.pose.y)
        camera_xy = (float(obs.cam_to_world[0, 3]), float(obs.cam_to_world[1, 3]))
        for o in visible_objects(obs, labels, glimpse, noise):
            door = o.label.category == "door"  # where it is only: the rooms it joins are
            # what the floor beyond shows, never the label's
            if not door and not any(target.is_a(t, o.label.category) for t in wanted):
                continue
            mask = (obs.instance == o.instance_id) & (obs.depth_m > 0)
            rows, cols = np.nonzero(mask)
            p = points[mask]
            cut = bool(cols.min() == 0 or cols.max() == w - 1 or rows.min() == 0)
            place = (float(np.median(p[:, 0])), float(np.median(p[:, 1])))
            top = float(np.percentile(p[:, 2], 98))
            if door:
                doors.append(Sighting("door", place, top, o.pixels, cut, None))
            if any(target.is_a(t, o.label.category) for t in wanted):
                where = _where(o.label, rooms, here, camera_xy)
                room = where[len("in the "):] if where and where.startswith("in the ") else None
                things.append(Sighting(o.label.category, place, top, o.pixels, cut, room))
    return Sightings(floor, tuple(things), tuple(doors))
