"""The direct answer's text views, cut to what the question names (DESIGN 8).

The direct answer reads text views cut to what the question names (``focus_views``: one view
for a count, the views that show the object for a location, the object's own colour) and, for
an existence question no view answers, a sentence saying so (``absence_note``); a count
question is told its view's count as a number (``count_note``). All read the
frame text of ``perception.semantic``, which the labels and the pixel perception share. A VLM
over images gets the image hints of ``answer.prompting`` instead (count each object once, the
colour of that object): the views are pictures, and the VLM does the focusing itself.

Apart from the model calls (``answer.calls``) because this is plain text work on the views,
with no model: the evaluation's replays (``eval.replay``) and the benchmarks read the views
the same way.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

from efficienteqa.question import Target, parse_question, singular

# Words of a question that name no object: what is left names what the question is about.
_FUNCTION_WORDS = frozenset((
    "a", "an", "the", "is", "are", "was", "were", "there", "what", "which", "who", "whose", "how",
    "many", "much", "where", "when", "why", "do", "does", "did", "can", "could", "has", "have",
    "of", "on", "in", "at", "to", "from", "by", "for", "with", "around", "near", "next",
    "inside", "under", "above", "below", "this", "that", "these", "those", "it", "its", "any",
    "some", "colour", "color", "kind", "type", "room", "rooms", "house", "home"))
_ROOM_WORDS = frozenset(("kitchen", "bedroom", "bathroom", "hallway", "office", "dining",
                         "living", "guest", "laundry", "garage", "study", "corridor", "hall"))


def _words(text: str) -> set[str]:
    return {singular(w) for w in re.findall(r"[a-z]+", text.lower())}


_BEARING = r"(?:ahead|slightly left|slightly right|on the left|on the right)"
_NUMBERS = {w: n for n, w in enumerate(("zero", "one", "two", "three", "four", "five", "six",
                                        "seven", "eight", "nine"))} | {"a": 1, "an": 1}


@dataclass(frozen=True)
class Entry:
    """One "; "-separated entry of a frame text (``perception.semantic``'s format): ``noun`` the
    object's own words without count, article or state ("white cabinet"), ``count`` the number
    before it, ``support`` what it stands on or in, ``room`` the room it is in (the robot's
    when it names none), ``text`` the entry without its "with ... on it" clause."""

    noun: str
    count: int
    support: str | None
    room: str | None
    text: str


def parse_entry(entry: str, robot_room: str | None = None) -> Entry:
    parts = entry.strip().rstrip(".").split(", ")
    head, support = parts[0], None
    bearing = re.search(rf" {_BEARING}(?: to {_BEARING})?$", head)
    if bearing:
        head = head[:bearing.start()]
    else:  # "a cup on the brown table, ahead, ...": the bearing follows the support
        rel = re.search(r" (?:on|in) the ([a-z' ]+)$", head)
        if rel:
            support, head = rel.group(1), head[:rel.start()]
    head = re.sub(r" \((?:on|off|open|closed)\)$", "", head)
    first, _, rest = head.partition(" ")
    counted = first.lower() in _NUMBERS or first.isdigit()
    count = _NUMBERS.get(first.lower(), int(first) if first.isdigit() else 1)
    rooms = [p[len("in the "):] for p in parts[1:] if p.startswith("in the ")]
    return Entry(rest if counted else head, count, support, rooms[0] if rooms else robot_room,
                 ", ".join(p for p in parts if not p.startswith("with ")))


def _robot_room(head: str) -> str | None:
    m = re.match(r"you are in the ([a-z ]+)\.?$", head.strip().lower())
    return m.group(1) if m else None


def focus_views(question: str, views: Sequence[str], target: Target | None = None) -> list[str]:
    """Each text view cut to what the question names: its first sentence (where the robot is)
    and the "; "-separated entries whose own object the question names (``Target.is_a`` on
    the entry's words, not the furniture it stands on nor what stands on it), without their
    "with ... on it" clause, so the colour word before the object's name is its own. A small
    model reads a long list of objects badly ("a yellow refrigerator" among twelve entries is
    answered "grey"). Beyond the entries:

    - a question that names a room keeps the entries in that room when any is;
    - "What is on the X?": only entries of things standing on or in X;
    - "Where is X?": only the views that show X (one view of the lamp is not outvoted by four
      views of the room the robot stood in);
    - "How many X?": only the view that shows the most X (the same chairs are seen again from
      every pose; adding views up counts them twice).

    Views are returned unchanged when no entry of any view matches, or the question names no
    object (an existence question then gets ``absence_note``). ``target``: the question's
    target (default: ``parse_question``; an agent passes its own, with resolved aliases)."""
    target = target or parse_question(question)
    wanted = _words(question) - {singular(w) for w in _FUNCTION_WORDS | _ROOM_WORDS}
    things = target.things or tuple(sorted(wanted))
    if not wanted and not target.things:
        return list(views)
    q = question.strip().lower()
    surface = target.support if target.kind == "identification" else None
    room = target.room if len(target.rooms) == 1 else None
    kept: list[tuple[str, list[Entry]]] = []
    for view in views:
        head, _, rest = view.partition(". ")
        listed = rest.split(". ")[0]  # not "Through a doorway: ..."
        listed = listed.removeprefix("Visible: ").removeprefix("Seen: ")  # focused already
        entries = [parse_entry(e, _robot_room(head)) for e in listed.split("; ") if e]
        if surface:  # what stands on X, not X itself (a small model names the furniture)
            entries = [e for e in entries if e.support is not None
                       and (target.is_a(surface, e.support) or bool(_words(surface)
                                                                    & _words(e.support)))]
        else:
            entries = [e for e in entries if any(target.is_a(t, e.noun) for t in things)
                       or (not target.things and wanted & _words(e.noun))]
        kept.append((head, entries))
    if room is not None and any(e.room == room for _, es in kept for e in es):
        kept = [(h, [e for e in es if e.room in (room, None)]) for h, es in kept]
    if not any(es for _, es in kept):
        return list(views)
    if re.match(r"^where\b", q):
        kept = [(h, es) for h, es in kept if es]
    elif re.match(r"^how many\b", q) and target.object:
        def counted(es: list[Entry]) -> int:
            return sum(e.count for e in es if target.is_a(target.object, e.noun))
        best = max(range(len(kept)), key=lambda i: (counted(kept[i][1]), -i))
        kept = [kept[best]]
    return [head + "." + (" Seen: " + "; ".join(e.text for e in es) + "." if es
                          else " Nothing the question names.") for head, es in kept]


def absence_note(question: str, views: Sequence[str], target: Target | None = None) -> str:
    """For an existence question whose object no view lists in the room it names (or in any
    room, when it names none), a plain sentence that says so ("The robot looked in the living
    room and saw no armchair there: the answer is no."), so that a small model answers "no" (it
    said "Yes" to a prompt listing the room without the object, and to one listing a sofa of
    the room next door); "" otherwise. When the views never show the named room, the sentence
    says that instead and leaves the answer to the model. ``target`` as in ``focus_views``."""
    target = target or parse_question(question)
    if target.kind != "existence" or not target.object or len(target.rooms) > 1:
        return ""
    entries = [parse_entry(e, _robot_room(head)) for head, _, rest in
               (v.partition(". ") for v in views)
               for e in rest.split(". ")[0].removeprefix("Visible: ").split("; ") if e]
    room = target.room
    if any(target.is_a(target.object, e.noun) and (room is None or e.room == room)
           for e in entries):
        return ""
    if room is None:
        return f"The robot saw no {target.object}: the answer is no."
    seen = {_robot_room(v.partition(". ")[0]) for v in views} | {e.room for e in entries}
    if room in seen:
        return (f"The robot looked in the {room} and saw no {target.object} there: "
                f"the answer is no.")
    return f"The views do not show the {room}, and no {target.object} in it."


def count_note(question: str, views: Sequence[str], target: Target | None = None,
               counted: int | None = None) -> str:
    """For a count question, the count its one focused view lists, said as a number ("The
    view lists 5 chairs: the answer is 5."): the 1.5B model read "five blue chairs" as 4 and
    "a grey chair" as 2 (syn-107-02, syn-101-02). Entries in the named room only, when the
    question names one; "" when the views list none. ``target`` as in ``focus_views``.

    ``counted``: the count of the episode's instance map (``mapping.instances.asked_count``:
    each object once over all views, around the support asked about), which the note says
    instead where the view lists another number, or none (views that are images)."""
    target = target or parse_question(question)
    if target.kind != "count" or not target.object:
        return ""
    n = _view_count(question, views, target) if views else 0
    if counted is not None and counted > 0 and counted != n:
        place = f" around the {target.support}" if target.support else (
            f" in the {target.room}" if len(target.rooms) == 1 else "")
        return (f"Counting each one once over all its views, the robot saw {counted} "
                f"{_plural(target.object, counted)}{place}: the answer is {counted}.")
    if not n:
        return ""
    return f"The view lists {n} {_plural(target.object, n)}: the answer is {n}."


def _plural(noun: str, n: int) -> str:
    if n == 1:
        return noun
    return noun + ("es" if noun.endswith(("s", "sh", "ch", "x")) else "s")


def _view_count(question: str, views: Sequence[str], target: Target) -> int:
    """The count of the question's object that its one focused view lists (0: none)."""
    focused = focus_views(question, views, target)
    if len(focused) != 1:  # nothing matched: the views were left alone
        return 0
    head, _, rest = focused[0].partition(". ")
    entries = [parse_entry(e, _robot_room(head))
               for e in rest.removeprefix("Seen: ").rstrip(".").split("; ") if e]
    room = target.room if len(target.rooms) == 1 else None
    return sum(e.count for e in entries if target.is_a(target.object or "", e.noun)
               and (room is None or e.room in (room, None)))

