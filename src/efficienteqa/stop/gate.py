"""The answerability gate (beyond the paper, DESIGN 9): a relevancy outlier stops the robot only
when the frame can answer the question.

Relevancy alone stops on the container as readily as on its content: "What is on the
bookshelf?" scores as high on a view of the bookshelf from 3 m, where the book on it has 40
pixels, as on a view that shows the book. The gate asks whether the frame answers:

- ``rules`` (text perceptions that describe objects, the offline default): the question's target
  (``question.Target``) is in the frame's description, in the room the question names when the
  frame names one:
  - "What is on the X?": something the description says stands on or in X
    (``VisibleObject.support_id``, the one relation the frame's text states, see
    ``perception.supports``), so the gate passes exactly what the model is told, at the text's
    own size threshold (``REFERENCE_MIN_PIXELS``: relations are as right at 150-250 px as above,
    ``experiments/relation_bench.py`` on training houses 0-20);
  - count questions: the object and its support, seen from inside the named room, the support
    not cut by the frame's edge, and every member seen so far around it (in any frame of the
    episode) in this frame. Members are the episode's object instances where the perception
    keeps an instance map (``mapping.instances``, ``StopConfig.count_from`` "instances", the
    default: each object once however many views show it, the sure ones around the support
    less what stands under it; ``_instances``), else the frame's sightings merged across views
    by position (``_merge``: one member per sighting within SAME_M, never two of one frame).
    Such a frame answers outright (``Verdict.final``): with ``AgentConfig.gate_final`` it stops
    the robot without waiting for a relevancy outlier, which these frames never make (every
    view of the table and a chair scores the same Sim); the direct answer is told the map's
    count (``answer.views.count_note``);
  - state, colour, location and existence questions: the object; for a door question that
    names two rooms, a door the text places between them (or, closed, in a wall of one of
    them: no frame shows a closed door's far side), not any door. A question whose target the
    parse cannot read passes (relevancy decides alone).
- ``sightings`` (a perception that gives sightings but no description: a VLM over images whose
  sightings the model reads, ``perception.sightings``): the same rules on the sightings. They
  state no relation, so "What is on the X?" passes on the X wholly in view;
- ``model`` (any perception, images included): one yes/no call to the chat model, "can the
  question be answered from this view?", passing at P(yes) > 0.5; an unreadable reply does not
  pass.

The gate is asked only on frames the stop rule already flags, so the model gate costs one call
per flagged frame, not per step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from efficienteqa.question import Target

if TYPE_CHECKING:
    import numpy as np

    from efficienteqa.mapping.instances import FrameInstances, InstanceMap
    from efficienteqa.observation import Observation
    from efficienteqa.perception.base import Sightings
    from efficienteqa.perception.visible import FrameDescription, VisibleObject
    from efficienteqa.relevancy.vlm_match import VLMMatchScorer

# "auto": rules where the perception describes objects (the semantic sensor), sightings where it
# gives sightings only (a VLM's, perception.sightings), else model.
GATES = ("auto", "none", "rules", "sightings", "model")
GROUP_M = 1.6  # a count group's member stands this close to its support ("around the table")
# Sightings of a member this close are one member: on training houses 0-20 one chair's
# sightings (the median of its visible points) spread up to 0.51 m across an episode's views,
# and two chairs' nearest sightings are 0.3 m apart at least, 0.47 m in 95% of pairs (those
# seen in one frame stay apart whatever the distance: ``_merge``).
SAME_M = 0.55


@dataclass(frozen=True)
class Verdict:
    """The gate's answer for one frame and why, in a few words (recorded per step)."""

    ok: bool
    why: str
    final: bool = False  # the frame answers outright: stop now (``AgentConfig.gate_final``)


class AnswerGate(Protocol):
    name: str
    eager: bool  # cheap: judge every frame (else only the frames the stop rule flags)

    def reset(self) -> None:
        """Start a new episode."""

    def check(self, question: str, target: Target, obs: Observation,
              frame: str | np.ndarray) -> Verdict: ...


class Describer(Protocol):
    def describe(self, obs: Observation) -> FrameDescription: ...

    def sightings(self, obs: Observation, target: Target) -> Sightings: ...


class RulesGate:
    """The target in the frame's description (module docstring)."""

    name = "rules"
    eager = True

    def __init__(self, perception: Describer, instances: bool = True) -> None:
        self.perception = perception
        self.instances = instances  # count groups from the perception's instance map
        self.reset()

    def reset(self) -> None:
        """Forget the count groups of the last episode."""
        self._members: list[Member] = []  # group members seen near the support
        self._around: set[int] = set()  # instances seen around a whole support (``_instances``)

    def check(self, question: str, target: Target, obs: Observation,
              frame: str | np.ndarray) -> Verdict:
        if target.kind == "other" or not target.things:
            return Verdict(True, "no target parsed")
        d = self.perception.describe(obs)
        room = target.room if target.kind != "state" or target.object != "door" else None

        def in_room(where: str | None) -> bool:
            return room is None or where is None or where == f"in the {room}"

        shown = [o for o in d.objects if in_room(o.where)]
        if target.kind == "identification":  # what the text says stands on or in it
            surfaces = {o.instance_id for o in shown
                        if target.is_a(target.support, o.label.category)}
            if not any(o.support_id in surfaces for o in d.objects):
                return Verdict(False, f"{target.support} with something on it not in view")
            return Verdict(True, f"{target.support} with something on it")
        if target.kind == "count":
            group = [o for o in shown if target.is_a(target.object, o.label.category)]
            if not group:
                return Verdict(False, f"no {target.object} in view")
            if room is not None and d.room != room:  # a doorway cuts a group: count from inside
                return Verdict(False, f"{target.object} seen from outside the {room}")
            if target.support:
                return self._count_group(target, obs, len(group))
            return Verdict(True, f"{len(group)} {target.object} in view")
        thing = target.object or target.support or ""
        hits = [o for o in shown if target.is_a(thing, o.label.category)]
        if len(target.rooms) == 2 and hits and all(o.label.door is not None for o in hits):
            hits = [o for o in hits if _joins(o, target.rooms)]  # that door, not any door
            if not hits:
                return Verdict(False, f"no {thing} of the {' and the '.join(target.rooms)} "
                                      "in view")
        return Verdict(bool(hits), f"{thing} {'in view' if hits else 'not in view'}")

    def _count_group(self, target: Target, obs: Observation, told: int | None) -> Verdict:
        """A count group around its support: from the perception's instance map where it
        keeps one and the gate reads it (``instances``, ``StopConfig.count_from``:
        ``_instances``), else from the frame's sightings merged by place (``_group``)."""
        seen_instances = getattr(self.perception, "instances_seen", None)
        if seen_instances is not None and self.instances:
            return self._instances(target, seen_instances(obs, target),
                                   self.perception.instances, told)  # type: ignore[attr-defined]
        return self._group(target, self.perception.sightings(obs, target), told)

    def _instances(self, target: Target, seen: FrameInstances, instances: InstanceMap,
                   told: int | None) -> Verdict:
        """A count group from the episode's instance map (``mapping.instances``): a sure
        support of the frame wholly in view and its sure members in the frame (``group``),
        every member seen around a whole support so far among them, which then answers
        outright (``told``: how many members the frame's text lists; None where no text is
        read). The answer is told the map's count (``mapping.instances.asked_count``)."""
        in_frame = [i for i in dict.fromkeys(seen.ids) if i in instances.ids]
        supports = [i for i in in_frame if instances[i].sure
                    and target.is_a(target.support, instances[i].category)]
        whole = [i for i in supports if seen.whole(i)]
        if not whole:
            return Verdict(False, f"{target.support} not wholly in view")
        members = instances.group(lambda c: target.is_a(target.object, c), whole)
        here = {m.id for m in members if seen.seen(m.id)}
        self._around = {instances.current(i) for i in self._around} | here
        known = [m for m in members if m.id in self._around]
        if not here:
            return Verdict(False, f"no {target.object} around the {target.support}")
        if told is not None and told < len(here):  # a glimpse the text does not list
            return Verdict(False, f"{len(here) - told} of the {len(here)} "
                                  f"{target.object} too small to be told")
        if len(here) < len(known):
            return Verdict(False, f"{len(here)} of the {len(known)} "
                                  f"{target.object} seen around the {target.support}")
        return Verdict(True, f"{len(here)} {target.object} around the whole "
                             f"{target.support}", final=True)

    def _group(self, target: Target, seen: Sightings, told: int | None) -> Verdict:
        """A count group around its support from one frame's sightings: the support wholly in
        view and every member seen so far around it in this frame, which then answers outright
        (``told``: how many members the frame's text lists; None where no text is read)."""
        support = [s for s in seen.things if target.is_a(target.support, s.category)]
        if not support or any(s.cut for s in support):
            return Verdict(False, f"{target.support} not wholly in view")
        members = [s.xy for s in seen.things if target.is_a(target.object, s.category)
                   and any(_near(s.xy, b.xy, GROUP_M) for b in support)]
        self._members = _merge(self._members, members)
        if told is not None and told < len(members):  # a glimpse the text does not list:
            # the model would count fewer than the gate
            return Verdict(False, f"{len(members) - told} of the {len(members)} "
                                  f"{target.object} too small to be told")
        if len(members) < len(self._members):
            return Verdict(False, f"{len(members)} of the {len(self._members)} "
                                  f"{target.object} seen around the {target.support}")
        # the whole group and its support, from inside the room: it answers outright
        return Verdict(True, f"{len(members)} {target.object} around the whole "
                             f"{target.support}", final=True)


class SightingsGate(RulesGate):
    """The target in the frame's sightings, for a perception that gives sightings but no
    description (a VLM over images with ``perception.sightings.ModelSightings``): the same
    rules read from the model's sightings. The thing (or the surface of "What is on the X?",
    wholly in view) in the named room as the sightings place it; a count group as the rules
    gate judges one. The sightings state no relation, so "on the X" is the X in view."""

    name = "sightings"

    def __init__(self, perception: Sighter, instances: bool = True) -> None:
        self.perception = perception  # type: ignore[assignment]
        self.instances = instances
        self.reset()

    def check(self, question: str, target: Target, obs: Observation,
              frame: str | np.ndarray) -> Verdict:
        if target.kind == "other" or not target.things:
            return Verdict(True, "no target parsed")
        seen = self.perception.sightings(obs, target)
        room = target.room if target.kind != "state" or target.object != "door" else None
        shown = [s for s in seen.things if room is None or s.room in (None, room)]
        if target.kind == "identification":
            surfaces = [s for s in shown if target.is_a(target.support, s.category)]
            if not surfaces or all(s.cut for s in surfaces):
                return Verdict(False, f"{target.support} not wholly in view")
            return Verdict(True, f"{target.support} in view")
        if target.kind == "count":
            group = [s for s in shown if target.is_a(target.object, s.category)]
            if not group:
                return Verdict(False, f"no {target.object} in view")
            if target.support:
                return self._count_group(target, obs, None)
            return Verdict(True, f"{len(group)} {target.object} in view")
        thing = target.object or target.support or ""
        hits = [s for s in shown if target.is_a(thing, s.category)]
        return Verdict(bool(hits), f"{thing} {'in view' if hits else 'not in view'}")


class Sighter(Protocol):
    def sightings(self, obs: Observation, target: Target) -> Sightings: ...


def _near(a: tuple[float, float], b: tuple[float, float], within_m: float) -> bool:
    return (a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 <= within_m ** 2


def _merge(known: list[Member], seen: list[tuple[float, float]]) -> list[Member]:
    """The group's members after one frame's sightings ``seen``: each sighting is the member
    nearest to it within SAME_M, one sighting per member (the frame tells its members apart:
    two chairs side by side in one view are two, however close), nearest pairs first; a
    sighting left over is a new member. A member's place is the mean of its sightings (the
    median of an object's visible points moves with the viewpoint)."""
    pairs = sorted((math.dist(p, m.xy), i, j) for i, p in enumerate(seen)
                   for j, m in enumerate(known) if math.dist(p, m.xy) <= SAME_M)
    out, taken, used = list(known), set(), set()
    for _, i, j in pairs:
        if i not in taken and j not in used:
            taken.add(i)
            used.add(j)
            out[j] = out[j].seen_at(seen[i])
    return out + [Member(p, 1) for i, p in enumerate(seen) if i not in taken]


@dataclass(frozen=True)
class Member:
    """A count group's member: its place (the mean of its sightings, world x, y in metres)."""

    xy: tuple[float, float]
    n: int

    def seen_at(self, p: tuple[float, float]) -> Member:
        n = self.n + 1
        return Member(((self.xy[0] * self.n + p[0]) / n, (self.xy[1] * self.n + p[1]) / n), n)


def _joins(door: VisibleObject, rooms: tuple[str, ...]) -> bool:
    """Whether the text places ``door`` between the two ``rooms`` (either order), or, for a
    closed door, whose far side no frame shows, in a wall of one of them."""
    a, b = rooms
    if door.where in (f"between the {a} and the {b}", f"between the {b} and the {a}"):
        return True
    return door.label.state == "closed" and door.where in (f"in a wall of the {a}",
                                                            f"in a wall of the {b}")


class ModelGate:
    """One yes/no call per flagged frame (module docstring), through a ``VLMMatchScorer`` of the
    agent's own chat model: images for a VLM, the frame's text for a text model."""

    name = "model"
    eager = False

    def __init__(self, match: VLMMatchScorer) -> None:
        self.match = match

    def reset(self) -> None:
        pass

    def check(self, question: str, target: Target, obs: Observation,
              frame: str | np.ndarray) -> Verdict:
        if isinstance(frame, str):
            p_yes = self.match.score(question, text=frame)
        else:
            p_yes = self.match.score(question, image=frame)
        if math.isnan(p_yes):  # an unreadable reply does not pass
            return Verdict(False, "unreadable reply")
        return Verdict(p_yes > 0.5, f"P(answerable) {p_yes:.2f}")

    @property
    def problems(self) -> list[str]:
        """What the yes/no calls' replies did not say plainly, for the record."""
        return self.match.problems
