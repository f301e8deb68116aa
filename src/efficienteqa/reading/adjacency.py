"""Which rooms a named room is usually next to: a prior on the house's layout from the language
model's general knowledge of homes (DESIGN 9), for steering while the named room is unseen.

One call per room type (``reading/prompts/near.txt``), asked once and kept for the agent's
life (the client's response cache keeps it across runs), so a vocabulary of a dozen rooms costs
a dozen calls in all. The reply's rooms must be canonical (``question.ROOMS``); the room itself
and unknown names are dropped. Nothing comes from the generator: its room programme and its
houses' layouts would score well on its own houses and mislead in a real home.

The call reads a room name only, never a frame: the same for every perception.
"""

from __future__ import annotations

from efficienteqa.models.base import ChatModel, Message
from efficienteqa.question import ROOMS, canonical_room
from efficienteqa.vc.json_reply import json_reply
from efficienteqa.vc.prompts import load_prompt

PROMPTS = "efficienteqa.reading"  # reading/prompts/near.txt
MAX_TOKENS = 60  # {"next_to": [three room names]}
MAX_NEAR = 3


class RoomAdjacency:
    """``near(room)``: the rooms ``room`` is usually next to or entered from, most likely
    first; () where the reply gives none. ``problems`` collects unusable replies."""

    def __init__(self, model: ChatModel) -> None:
        self.model = model
        self.problems: list[str] = []
        self._near: dict[str, tuple[str, ...]] = {}

    def near(self, room: str) -> tuple[str, ...]:
        if room not in self._near:
            self._near[room] = self._ask(room)
        return self._near[room]

    def _ask(self, room: str) -> tuple[str, ...]:
        prompt = load_prompt("near", PROMPTS).format(room=room, rooms=", ".join(ROOMS))
        reply = self.model.chat([Message("user", prompt)], max_tokens=MAX_TOKENS,
                                temperature=0.0).text or ""
        said, why = json_reply(reply)
        value = said.get("next_to") if said is not None else None
        if not isinstance(value, list):
            self.problems.append(f"{why or 'no next_to list'} in the rooms next to the {room} "
                                 f"{reply[:60]!r}: none")
            return ()
        rooms = (canonical_room(v) for v in value if isinstance(v, str))
        return tuple(dict.fromkeys(r for r in rooms if r and r != room))[:MAX_NEAR]
