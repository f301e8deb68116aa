"""The question's target, parsed once per episode: the room it names, the object it asks about,
what that object stands on or around, and the kind of question.

"What is on the nightstand in the bedroom?" -> kind "identification", object None (it is what the
robot must find), support "nightstand", room "bedroom". "How many chairs are around the table in
the dining room?" -> kind "count", object "chair", support "table", room "dining room".

The parse is rules over the question's words, so it reads any question in any configuration
(text or images); where it finds nothing, the target is empty and every mechanism that reads it
falls back to the paper's behaviour. Room names are canonical (``ROOMS``; "study" -> "office").
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

# Canonical room names and the other words people use for them; the synthetic houses and
# HM-EQA's scenes name their rooms with these.
ROOMS: dict[str, tuple[str, ...]] = {
    "living room": ("lounge", "sitting room", "living area", "family room"),
    "kitchen": (),
    "dining room": ("dining area",),
    "guest bedroom": ("second bedroom", "spare bedroom", "guest room", "spare room"),
    "bedroom": ("main bedroom", "master bedroom"),
    "guest bathroom": ("second bathroom", "guest bath"),
    "bathroom": ("washroom", "restroom", "bath room"),
    "office": ("study", "home office", "study room"),
    "hallway": ("hall", "corridor", "entrance hall", "entryway", "foyer"),
    "laundry room": ("laundry",),
    "garage": (),
    "closet": (),
}
KINDS = ("identification", "count", "existence", "state", "location", "colour", "other")

_ROOM_WORDS = sorted(((w, room) for room, words in ROOMS.items() for w in (room, *words)),
                     key=lambda t: -len(t[0]))  # longest first: "guest bedroom" before "bedroom"
_ROOM_RE = re.compile(r"\b(?:the|a|an|my|our)?\s*(" + "|".join(re.escape(w) for w, _ in _ROOM_WORDS)
                      + r")\b")
_NOUN = r"(?:the|a|an|any)\s+([a-z][a-z -]*?)"


@dataclass(frozen=True)
class Target:
    """What a question points at. ``rooms``: the rooms it names (a door names two); ``object``:
    the thing asked about (None when the answer is the thing, "What is on the X?");
    ``support``: what it stands on or around ("on the X", "around the X"); ``kind``: one of
    ``KINDS``."""

    kind: str = "other"
    object: str | None = None
    support: str | None = None
    rooms: tuple[str, ...] = ()
    # (the question's words, a perception's category) pairs known to name the same thing,
    # resolved once per episode by meaning ("couch" -> "sofa"); ``is_a`` reads them.
    aliases: tuple[tuple[str, str], ...] = ()
    # Where no room is named: the rooms such an object is usually in, most likely first (a
    # prior from the language model, never from the generator's catalogue); () when unknown.
    likely_rooms: tuple[str, ...] = ()

    @property
    def room(self) -> str | None:
        return self.rooms[0] if self.rooms else None

    @property
    def things(self) -> tuple[str, ...]:
        """The object categories a view must show: the object, then its support."""
        return tuple(t for t in (self.object, self.support) if t)

    def is_a(self, thing: str | None, category: str) -> bool:
        """Whether the question's words ``thing`` (its object or support) name a perceived
        object of ``category``: by the words themselves (``names``) or by a resolved alias.
        The one match the gate, the steering, the sightings and the hints all use."""
        if not thing:
            return False
        if names(thing, category):
            return True
        pair = (thing.lower(), category.lower())
        return any((a.lower(), b.lower()) == pair for a, b in self.aliases)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"kind": self.kind, "object": self.object,
                               "support": self.support, "rooms": list(self.rooms)}
        if self.aliases:
            out["aliases"] = [list(a) for a in self.aliases]
        if self.likely_rooms:
            out["likely_rooms"] = list(self.likely_rooms)
        return out


def canonical_room(words: str) -> str | None:
    """The canonical name of a room word ("study" -> "office"), None if it names no room."""
    words = words.strip().lower()
    return next((room for w, room in _ROOM_WORDS if w == words), None)


def singular(noun: str) -> str:
    """A plain singular of an English noun phrase's last word ("chairs" -> "chair",
    "boxes" -> "box", "shelves" -> "shelf")."""
    head, _, last = noun.strip().rpartition(" ")
    if last.endswith("ves") and len(last) > 4:
        last = last[:-3] + "f"
    elif re.search(r"(ches|shes|xes|sses)$", last):
        last = last[:-2]
    elif last.endswith("s") and not last.endswith("ss") and len(last) > 3:
        last = last[:-1]
    return f"{head} {last}".strip()


def parse_question(question: str) -> Target:
    """The target of ``question`` (see the module docstring); an empty ``Target`` when the words
    fit no known form."""
    q = " ".join(question.lower().replace("?", " ").replace("colour", "color").split())
    rooms = tuple(dict.fromkeys(room for _, room in
                                ((m.group(1), canonical_room(m.group(1)))
                                 for m in _ROOM_RE.finditer(q)) if room))
    text = _without_rooms(q)
    patterns: list[tuple[str, str]] = [
        ("identification", rf"^what (?:is|are|'s) (?:on|in|inside|under|above|next to|on top of) {_NOUN}$"),
        ("count", rf"^how many ([a-z -]+?) (?:are |is )?(?:there )?(?:around|on|at|in|near) {_NOUN}$"),
        ("count", r"^how many ([a-z -]+?)(?: are| is)?(?: there)?$"),
        ("existence", rf"^(?:is|are) there {_NOUN}$"),
        ("state", rf"^is {_NOUN} (?:on|off|open|closed|turned on|switched on)$"),
        ("location", rf"^where (?:is|are|can i find) {_NOUN}$"),
        ("colour", rf"^what color (?:is|are) {_NOUN}$"),
    ]
    for kind, pattern in patterns:
        m = re.match(pattern, text)
        if not m:
            continue
        nouns = [_clean(g) for g in m.groups()]
        if kind == "identification":
            return Target(kind, None, nouns[0] or None, rooms)
        if kind == "count":
            return Target(kind, singular(nouns[0]) if nouns[0] else None,
                          nouns[1] if len(nouns) > 1 and nouns[1] else None, rooms)
        return Target(kind, nouns[0] or None, None, rooms)
    return Target("other", None, None, rooms)


def _without_rooms(q: str) -> str:
    """The question with its room phrases dropped ("in the kitchen", "between the A and the B",
    "of the office"), so that what is left names the object."""
    q = re.sub(r"\bbetween (?:the )?[a-z ]+? and (?:the )?[a-z ]+?(?= (?:on|off|open|closed)\b|$)",
               "", q)
    room_alt = "|".join(re.escape(w) for w, _ in _ROOM_WORDS)
    q = re.sub(rf"\s*\b(?:in|of|inside|from|at) (?:the |a |an |my |our )?(?:{room_alt})\b", "", q)
    return " ".join(q.split())


def _clean(noun: str | None) -> str:
    if not noun:
        return ""
    noun = re.sub(r"^(?:the|a|an|any)\s+", "", noun.strip())
    return noun.strip()


def names(thing: str, category: str) -> bool:
    """Whether the question's words ``thing`` ("red sofa", "tv", "chairs") name an object of
    ``category`` ("sofa", "TV", "chair"): equal after case and plural, or one ends with the
    other as a whole word."""
    a, b = singular(thing.lower()), singular(category.lower())
    return a == b or a.endswith(" " + b) or b.endswith(" " + a)
