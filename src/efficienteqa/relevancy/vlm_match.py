"""Relevancy asked of the chat model itself: P(the view shows what the question asks about).

The analogue of BLIP-2's image-text matching head (the probability of "match") for a back-end
that has no matching model: the agent's own (vision-)language model answers yes or no with a
verbalized confidence, read as P(yes) in [0, 1]. One short call per frame; its fixed
instructions come first, so a llama.cpp server reuses them between frames.

A reply with neither a yes/no nor a confidence (a refusal, "N/A", prose cut at ``max_tokens``)
scores NaN, "missing": the agent leaves such a frame out of the stop statistics and the
retrieval, and the gate does not pass it. Read as 0.5 it would stand far above a confident
"no" (0.1), become the outlier that stops the robot, and be retrieved first.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from efficienteqa.models.base import ChatModel, Message
from efficienteqa.relevancy.base import Modality, check_question, observation_of
from efficienteqa.vc.prompts import load_prompt
from efficienteqa.vc.yes_no import yes_no_confidence

PROMPTS = "efficienteqa.relevancy"  # relevancy/prompts/match.txt
# Room for "yes 80" after a short preamble ("Sure! The answer: yes 80"); a reply cut here is
# read as far as it goes.
MAX_TOKENS = 24


class VLMMatchScorer:
    """``modality`` "text" reads frame descriptions, "image" sends the RGB frame. ``problems``
    collects what could not be read, for the record."""

    def __init__(self, model: ChatModel, modality: Modality = "text",
                 max_tokens: int = MAX_TOKENS) -> None:
        self.model, self.modality, self.max_tokens = model, modality, max_tokens
        self.name = f"vlm-match:{model.name}"
        self.problems: list[str] = []

    def score(self, question: str, *, image: np.ndarray | None = None,
              text: str | None = None) -> float:
        """P(yes) in [0, 1], or NaN when the reply says neither yes nor no nor a number."""
        item = observation_of(self, image, text)
        view = item if isinstance(item, str) else "the image"
        images = () if isinstance(item, str) else (item,)
        prompt = load_prompt("match", PROMPTS).format(question=check_question(question), view=view)
        response = self.model.chat([Message("user", prompt, images)], max_tokens=self.max_tokens,
                                   temperature=0.0)
        reply = response.text or ""
        p_yes, problems = yes_no_confidence(reply)
        if math.isnan(p_yes):
            self.problems.append(f"unreadable reply {reply[:60]!r}: relevancy missing")
            return math.nan
        if response.finish_reason == "length":
            problems.append(f"reply cut at {self.max_tokens} tokens")
        self.problems += problems
        return p_yes

    def score_many(self, question: str, items: Sequence[np.ndarray | str]) -> np.ndarray:
        return np.array([self.score(question, text=item) if isinstance(item, str)
                         else self.score(question, image=item) for item in items], dtype=float)
