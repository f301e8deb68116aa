"""Relevancy asked of the chat model itself: P(the view shows what the question asks about).

The analogue of BLIP-2's image-text matching head (the probability of "match") for a back-end
that has no matching model: the agent's own (vision-)language model answers yes or no with a
verbalized confidence, read as P(yes) in [0, 1]. One short call per frame; its fixed
instructions come first, so a llama.cpp server reuses them between frames.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from efficienteqa.models.base import ChatModel, Message
from efficienteqa.relevancy.base import Modality, check_question, observation_of
from efficienteqa.vc.parse import parse_worth_exploring
from efficienteqa.vc.prompts import load_prompt

PROMPTS = "efficienteqa.relevancy"  # relevancy/prompts/match.txt


class VLMMatchScorer:
    """``modality`` "text" reads frame descriptions, "image" sends the RGB frame."""

    def __init__(self, model: ChatModel, modality: Modality = "text", max_tokens: int = 8) -> None:
        self.model, self.modality, self.max_tokens = model, modality, max_tokens
        self.name = f"vlm-match:{model.name}"
        self.problems: list[str] = []  # unreadable replies, for the record

    def score(self, question: str, *, image: np.ndarray | None = None,
              text: str | None = None) -> float:
        item = observation_of(self, image, text)
        view = item if isinstance(item, str) else "the image"
        images = () if isinstance(item, str) else (item,)
        prompt = load_prompt("match", PROMPTS).format(question=check_question(question), view=view)
        reply = self.model.chat([Message("user", prompt, images)], max_tokens=self.max_tokens,
                                temperature=0.0).text or ""
        p_yes, problems = parse_worth_exploring(reply)
        self.problems += problems
        return float(p_yes)

    def score_many(self, question: str, items: Sequence[np.ndarray | str]) -> np.ndarray:
        return np.array([self.score(question, text=item) if isinstance(item, str)
                         else self.score(question, image=item) for item in items], dtype=float)
