"""The objects a frame shows, one by one, and the words for them (DESIGN 5).

``visible_objects`` reads the instance buffer: each labelled object with enough pixels, its
bearing and distance, near to far, after the optional noise model. The phrase helpers say such
objects as the frame text does ("a white desk lamp (on)", "four black chairs"). They sit here,
below the frame text (``perception.semantic``), the support relation (``perception.supports``)
and the world points (``perception.regions``), because all of those read these objects.

Bearings come from the pixel column of an object's centroid (degrees, positive = left of the
optical axis); distances are the median depth of its pixels (metres along the optical axis).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from efficienteqa.envs.base import ObjectLabel, SceneLabels

if TYPE_CHECKING:
    from efficienteqa.observation import Observation

REFERENCE_AREA_PX = 640 * 480
REFERENCE_MIN_PIXELS = 150  # at 640x480; scaled with image area
AHEAD_DEG = 10.0  # |bearing| up to this is "ahead"
SLIGHTLY_DEG = 30.0  # then "slightly left/right" up to this, "on the left/right" beyond
_NUMBER_WORDS = ("zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine")
_DISPLAY = {"tv": "TV", "tv stand": "TV stand"}


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
        return entry_phrase([self], robot_room)


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


def support_name(label: ObjectLabel) -> str:
    """ "the brown nightstand": colour and category, without the state."""
    noun = _DISPLAY.get(label.category, label.category)
    return f"the {label.colour} {noun}" if label.colour else f"the {noun}"


def entry_phrase(group: list[VisibleObject], robot_room: str | None) -> str:
    """One entry of the frame text: an object, or identical objects counted ("four black chairs
    on the left to ahead, 1.4-2.2 m"; bearings from leftmost to rightmost, distances near-far)."""
    first = group[0]
    text = noun_phrase(first.label, len(group))
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


def listed(labels: list[ObjectLabel] | None) -> str | None:
    """ "a lamp and two cups", or None for no labels."""
    return and_list(group_phrases(labels, len(labels))) if labels else None


def and_list(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def noun_phrase(label: ObjectLabel, count: int) -> str:
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


def group_phrases(labels: list[ObjectLabel], max_groups: int) -> list[str]:
    """Identical labels (category, colour, state) counted together, in order of first sight."""
    counts: dict[tuple[str, str | None, str | None], int] = {}
    first: dict[tuple[str, str | None, str | None], ObjectLabel] = {}
    for label in labels:
        key = (label.category, label.colour, label.state)
        counts[key] = counts.get(key, 0) + 1
        first.setdefault(key, label)
    return [noun_phrase(first[k], n) for k, n in list(counts.items())[:max_groups]]
