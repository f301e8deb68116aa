"""Scripted chat models for agent tests: they read the prompts the agent sends (semantic-sensor
text) and reply in the formats of the templates in ``explore/prompts`` and ``answer/prompts``;
deterministic, no server."""

from __future__ import annotations

import re
import zlib

import numpy as np

from efficienteqa.models.base import Message
from efficienteqa.models.stub import StubChatModel


def _directions(prompt: str) -> dict[str, str]:
    block = prompt.split("Directions:\n", 1)[1]
    return {line[0]: line[2:].lower() for line in block.splitlines() if re.match(r"^[A-Z]:", line)}


def _answer_from_views(prompt: str, noun: str) -> str | None:
    """The colour word in front of ``noun`` in any retrieved view ("a blue sofa" -> blue)."""
    views = prompt.split("What it saw:\n", 1)[1]
    match = re.search(rf"\b(?:a|an|two|three) (\w+) {re.escape(noun)}\b", views)
    return match.group(1) if match else None


def _bare(prompt: str) -> bool:
    """Whether an answer prompt asks for the answer alone (the direct and token answers), not
    for M guesses with confidences."""
    return "Reply with the answer only" in prompt


def _pick_direction(prompt: str, noun: str, room: str) -> str:
    """The direction that mentions ``noun``, else ``room``, else the first letter."""
    dirs = _directions(prompt)
    return (next((k for k, d in dirs.items() if noun in d), None)
            or next((k for k, d in dirs.items() if room in d), None) or min(dirs))


def seeking_model(noun: str, room: str) -> StubChatModel:
    """Points at the direction that mentions ``noun`` (else ``room``), and answers a colour
    question about ``noun`` from the retrieved views: what a good VLM would do."""

    def reply(messages: list[Message]) -> str:
        prompt = messages[-1].text
        if prompt.startswith("You guide a robot"):
            return f"{_pick_direction(prompt, noun, room)}: 90\nworth exploring: yes 90"
        if prompt.startswith("A robot explored a home"):
            colour = _answer_from_views(prompt, noun)
            if _bare(prompt):  # the direct answer
                return colour or "unknown"
            return f"{colour}; 90\nunknown; 5\ngrey; 5" if colour else "unknown; 100\ngrey; 1\nred; 1"
        return "no"  # grouping: keep answers apart

    return StubChatModel(reply, name="seeking-stub")


def averse_model(noun: str, room: str) -> StubChatModel:
    """Points away from ``noun`` and ``room`` and says nothing is worth exploring; never knows."""

    def reply(messages: list[Message]) -> str:
        prompt = messages[-1].text
        if prompt.startswith("You guide a robot"):
            dirs = _directions(prompt)
            worst = next((k for k, d in sorted(dirs.items(), reverse=True)
                          if noun not in d and room not in d), max(dirs))
            return f"{worst}: 100\nworth exploring: no 100"
        if prompt.startswith("A robot explored a home"):
            return "unknown" if _bare(prompt) else "unknown; 100\ngrey; 1\nred; 1"
        return "no"

    return StubChatModel(reply, name="averse-stub")


class MentionScorer:
    """A text relevancy stand-in: Sim = 1 when a frame's description names every one of
    ``words``, else a small deterministic value from the text (so sigma > 0)."""

    name = "mention-stub"
    modality = "text"

    def __init__(self, *words: str) -> None:
        self.words = words

    def score(self, question: str, *, image=None, text: str | None = None) -> float:  # noqa: ANN001
        return float(self.score_many(question, [text or ""])[0])

    def score_many(self, question: str, items) -> np.ndarray:  # noqa: ANN001
        out = []
        for text in items:
            if all(w in text for w in self.words):
                out.append(1.0)
            else:
                out.append(0.1 + 0.05 * (zlib.crc32(text.encode()) % 1000) / 1000)
        return np.array(out)


def token_seeking_model(noun: str, room: str) -> StubChatModel:
    """``seeking_model`` for the white-box prompts: a letter and yes/no on two lines, and a bare
    answer; the stub's logprobs make each said word 90% likely."""

    def reply(messages: list[Message]) -> str:
        prompt = messages[-1].text
        if prompt.startswith("You guide a robot"):
            return f"{_pick_direction(prompt, noun, room)}\nyes"
        if prompt.startswith("A robot explored a home"):
            return _answer_from_views(prompt, noun) or "I cannot tell"
        return "no"

    return StubChatModel(reply, name="token-seeking-stub")
