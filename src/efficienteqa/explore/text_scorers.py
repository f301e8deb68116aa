"""Semantic scorers that read the direction texts without a chat model (DESIGN 8).

A text model on the offline stack reads each lettered direction as text (the ``semantic``
perception). ``LogitDirections`` reads the same texts, plus how far each point lies from the
robot, and gives each letter a confidence (the offline default, ``direction-logit``);
``DirectionScorer`` turns it, or any ``DirectionTextScorer``, into the explore module's
``SemanticScorer``. The baselines it was chosen against (random, the nearest point, keyword
overlap, MiniLM similarity) are the direction experiment's (``experiments/direction_scorers.py``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from efficienteqa.explore.module import SemanticScore
from efficienteqa.observation import Observation, PromptPoint
from efficienteqa.perception.base import Perception
from efficienteqa.relevancy.text import MiniLMScorer, content_words
from efficienteqa.vc.yes_no import DEFAULT_P_YES


@dataclass(frozen=True)
class DirectionFrame:
    """What a direction scorer reads of one prompted frame: the question, the view text, each
    letter's direction text, and each point's straight-line range from the robot (metres)."""

    question: str
    view: str
    directions: Mapping[str, str]
    ranges_m: Mapping[str, float]

    @property
    def letters(self) -> list[str]:
        return list(self.directions)


Scores = tuple[dict[str, float], dict[str, Any]]


class DirectionTextScorer(Protocol):
    """Per-letter confidences (non-negative, any scale) and an info dict (``problems``: what
    could not be read; the scorer then degrades to uniform)."""

    name: str

    def letter_scores(self, frame: DirectionFrame) -> Scores: ...


def uniform(letters: Sequence[str]) -> dict[str, float]:
    return {x: 1.0 / len(letters) for x in letters} if letters else {}


def softmax(values: Mapping[str, float], temperature: float) -> dict[str, float]:
    """Confidences from scores: exp(v / temperature), normalised to sum to 1."""
    keys = list(values)
    v = np.array([values[k] for k in keys], float) / temperature
    e = np.exp(v - v.max())
    return {k: float(x) for k, x in zip(keys, e / e.sum())}


def frame_of(perception: Perception, obs: Observation, prompts: Sequence[PromptPoint],
             question: str) -> DirectionFrame:
    """The direction frame of an observation, as ``perception`` describes it (a VLM's
    perception gives letters only: their texts are empty)."""
    request = perception.explore_request(obs, prompts)
    texts = request.directions if isinstance(request.directions, Mapping) else {}
    return DirectionFrame(question, request.view,
                          {p.letter: str(texts.get(p.letter, "")) for p in prompts},
                          {p.letter: float(np.hypot(p.xy[0] - obs.pose.x, p.xy[1] - obs.pose.y))
                           for p in prompts})


class DirectionScorer:
    """The explore module's ``SemanticScorer`` from a direction scorer: the letters' confidences
    are the LSV; P(worth exploring) is ``p_yes`` (these scorers do not answer the GSV question,
    so every prompted frame gets the same GSV and only the LSV steers)."""

    def __init__(self, scorer: DirectionTextScorer, perception: Perception,
                 p_yes: float = DEFAULT_P_YES) -> None:
        self.scorer, self.perception, self.p_yes = scorer, perception, p_yes
        self.name = scorer.name

    def score(self, obs: Observation, prompts: list[PromptPoint], question: str) -> SemanticScore:
        frame = frame_of(self.perception, obs, prompts, question)
        scores, info = self.scorer.letter_scores(frame)
        return SemanticScore(scores, self.p_yes, {**info, "scorer": self.name})


def direction_parts(text: str) -> list[str]:
    """The phrases of a direction text ("towards the hallway", "a brown door (open)", "an open
    door to the kitchen"), split at semicolons and commas; distances ("2.3 m away") dropped."""
    parts = [p.strip(" .") for chunk in text.split(";") for p in chunk.split(",")]
    return [p for p in parts if p and not p.endswith(" m away")] or [text]


# -- a learned combination: direction features and a conditional logit ----------------------
# The features read the semantic perception's direction text ("towards the dining room, floor
# of the hallway in view, 5.4 m away; a black table; an open door to the hallway.") and the
# point's range; none needs a chat model. See ``LogitDirections``.
_ROOM = re.compile(r"^(in|towards) the ([a-z ]+?), ")
_FLOOR = re.compile(r"floor of (.+?) in view")
_DOOR = re.compile(r"open door to the ([a-z ]+)")
_HERE = re.compile(r"You are in the ([a-z ]+?)\.")


@dataclass(frozen=True)
class DirectionRooms:
    """The rooms a direction text names: ``at`` the point's room (None when its floor is not in
    view there), ``towards`` whether that is another room than the robot's, ``floor`` other
    rooms whose floor is in view there, ``doors`` where open doors there lead."""

    at: str | None
    towards: bool
    floor: tuple[str, ...]
    doors: tuple[str, ...]

    @property
    def all(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys([*([self.at] if self.at else []), *self.floor, *self.doors]))


def direction_rooms(text: str) -> DirectionRooms:
    """The rooms named in one direction text (see ``perception.semantic.describe_directions``)."""
    m = _ROOM.match(text)
    floor: list[str] = []
    for group in _FLOOR.findall(text):
        floor += [r.strip()[4:] for r in re.split(r", | and ", group) if r.strip().startswith("the ")]
    return DirectionRooms(m.group(2) if m else None, bool(m and m.group(1) == "towards"),
                          tuple(floor), tuple(_DOOR.findall(text)))


FEATURES = ("towards", "floor", "door", "hallway", "question_room", "keyword", "no_objects",
            "range_m", "nearest", "cosine", "room_cosine")


def direction_features(frame: DirectionFrame, embedder: MiniLMScorer | None = None) -> np.ndarray:
    """(letters, len(FEATURES)) features of each direction, in ``FEATURES`` order:
    towards another room; other rooms' floor in view; an open door there; the hallway named;
    a room the question names is named; any question word in the text; no objects seen there;
    range (m); the nearest point; and with an ``embedder`` (else 0) the MiniLM cosine of the
    question with the direction's best phrase and with its best-matching room name ("the
    office"), each minus the frame's mean."""
    wanted = content_words(frame.question)
    rows, cos, room_cos = [], [], []
    ranges = [float(frame.ranges_m.get(x, 0.0)) for x in frame.letters]
    q = embedder.embed([frame.question])[0] if embedder is not None and wanted else None
    for x, r in zip(frame.letters, ranges):
        text = frame.directions.get(x, "")
        rooms = direction_rooms(text)
        named = any(content_words(room) - {"room"} and content_words(room) <= wanted | {"room"}
                    for room in rooms.all)
        rows.append([float(rooms.towards), float(bool(rooms.floor)), float(bool(rooms.doors)),
                     float("hallway" in rooms.all), float(named),
                     float(bool(wanted & content_words(text))), float("no objects" in text), r,
                     float(r <= min(ranges))])
        if q is not None:
            cos.append(float((embedder.embed(direction_parts(text)) @ q).max()))  # type: ignore[union-attr]
            names = [f"the {room}" for room in rooms.all]
            room_cos.append(float((embedder.embed(names) @ q).max()) if names else 0.0)  # type: ignore[union-attr]
        else:
            cos.append(0.0)
            room_cos.append(0.0)
    c, rc = np.array(cos), np.array(room_cos)
    return np.column_stack([np.array(rows, float), c - c.mean(), rc - rc.mean()])


class LogitDirections:
    """A conditional logit over the directions of a frame: confidence of a letter is
    softmax(features . ``weights``) (``direction_features``). The weights are fitted on the
    training houses (``experiments/direction_bench.py fit``); without an ``embedder`` the two
    cosine features are 0 and their weights unused."""

    def __init__(self, weights: Sequence[float], embedder: MiniLMScorer | None = None,
                 name: str = "logit", temperature: float = 1.0) -> None:
        if len(weights) != len(FEATURES):
            raise ValueError(f"{len(FEATURES)} weights expected ({', '.join(FEATURES)}), "
                             f"got {len(weights)}")
        self.weights, self.embedder, self.name = np.asarray(weights, float), embedder, name
        self.temperature = temperature  # below 1: sharper confidences, the same ranking

    def letter_scores(self, frame: DirectionFrame) -> Scores:
        if not frame.letters:
            return {}, {"problems": ["no directions"]}
        z = direction_features(frame, self.embedder) @ self.weights
        if not np.isfinite(z).all():
            return uniform(frame.letters), {"problems": ["non-finite features: uniform"]}
        return softmax(dict(zip(frame.letters, z.tolist())), self.temperature), {}


# Fitted with `python -m experiments.direction_bench fit out/direction/train.jsonl --no-embed
# --l2 0.01` on 2026-11-24: 446 frames of training houses 0-20 (5 questions per house, at most 8
# frames per episode), in FEATURES order; top-1 by leave-houses-out cross-validation 0.621
# (nearest point 0.479; l2 0.003 / 0.03: 0.605 / 0.583). With the two MiniLM features (--embed)
# 0.628, within noise for 40-140 ms per frame, so the default needs no embedder (weights 0).
LOGIT_WEIGHTS = (0.7048, 0.2443, 0.1324, 1.1067, 0.6570, 0.5475, 0.4052, -0.0067, 0.4747, 0.0, 0.0)
