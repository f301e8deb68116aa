"""Semantic-sensor perception (DESIGN 5): the instance buffer of a frame as short factual text.

No image model's weights can be installed here, so the offline default lets a text-only language
model read what a frame shows instead of its pixels: the visible objects (category, colour,
state, bearing, distance), the room the robot stands in and the rooms seen through doorways, and
what lies towards each lettered prompt point. Everything is deterministic for a given frame.

The text says only what a camera at that pose shows: the objects as ``perception.visible`` reads
them, the rooms whose floor is in view (``perception.floor``), what each object stands on as
the frame shows it (``perception.supports``). This module puts them into words, and holds the
``Perception`` back-end (``SemanticPerception``), which adds the world points of
``perception.regions``.

The frame text lists the visible objects near to far, each with what it stands on when the frame
shows that ("a white desk lamp (on) on the brown nightstand, slightly left, 1.2 m"; the support's
own entry says it the other way round, "..., with a white desk lamp on it", which a small model
finds next to the furniture a question names), and counts
identical objects (same category, colour, state, support and place) as one entry ("four black
chairs on the left to ahead, 1.4-2.2 m"), so that questions such as "What is on the nightstand?"
or "How many chairs are in the dining room?" can be answered from the words.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from efficienteqa.envs.base import ObjectLabel, SceneLabels
from efficienteqa.geometry import backproject
from efficienteqa.mapping.instances import FrameInstances, InstanceMap, Region
from efficienteqa.perception.base import ExploreRequest, Modality, Sightings
from efficienteqa.perception.floor import floor_view, open_door_leads, where_words
from efficienteqa.perception.regions import object_regions, sightings
from efficienteqa.perception.supports import find_supports
from efficienteqa.perception.visible import (
    FrameDescription,
    NoiseConfig,
    VisibleObject,
    and_list,
    entry_phrase,
    group_phrases,
    listed,
    noun_phrase,
    scaled_min_pixels,
    support_name,
    visible_objects,
)
from efficienteqa.question import Target

if TYPE_CHECKING:
    from efficienteqa.observation import Observation, PromptPoint

MAX_OBJECTS = 12
WINDOW_FRACTION = 0.05  # half-width of the pixel window around a prompt point, share of width


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
    supports = find_supports(obs, points, seen)
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
        o = replace(o, where=where_words(o.label, set(in_view), room, camera_xy),
                    on=support_name(s.thing.label) if s else None,
                    relation=s.relation if s else "on",
                    support_id=s.thing.instance_id if s else None,
                    carries=listed(carried.get("on")), holds=listed(carried.get("in")))
        groups.setdefault((o.label.category, o.label.colour, o.label.state, o.where, o.on,
                           o.relation, o.carries, o.holds), []).append(o)
    entries = list(groups.values())[:max_objects]
    objects = tuple(o for group in entries for o in group)
    others = tuple(r for r in in_view if r != here)
    parts = [f"You are in the {room}." if room else "The room you are in is not in view."]
    if objects:
        parts.append("Visible: " + "; ".join(entry_phrase(g, room) for g in entries) + ".")
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
            where += "floor of " + and_list([f"the {r}" for r in others]) + " in view, "
        distance = math.hypot(px - obs.pose.x, py - obs.pose.y)
        seen = group_phrases([label for _, _, label in hits], max_groups)
        leads = open_door_leads([label for _, _, label in hits], set(frame_rooms), camera_xy)
        out[p.letter] = (f"{where}{distance:.1f} m away; "
                         + (", ".join(seen) if seen else "no objects seen there")
                         + "".join(f"; an open door to the {r}" for r in leads) + ".")
    return out


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
        lines = [f"{noun_phrase(o.label, 1)} {o.where or ''}".strip() for o in d.objects]
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
