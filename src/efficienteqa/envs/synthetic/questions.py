"""Ground-truth questions about a house, in the HM-EQA categories plus colour.

Every question names its evidence objects (what must be seen to answer it). Objects are referred
to as "the <category> in the <room>", so a question is only asked where that phrase is unique.
Every question also lists the answers a grader must accept (``accepted``: synonyms, a number as
digits or words, grey/gray, "on"/"open" for a yes; see ``answers``).
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from efficienteqa.envs.synthetic import answers
from efficienteqa.envs.synthetic.house import House, PlacedObject
from efficienteqa.errors import EfficientEQAError

CATEGORIES = ("identification", "count", "existence", "state", "location", "colour")
NUMBER_WORDS = answers.NUMBER_WORDS
# Objects that are too generic or too many to be the subject of a question.
UNASKED = frozenset({"door", "chair", "kitchen cabinet"})
MIN_EVIDENCE_PIXELS = 250  # at 640x480; scaled by image area for other sizes


@dataclass
class Question:
    """One question with its exact answer and acceptable alternatives.

    ``accepted``: every form of the answer a grader accepts (the rule judge's key, with
    ``answers.lexicon(category)`` for the values that contradict it); empty in question files
    written before it existed. ``oracle_steps``: the fewest observations (the start view is
    step 1, each further step is a move of at most 3 m) after which every evidence object is in
    view; None when there is no
    evidence to see (a "no" existence answer) or it cannot be seen from anywhere reachable.
    """

    id: str
    house_seed: int
    category: str
    question: str
    answer: str
    alternatives: list[str] = field(default_factory=list)
    evidence: list[int] = field(default_factory=list)
    oracle_steps: int | None = None
    oracle_pose: tuple[float, float, float] | None = None
    accepted: list[str] = field(default_factory=list)

    def to_json(self) -> str:
        return json.dumps(asdict(self))


def _the(house: House, obj: PlacedObject) -> str:
    return f"the {obj.category} in the {house.room(obj.room_id).name}"


def evidence_visible(instance: np.ndarray, evidence: list[int], min_pixels: int | None = None
                     ) -> bool:
    """Whether every evidence object covers at least ``min_pixels`` of an instance buffer."""
    if not evidence:
        return False
    if min_pixels is None:
        min_pixels = max(4, round(MIN_EVIDENCE_PIXELS * instance.size / (640 * 480)))
    counts = np.bincount(instance[instance > 0].ravel(), minlength=max(evidence) + 1)
    return all(counts[e] >= min_pixels for e in evidence)


def generate_questions(house: House, rng: np.random.Generator, per_category: int = 2
                       ) -> list[Question]:
    """Up to ``per_category`` questions of each category (fewer where the house has none)."""
    by_kind = {
        "identification": _identification(house),
        "count": _count(house),
        "existence": _existence(house, rng),
        "state": _state(house),
        "location": _location(house),
        "colour": _colour(house),
    }
    out: list[Question] = []
    for kind in CATEGORIES:
        options = by_kind[kind]
        if kind == "existence":  # balance the answers: "yes" and "no" alternate
            picks = _balanced(rng, options, per_category)
        else:
            picks = sorted(rng.permutation(len(options))[:per_category].tolist())
        for idx in picks:
            text, answer, alternatives, evidence, accepted = options[idx]
            alternatives = [a for a in dict.fromkeys(alternatives) if a != answer]
            out.append(Question(f"syn-{house.seed}-{len(out):02d}", house.seed, kind, text,
                                answer, alternatives, evidence, accepted=answers.unique(accepted)))
    return out


def _balanced(rng: np.random.Generator, options: list[Template], k: int) -> list[int]:
    """Up to k option indices alternating between "yes" and "no" answers."""
    pools = [[i for i, t in enumerate(options) if t[1] == answer] for answer in ("yes", "no")]
    pools = [list(rng.permutation(p)) for p in pools]
    picks: list[int] = []
    while len(picks) < k and any(pools):
        pool = pools[len(picks) % 2] or pools[(len(picks) + 1) % 2]
        picks.append(int(pool.pop()))
    return sorted(picks)


# (question, answer, alternatives, evidence object ids, accepted answers)
Template = tuple[str, str, list[str], list[int], list[str]]


def _unique_in_room(house: House) -> list[PlacedObject]:
    counts = Counter((o.room_id, o.category) for o in house.objects)
    return [o for o in house.objects
            if counts[(o.room_id, o.category)] == 1 and o.category not in UNASKED]


def _identification(house: House) -> list[Template]:
    out: list[Template] = []
    for surface in _unique_in_room(house):
        on_top = [o for o in house.objects if o.support_id == surface.id]
        if len(on_top) == 1:
            item = on_top[0]
            out.append((f"What is on {_the(house, surface)}?", f"a {item.category}",
                        [item.category, item.name.lower()], [surface.id, item.id],
                        answers.category_forms(item.category, item.name)))
    return out


def _count(house: House) -> list[Template]:
    out: list[Template] = []
    for table_id, chairs in house.meta.get("chairs_at_table", {}).items():
        table = house.object(int(table_id))
        n = len(chairs)
        if n:
            out.append((f"How many chairs are around {_the(house, table)}?", str(n),
                        [NUMBER_WORDS[n], f"{n} chairs"], [table.id, *chairs],
                        answers.number_forms(n)))
    return out


def _existence(house: House, rng: np.random.Generator) -> list[Template]:
    present = _unique_in_room(house)
    out: list[Template] = [
        (f"Is there a {o.category} in the {house.room(o.room_id).name}?", "yes",
         [f"yes, there is a {o.category}"], [o.id], answers.polarity_forms("yes"))
        for o in present if o.support_id is None
    ]
    categories = sorted({o.category for o in present if o.support_id is None})
    for room in house.layout.rooms:
        here = {o.category for o in house.objects if o.room_id == room.id}
        absent = [c for c in categories if c not in here]
        if absent:
            cat = absent[int(rng.integers(len(absent)))]
            out.append((f"Is there a {cat} in the {room.name}?", "no",
                        [f"no, there is no {cat}"], [], answers.polarity_forms("no")))
    return out


def _state(house: House) -> list[Template]:
    out: list[Template] = []
    for o in _unique_in_room(house):
        if o.state in ("on", "off"):
            yes = o.state == "on"
            out.append((f"Is {_the(house, o)} on?", "yes" if yes else "no",
                        ["yes, it is on" if yes else "no, it is off"], [o.id],
                        answers.polarity_forms("yes" if yes else "no", "on")))
    for o in house.objects:
        if o.category == "door" and o.state is not None:
            door_id = {v: int(k) for k, v in house.meta["door_objects"].items()}[o.id]
            door = house.layout.doors[door_id]
            a, b = house.room(door.room_a).name, house.room(door.room_b).name
            is_open = o.state == "open"
            out.append((f"Is the door between the {a} and the {b} open?",
                        "yes" if is_open else "no",
                        ["yes, it is open" if is_open else "no, it is closed"], [o.id],
                        answers.polarity_forms("yes" if is_open else "no", "open")))
    return out


def _location(house: House) -> list[Template]:
    counts = Counter(o.category for o in house.objects)
    out: list[Template] = []
    for o in house.objects:
        if counts[o.category] != 1 or o.category in UNASKED:
            continue
        room = house.room(o.room_id).name
        if o.support_id is not None:
            surface = house.object(o.support_id).category
            out.append((f"Where is the {o.category}?", f"on the {surface} in the {room}",
                        [f"on the {surface}", f"in the {room}"], [o.id, o.support_id],
                        [*answers.room_forms(room), *answers.category_forms(surface)]))
        else:
            out.append((f"Where is the {o.category}?", f"in the {room}", [room], [o.id],
                        answers.room_forms(room)))
    return out


def _colour(house: House) -> list[Template]:
    return [
        (f"What colour is {_the(house, o)}?", o.colour, [f"it is {o.colour}"], [o.id],
         answers.colour_forms(o.colour))
        for o in _unique_in_room(house) if o.colour_rgb is not None
    ]


def save_questions(questions: list[Question], path: Path) -> None:
    path.write_text("".join(q.to_json() + "\n" for q in questions))


def load_questions(path: Path) -> list[Question]:
    out = []
    for n, line in enumerate(Path(path).read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            data = json.loads(line)
            data["oracle_pose"] = tuple(data["oracle_pose"]) if data.get("oracle_pose") else None
            out.append(Question(**data))
        except (json.JSONDecodeError, TypeError) as exc:
            raise EfficientEQAError(f"{path}:{n}: not a question record ({exc})") from exc
    return out
