"""Sightings read by the chat model: what a view shows of the rooms and of the question's target,
from one call per step (beyond the paper, DESIGN 9).

The target steering, its inspect moves, the "searched" end and the sightings gate read
``Sightings``: each room's floor in view as world points, and the target's things with a world
point, a top and whether the frame cuts them. The semantic sensor and the pixel network know
them per pixel. A VLM over images does not: ``ModelSightings`` asks it, once per step, for the
room the view is in, the rooms seen through doorways and the target's things, each with a box
in thousandths of the image (``BOX_SCALE``, the convention of Qwen-VL and many servers), and
turns the reply into the same ``Sightings`` with the frame's depth and pose:

- the floor: every valid pixel whose world point lies within ``FLOOR_M`` of z = 0 belongs to
  the room of the doorway box it falls in, else to the view's room;
- a thing: the points of its box (less the floor) at the depth most of the box's middle half
  shows (a box also holds the wall behind a chair): the median x, y, the 98th percentile of z;
  cut when the box touches the left, right or top edge; its room the room of the nearest floor
  point named, within ``ROOM_M``;
- a doorway's box is also a door (``Sightings.doors``), placed as a thing is (its frame, the
  nearest surface off the floor in the box), with the room the reply saw through it.

The same call reads a text perception's description (``images`` False): the objects are listed
by number, the reply names numbers, and each number's pixels come from the perception's own
frame (``read``); the floor is the perception's own, kept for the rooms the model named. This
measures what reading by a model costs against the rules, with everything else equal.

Nothing of the reply is trusted: a room must be one of ``question.ROOMS``, a thing's name one of
the target's words (or an alias of them), a box four numbers inside the frame, an item a number
listed, a number finite. A reply with no JSON object (a refusal, chatter, a reply cut at
``MAX_TOKENS``), or one beyond the bounds of ``vc.json_reply.json_reply`` (nested too deep, too many
values, a number that is not finite), is a problem and means "no sighting" for that step, never
an error; of a reply's doorways and things the first ``MAX_ENTRIES`` each are read.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from efficienteqa.geometry import backproject
from efficienteqa.mapping.instances import FrameInstances, InstanceMap
from efficienteqa.mapping.instances import Region as MapRegion
from efficienteqa.models.base import ChatModel, Message
from efficienteqa.perception.base import Perception, Sighting, Sightings
from efficienteqa.question import ROOMS, Target, canonical_room, singular
from efficienteqa.vc.json_reply import json_reply
from efficienteqa.vc.prompts import load_prompt

if TYPE_CHECKING:
    from efficienteqa.observation import Observation

PROMPTS = "efficienteqa.perception"  # perception/prompts/sightings.txt
MAX_TOKENS = 200  # a JSON object with a room, a doorway or two and a few boxes
BOX_SCALE = 1000.0  # box coordinates are thousandths of the frame's width and height
FLOOR_M = 0.08  # world points this close to z = 0 are floor
STRIDE = 4  # floor points: every 4th pixel each way, as the semantic sensor's
EDGE = 5.0  # a box within this many thousandths of the left, right or top edge is cut
# A thing's points: within NEAR_M / 2 of the depth bin (DEPTH_BIN_M) most of its box's middle
# lies in. Training houses 0-7, 96 random poses, 380 things boxed from the labels: the median
# distance to the semantic sensor's place is 0.06 m, 5.5% are over 0.6 m off (the 25th
# percentile of the depths and all within 0.6 m of it: 0.08 m, 8.9%); the rest are things
# behind others (a chair behind its table), whose box shows mostly the nearer thing.
NEAR_M = 0.6
DEPTH_BIN_M = 0.25
ROOM_M = 1.5  # a thing's room: the nearest floor point named within this
# A reply's doorways and things read at most, each (a view shows a few; ``project`` builds a
# frame mask per entry, and 100,000 entries held a step for minutes).
MAX_ENTRIES = 32


@dataclass(frozen=True)
class Region:
    """Where in the frame: a box (x0, y0, x1, y1) in thousandths, or listed item numbers."""

    box: tuple[float, float, float, float] | None = None
    items: tuple[int, ...] = ()


@dataclass(frozen=True)
class SightingReply:
    """A readable reply: the view's room, the doorways' rooms and the target's things."""

    room: str | None
    doorways: tuple[tuple[str, Region], ...] = ()
    things: tuple[tuple[str, Region], ...] = ()


def prompt(question: str, target: Target, view: str, images: bool) -> str:
    """The sighting call's text: fixed instructions first (a llama.cpp or vLLM server reuses
    them between calls), then the episode's question and things, then the view (a numbered
    description, or "the attached image")."""
    if images:
        where = '"box": [x0, y0, x1, y1]'
        how = ("A box is the rectangle around it in thousandths of the image: x0, x1 from the "
               "left edge (0) to the right edge (1000), y0, y1 from the top (0) to the bottom "
               "(1000).\n")
        example = ('{"room": "kitchen", "doorways": [{"room": "hallway", "box": [700, 250, 1000, '
                   '800]}], "things": [{"name": "chair", "box": [120, 450, 480, 900]}]}')
        doorway = f'{{"room": its kind, {where}}}'
    else:
        where = '"item": its number in the list'
        how = "Name each thing by its number in the list; list one entry per number.\n"
        example = ('{"room": "kitchen", "doorways": [{"room": "hallway"}], "things": '
                   '[{"name": "chair", "item": 2}]}')
        doorway = '{"room": its kind}'
    return load_prompt("sightings", PROMPTS).format(
        question=question, view=view, rooms=", ".join(ROOMS), doorway=doorway,
        names=", ".join(f'"{t}"' for t in target.things) or "none",
        thing=f'{{"name": one of the things to look for, {where}}}', how=how, example=example)


def schema(images: bool) -> dict[str, Any]:
    """The reply's JSON schema, for servers that constrain replies to one."""
    where: dict[str, Any] = ({"box": {"type": "array", "items": {"type": "number"},
                                      "minItems": 4, "maxItems": 4}}
                             if images else {"item": {"type": "integer"}})
    key = "box" if images else "item"
    door: dict[str, Any] = {"type": "object", "properties": {
        "room": {"type": "string"}, **(where if images else {})},
        "required": ["room", *(["box"] if images else [])]}
    thing = {"type": "object", "properties": {"name": {"type": "string"}, **where},
             "required": ["name", key]}
    return {"type": "object", "properties": {
        "room": {"type": ["string", "null"]},
        "doorways": {"type": "array", "items": door},
        "things": {"type": "array", "items": thing}},
        "required": ["room", "doorways", "things"]}


def read_reply(reply: str, target: Target, items: int | None = None
               ) -> tuple[SightingReply | None, list[str]]:
    """The reply as ``SightingReply`` and what of it could not be used. ``items``: the number
    of objects listed (a text view; None: an image, whose things have boxes). None when the
    reply holds no JSON object."""
    said, why = json_reply(reply)
    if said is None:
        return None, [f"{why} in the sighting reply {reply[:60]!r}: no sighting"]
    problems: list[str] = []
    room = _room(said.get("room"), problems)
    doorways: list[tuple[str, Region]] = []
    for entry in _entries(said.get("doorways"), "doorways", problems):
        name = _room(entry.get("room"), problems)
        region = _region(entry, items, problems, required=items is None)
        if name is not None and region is not None:
            doorways.append((name, region))
    things: list[tuple[str, Region]] = []
    for entry in _entries(said.get("things"), "things", problems):
        name = thing_of(entry.get("name"), target)
        if name is None:
            problems.append(f"thing {str(entry.get('name'))[:30]!r} is not the target's")
            continue
        region = _region(entry, items, problems, required=True)
        if region is not None:
            things.append((name, region))
    return SightingReply(room, tuple(doorways), tuple(things)), problems


def thing_of(name: Any, target: Target) -> str | None:
    """The target's word ``name`` stands for (its own words, plural or an alias), else None."""
    if not isinstance(name, str) or not name.strip():
        return None
    words = " ".join(name.lower().replace("_", " ").split())
    for article in ("the ", "a ", "an "):
        words = words.removeprefix(article)
    for thing in target.things:
        if singular(words) == singular(thing.lower()) or target.is_a(thing, words):
            return thing
    return None


def _room(value: Any, problems: list[str]) -> str | None:
    if value is None or (isinstance(value, str) and value.strip().lower() in ("", "none", "null")):
        return None
    room = canonical_room(value) if isinstance(value, str) else None
    if room is None:
        problems.append(f"room {str(value)[:30]!r} unknown")
    return room


def _entries(value: Any, key: str, problems: list[str]) -> list[dict[str, Any]]:
    if value is None:
        return []
    if not isinstance(value, list):
        problems.append(f"{key} is no list")
        return []
    entries = [v for v in value if isinstance(v, dict)]
    if len(entries) < len(value):
        problems.append(f"{len(value) - len(entries)} of the {key} are no objects")
    if len(entries) > MAX_ENTRIES:
        problems.append(f"{len(entries)} {key}, read the first {MAX_ENTRIES}")
        entries = entries[:MAX_ENTRIES]
    return entries


def _number(value: Any) -> float | None:
    """``value`` as a float; None for anything that is no number (text, a bool). A reply's
    numbers are finite and within a float already (``vc.json_reply.json_reply`` refuses others)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value)


def _region(entry: dict[str, Any], items: int | None, problems: list[str],
            required: bool) -> Region | None:
    if items is not None:
        item = entry.get("item")
        number = _number(item)
        if number is None or not number.is_integer() or not 1 <= number <= items:
            if required:
                problems.append(f"item {str(item)[:20]} is not listed")
            return None if required else Region()
        return Region(items=(int(number),))
    box = entry.get("box")
    found = [_number(v) for v in box] if isinstance(box, list) and len(box) == 4 else []
    values = [v for v in found if v is not None]
    if len(values) != 4:
        problems.append(f"box {str(box)[:40]} is not four numbers")
        return None
    if max(values) <= 1.0:  # fractions of the frame, not thousandths
        values = [v * BOX_SCALE for v in values]
    x0, y0, x1, y1 = (min(max(v, 0.0), BOX_SCALE) for v in values)
    x0, x1 = sorted((x0, x1))
    y0, y1 = sorted((y0, y1))
    if x1 - x0 < 1.0 or y1 - y0 < 1.0:
        problems.append(f"box {box} is empty")
        return None
    return Region(box=(x0, y0, x1, y1))


def box_mask(box: tuple[float, float, float, float], shape: tuple[int, int]) -> np.ndarray:
    """The (H, W) pixels of a box in thousandths."""
    h, w = shape
    x0, y0, x1, y1 = box
    mask = np.zeros((h, w), bool)
    mask[int(y0 * h / BOX_SCALE):max(int(np.ceil(y1 * h / BOX_SCALE)), 1),
         int(x0 * w / BOX_SCALE):max(int(np.ceil(x1 * w / BOX_SCALE)), 1)] = True
    return mask


def project(reply: SightingReply, obs: Observation,
            floor: dict[str, np.ndarray] | None = None,
            masks: dict[int, np.ndarray] | None = None) -> Sightings:
    """``reply`` as world points with the frame's depth and pose. ``floor``: the floor points
    per room to keep (a text perception's own; None: from depth, by the reply's boxes);
    ``masks``: item number -> its pixels (a text view)."""
    depth = obs.depth_m
    h, w = depth.shape
    points = backproject(depth, obs.intrinsics, obs.cam_to_world)
    valid = depth > 0
    on_floor = valid & (np.abs(points[..., 2]) < FLOOR_M)
    if floor is None:
        floor = _floor(reply, points, on_floor)
    else:
        named = {reply.room, *(r for r, _ in reply.doorways)}
        floor = {room: xy for room, xy in floor.items() if room in named}
    things: list[Sighting] = []
    for name, region in reply.things:
        if region.box is not None:
            mask = box_mask(region.box, (h, w))
            cut = (region.box[0] <= EDGE or region.box[2] >= BOX_SCALE - EDGE
                   or region.box[1] <= EDGE)
            inner = box_mask(_middle(region.box), (h, w))
            p = _thing_points(points, depth, mask & valid & ~on_floor,
                              inner & valid & ~on_floor)
            pixels = int(mask.sum())
        else:
            mask = np.zeros((h, w), bool)
            for item in region.items:
                mask |= (masks or {}).get(item, np.zeros((h, w), bool))
            mask &= valid
            rows, cols = np.nonzero(mask)
            cut = bool(len(cols) and (cols.min() == 0 or cols.max() == w - 1 or rows.min() == 0))
            p, pixels = points[mask], int(mask.sum())
        if not len(p):
            continue
        xy = (float(np.median(p[:, 0])), float(np.median(p[:, 1])))
        things.append(Sighting(name, xy, float(np.percentile(p[:, 2], 98)), pixels, cut,
                               _room_near(xy, floor) or reply.room, p[::STRIDE]))
    doors = []  # a doorway boxed: where its frame stands (the box's nearest surface off the
    # floor), with the room the reply saw through it
    for room, region in reply.doorways:
        if region.box is None:
            continue
        mask = box_mask(region.box, (h, w)) & valid & ~on_floor
        p = _thing_points(points, depth, mask, box_mask(_middle(region.box), (h, w)) & mask)
        if len(p):
            cut = (region.box[0] <= EDGE or region.box[2] >= BOX_SCALE - EDGE
                   or region.box[1] <= EDGE)
            doors.append(Sighting("door", (float(np.median(p[:, 0])), float(np.median(p[:, 1]))),
                                  float(np.percentile(p[:, 2], 98)), int(mask.sum()), cut, room))
    return Sightings(floor, tuple(things), tuple(doors))


def _floor(reply: SightingReply, points: np.ndarray,
           on_floor: np.ndarray) -> dict[str, np.ndarray]:
    """The floor points per room: in a doorway's box that room's, else the view's room's."""
    k = STRIDE
    keep = on_floor[::k, ::k].copy()
    xy = points[::k, ::k, :2]
    out: dict[str, list[np.ndarray]] = {}
    for room, region in sorted(reply.doorways, key=lambda d: _area(d[1])):  # smallest first
        if region.box is None:
            continue
        inside = keep & box_mask(region.box, on_floor.shape)[::k, ::k]
        out.setdefault(room, []).append(xy[inside])
        keep &= ~inside
    if reply.room is not None:
        out.setdefault(reply.room, []).append(xy[keep])
    return {room: np.concatenate(parts) for room, parts in out.items()
            if sum(len(p) for p in parts)}


def _area(region: Region) -> float:
    if region.box is None:
        return 0.0
    x0, y0, x1, y1 = region.box
    return (x1 - x0) * (y1 - y0)


def _middle(box: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    x0, y0, x1, y1 = box
    dx, dy = (x1 - x0) / 4, (y1 - y0) / 4
    return (x0 + dx, y0 + dy, x1 - dx, y1 - dy)


def _thing_points(points: np.ndarray, depth: np.ndarray, box: np.ndarray,
                  inner: np.ndarray) -> np.ndarray:
    """A box's points on the thing: those within NEAR_M / 2 of the depth most of its middle's
    pixels lie at (``DEPTH_BIN_M`` bins; the whole box where its middle shows only floor)."""
    core = inner if inner.any() else box
    if not core.any():
        return np.zeros((0, 3))
    bins, counts = np.unique(np.floor(depth[core] / DEPTH_BIN_M).astype(int), return_counts=True)
    centre = (bins[np.argmax(counts)] + 0.5) * DEPTH_BIN_M
    return points[box & (np.abs(depth - centre) <= NEAR_M / 2)]


def _room_near(xy: tuple[float, float], floor: dict[str, np.ndarray]) -> str | None:
    best, best_d = None, ROOM_M ** 2
    for room, pts in floor.items():
        if not len(pts):
            continue
        d = float(np.min((pts[:, 0] - xy[0]) ** 2 + (pts[:, 1] - xy[1]) ** 2))
        if d <= best_d:
            best, best_d = room, d
    return best


class ModelSightings:
    """A perception whose ``sightings`` come from one call to ``model`` per step (module
    docstring); everything else is ``base``'s. ``images``: send the RGB frame (default: when
    ``base`` gives images) rather than ``base``'s numbered description. ``problems`` collects
    what of the replies could not be used, for the record."""

    def __init__(self, base: Perception, model: ChatModel, images: bool | None = None,
                 max_tokens: int = MAX_TOKENS) -> None:
        self.base, self.model, self.max_tokens = base, model, max_tokens
        self.images = base.modality == "image" if images is None else images
        if not self.images and not hasattr(base, "describe"):
            raise ValueError(f"{base.name} perception gives no description to read sightings from")
        self.name, self.modality = base.name, base.modality
        self.problems: list[str] = []
        self.question = ""  # the episode's (``ask_about``), which the call quotes
        self._seen: tuple[Observation, Target, Sightings] | None = None
        self.instances = InstanceMap()  # the target's things the model boxed, over the episode
        self._added: tuple[Observation, FrameInstances] | None = None

    def __getattr__(self, name: str) -> Any:  # frame, relevancy_text, describe, read, labels
        if name == "base":
            raise AttributeError(name)
        return getattr(self.base, name)

    def reset(self) -> None:
        self._seen = None
        self.instances.reset()
        self._added = None
        reset = getattr(self.base, "reset", None)
        if reset is not None:
            reset()

    def ask_about(self, question: str) -> None:
        """The episode's question, quoted in each call (the agent says it as the episode
        starts)."""
        self.question = question

    def sightings(self, obs: Observation, target: Target) -> Sightings:
        """This frame's sightings of ``target``: one call, kept for the frame (the explorer and
        the gate both read them). No call where the target names no room and no thing."""
        if self._seen is not None and self._seen[0] is obs and self._seen[1] == target:
            return self._seen[2]
        seen = Sightings({})
        if target.things or target.rooms or target.likely_rooms:
            seen = self._ask(obs, target, self.question or _question_of(target))
        self._seen = (obs, target, seen)
        if self._added is None or self._added[0] is not obs:  # the things to the instance map
            self._added = (obs, self.instances.add([
                MapRegion(s.category, s.points, room=s.room, cut=s.cut)
                for s in seen.things if s.points is not None and len(s.points)]))
        return seen

    def instances_seen(self, obs: Observation, target: Target) -> FrameInstances:
        """The target's things of this frame added to the episode's instance map
        (``mapping.instances``), merged across views by place (a box's points), and which
        instances they are. The call is the frame's ``sightings``."""
        self.sightings(obs, target)
        assert self._added is not None and self._added[0] is obs
        return self._added[1]

    def _ask(self, obs: Observation, target: Target, question: str) -> Sightings:
        images: tuple[np.ndarray, ...] = ()
        listed: int | None = None
        if self.images:
            view, images = "The view is the attached image.", (obs.rgb,)
        else:
            view, items, masks, own = self._listed(obs, target)
            listed = len(items)
        schema_ = schema(self.images) if self.model.capabilities.json_schema else None
        response = self.model.chat(
            [Message("user", prompt(question, target, view, self.images), images)],
            max_tokens=self.max_tokens, temperature=0.0, json_schema=schema_)
        reply, problems = read_reply(response.text or "", target, listed)
        if reply is None and response.finish_reason == "length":
            problems = [f"{problems[0]} (cut at {self.max_tokens} tokens)"]
        self.problems += problems
        if reply is None:
            return Sightings({})
        if self.images:
            return project(reply, obs)
        return project(reply, obs, floor=own, masks=masks)

    def _listed(self, obs: Observation, target: Target
                ) -> tuple[str, Sequence[int], dict[int, np.ndarray], dict[str, np.ndarray]]:
        """A text view: the description with its objects numbered, each number's pixels and
        the perception's own floor per room."""
        d = self.base.describe(obs)  # type: ignore[attr-defined]
        seen, _ = self.base.read(obs)  # type: ignore[attr-defined]
        lines = [f"You are in the {d.room}." if d.room else "The room you are in is not in view."]
        lines += [f"{n}. {o.phrase(d.room)}" for n, o in enumerate(d.objects, 1)]
        if not d.objects:
            lines.append("Nothing but walls and floor.")
        if d.rooms_through_doorways:
            lines.append("Through a doorway: "
                         + ", ".join(f"the {r}" for r in d.rooms_through_doorways) + ".")
        masks = {n: seen.instance == o.instance_id for n, o in enumerate(d.objects, 1)}
        own = self.base.sightings(obs, target).floor  # type: ignore[attr-defined]
        return "\n".join(lines), range(1, len(d.objects) + 1), masks, dict(own)


def _question_of(target: Target) -> str:
    """A question standing in for the episode's, when the caller gives none."""
    return f"Where is the {target.things[0]}?" if target.things else "Which room is this?"
