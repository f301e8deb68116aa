"""The model's reading of the question: one call per episode to the agent's own chat model (the
local Qwen2.5-Coder-1.5B offline; the same chat model with a VLM; the client's response cache
makes a repeated question free), asking for the target as JSON: kind, object, support, the rooms
named and, where none is named, the rooms such an object usually is in, most likely first.

Nothing of the reply is taken on trust. The object and the support must be words of the question
(after case, plural and one-letter typos: ``words_of``), the rooms canonical (``question.ROOMS``),
the kind one of ``question.KINDS``; a field that fails, or a reply that is no JSON, falls back to
the rules' field. The rooms the question names are the rules' (a named room is a word of the
question, and the room words are read exactly); the likely rooms come only from the model (the
rules have no prior, and the generator's catalogue is no prior for real homes).

The call reads the question only, never a frame, so it is the same for the semantic sensor, the
pixel perception and a VLM over images: with a VLM the one call goes to that VLM as text.
"""

from __future__ import annotations

import re
from dataclasses import replace
from typing import Any

from efficienteqa.models.base import ChatModel, Message
from efficienteqa.question import (
    KINDS,
    ROOMS,
    Target,
    canonical_room,
    parse_question,
    singular,
    thing_name,
)
from efficienteqa.vc.json_reply import json_reply
from efficienteqa.vc.prompts import load_prompt

PROMPTS = "efficienteqa.reading"  # reading/prompts/read.txt
READINGS = ("rules", "model", "rules+rooms")
MAX_TOKENS = 120  # a JSON object of five short fields
MAX_LIKELY = 4
SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "kind": {"type": "string", "enum": [*KINDS, "color"]},
        "object": {"type": ["string", "null"]},
        "support": {"type": ["string", "null"]},
        "rooms": {"type": "array", "items": {"type": "string"}},
        "usual_rooms": {"type": "array", "items": {"type": "string"}},
    },
    "required": ["kind", "object", "support", "rooms", "usual_rooms"],
}
_LEADING = re.compile(r"^(?:the|a|an|my|any|some|your|our)\s+")


class ModelReader:
    """``read(question)``: the target, from one call to ``model``, checked field by field
    against the rules' target. ``problems`` collects what could not be used, for the record."""

    def __init__(self, model: ChatModel, max_tokens: int = MAX_TOKENS) -> None:
        self.model, self.max_tokens = model, max_tokens
        self.problems: list[str] = []

    def read(self, question: str) -> Target:
        rules = parse_question(question)
        prompt = load_prompt("read", PROMPTS).format(rooms=", ".join(ROOMS), question=question)
        schema = SCHEMA if self.model.capabilities.json_schema else None
        reply = self.model.chat([Message("user", prompt)], max_tokens=self.max_tokens,
                                temperature=0.0, json_schema=schema).text or ""
        said, why = json_reply(reply)
        if said is None:
            self.problems.append(f"{why} in the reading {reply[:60]!r}: the rules' target")
            return rules
        return self.checked(question, said, rules)

    def checked(self, question: str, said: dict[str, Any], rules: Target) -> Target:
        """``rules`` with each field the model said that passes its check."""
        kind = str(said.get("kind") or "").strip().lower().replace("color", "colour")
        if kind not in KINDS:
            self.problems.append(f"kind {said.get('kind')!r} unknown: the rules' {rules.kind!r}")
            kind = rules.kind
        things = []
        for name in ("object", "support"):
            value, kept = said.get(name), getattr(rules, name)
            if value is not None and not isinstance(value, str):
                self.problems.append(f"{name} {value!r} is no text: the rules' {kept!r}")
            elif value is None or not value.strip():
                kept = None
            elif (words := words_of(value, question)) is None:
                self.problems.append(f"{name} {value!r} is not in the question: the rules' {kept!r}")
            elif canonical_room(words) is not None or thing_name(words) is None:
                self.problems.append(f"{name} {value!r} names no thing: the rules' {kept!r}")
            else:  # its thing's name only: "bed with green bedding" -> "bed"
                kept = thing_name(words)
            things.append(kept)
        obj, support = things
        if kind == "identification" and obj is not None and support is None:
            obj, support = None, obj  # "what is on the X": X is where to look
        if kind == "count" and obj is not None:
            obj = singular(obj)
        # the rooms such a thing usually is in, asked always (a 1.5B model leaves an optional
        # list empty), used only where the question names none
        likely = () if rules.rooms else _rooms(said.get("usual_rooms", said.get("likely_rooms")))
        return replace(rules, kind=kind, object=obj, support=support, likely_rooms=likely)


def words_of(phrase: str, question: str) -> str | None:
    """``phrase`` (lower case, without a leading article) when each of its words is a word of
    ``question`` after case, plural and one-letter typos ("bathtub" for "bathrub"); None when
    one is not."""
    phrase = _LEADING.sub("", " ".join(phrase.lower().split()))
    asked = {singular(w) for w in re.findall(r"[a-z0-9]+(?:['-][a-z0-9]+)*", question.lower())}
    words = re.findall(r"[a-z0-9]+(?:['-][a-z0-9]+)*", phrase)
    if not words:
        return None
    for word in words:
        w = singular(word)
        if w not in asked and not (len(w) >= 5 and any(_one_edit(w, a) for a in asked)):
            return None
    return phrase


def _one_edit(a: str, b: str) -> bool:
    """Whether ``a`` and ``b`` differ by one letter changed, added, dropped or two swapped."""
    if abs(len(a) - len(b)) > 1 or a == b:
        return a == b
    if len(a) == len(b):
        diff = [i for i in range(len(a)) if a[i] != b[i]]
        return len(diff) == 1 or (len(diff) == 2 and diff[1] == diff[0] + 1
                                  and a[diff[0]] == b[diff[1]] and a[diff[1]] == b[diff[0]])
    short, long_ = (a, b) if len(a) < len(b) else (b, a)
    return any(long_[:i] + long_[i + 1:] == short for i in range(len(long_)))


def _rooms(value: Any) -> tuple[str, ...]:
    """The canonical rooms of a list the model gave, in its order, unknown names dropped."""
    if not isinstance(value, list):
        return ()
    rooms = (canonical_room(v) for v in value if isinstance(v, str))
    return tuple(dict.fromkeys(r for r in rooms if r))[:MAX_LIKELY]
