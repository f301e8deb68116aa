"""RAG answering (SPEC 3.5): the K most relevant frames of the whole history go to the model.

``TopK`` keeps the K best frames in a min-heap as the episode runs, so memory stays flat however
long the history grows; ``RagAnswerer`` asks the model for M candidate answers with verbalized
confidences, groups equivalent ones and returns the argmax (or, for the white-box baseline, one
greedy answer whose confidence is its token probability).
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Generic, Literal, TypeVar

import numpy as np

from efficienteqa.answer.vc import answer_token_probability, answer_with_confidence
from efficienteqa.models.base import ChatModel
from efficienteqa.vc.grouping import Grouper
from efficienteqa.vc.parse import AnswerResult, M

T = TypeVar("T")
TOP_K = 5
# How a model's confidence is read: asked for in words (black-box), or from token probabilities.
Confidence = Literal["verbalized", "token"]


@dataclass(frozen=True)
class Ranked(Generic[T]):
    sim: float
    step: int
    item: T


class TopK(Generic[T]):
    """The ``k`` items of highest Sim seen so far. Ties keep the earlier step."""

    def __init__(self, k: int = TOP_K) -> None:
        if k < 1:
            raise ValueError(f"top-K needs k >= 1, got {k}")
        self.k = k
        self._heap: list[tuple[float, int, int, Ranked[T]]] = []
        self._order = itertools.count()

    def push(self, sim: float, step: int, item: T) -> None:
        # Among equal Sims the heap root is the latest step, so a later frame never evicts an
        # earlier one of the same relevancy.
        entry = (sim, -step, next(self._order), Ranked(sim, step, item))
        if len(self._heap) < self.k:
            heapq.heappush(self._heap, entry)
        elif entry[:2] > self._heap[0][:2]:
            heapq.heapreplace(self._heap, entry)

    def best(self) -> list[Ranked[T]]:
        """Best first (highest Sim, then earliest step)."""
        return [e[3] for e in sorted(self._heap, key=lambda e: (-e[0], -e[1]))]

    def __len__(self) -> int:
        return len(self._heap)


class RagAnswerer:
    """Answer from retrieved evidence: frame descriptions (text models) or RGB frames (VLMs)."""

    def __init__(self, model: ChatModel, grouper: Grouper, m: int = M,
                 confidence: Confidence = "verbalized") -> None:
        self.model, self.grouper, self.m, self.confidence = model, grouper, m, confidence

    def answer(self, question: str, evidence: Sequence[str | np.ndarray]) -> AnswerResult:
        if self.confidence == "token":
            return answer_token_probability(self.model, question, evidence)
        return answer_with_confidence(self.model, question, evidence, self.grouper, m=self.m)
