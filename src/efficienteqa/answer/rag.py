"""RAG answering (DESIGN 3.5): the K most relevant frames of the whole history go to the model.

``TopK`` keeps the K best frames in a min-heap as the episode runs, so memory stays flat however
long the history grows; ``RagAnswerer`` asks the model for M candidate answers with verbalized
confidences, groups equivalent ones and returns the argmax (or, for the white-box baseline, one
greedy answer whose confidence is its token probability).
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Generic, Literal, TypeVar

import numpy as np

from efficienteqa.answer.calls import (
    ANSWER_PROBABILITY,
    TOKEN_ANSWER,
    answer_token_probability,
    answer_with_confidence,
    verbalized_token_probability,
)
from efficienteqa.models.base import ChatModel
from efficienteqa.question import Target
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


@dataclass(frozen=True)
class View:
    """Where a frame was taken (x, y metres, yaw radians) and, for text perception, what it
    said: enough to tell two frames that show the model the same thing."""

    x: float
    y: float
    yaw: float
    text: str | None = None


SAME_POSE_M = 0.25  # frames taken this close ...
SAME_YAW_DEG = 15.0  # ... and turned less than this apart show the same view


def same_view(a: View, b: View, pose_m: float = SAME_POSE_M, yaw_deg: float = SAME_YAW_DEG) -> bool:
    """Whether two frames are near-duplicates: the same pose (within ``pose_m`` and
    ``yaw_deg``), or the same description (the same objects at the same ranges, read by a text
    model as the same evidence)."""
    if a.text is not None and a.text == b.text:
        return True
    turn = abs((a.yaw - b.yaw + math.pi) % (2 * math.pi) - math.pi)
    return math.hypot(a.x - b.x, a.y - b.y) <= pose_m and math.degrees(turn) <= yaw_deg


class TopK(Generic[T]):
    """The ``k`` items of highest Sim seen so far. Ties keep the earlier step.

    Items pushed with a ``View`` are distinct views: a frame that ``same_view`` matches with
    one held replaces it when its Sim is higher and is dropped otherwise, so K retrieved frames
    are K different views (a robot that did not move between steps sends the model one frame,
    not three copies). Items pushed without a view are all kept, as DESIGN 3.5 reads."""

    def __init__(self, k: int = TOP_K) -> None:
        if k < 1:
            raise ValueError(f"top-K needs k >= 1, got {k}")
        self.k = k
        self._heap: list[tuple[float, int, int, Ranked[T]]] = []
        self._views: dict[int, View] = {}  # entry order -> its view
        self._order = itertools.count()

    def push(self, sim: float, step: int, item: T, view: View | None = None) -> None:
        # Among equal Sims the heap root is the latest step, so a later frame never evicts an
        # earlier one of the same relevancy.
        entry = (sim, -step, next(self._order), Ranked(sim, step, item))
        if view is not None:
            twin = next((e for e in self._heap if e[2] in self._views
                         and same_view(self._views[e[2]], view)), None)
            if twin is not None:
                if entry[:2] <= twin[:2]:
                    return  # the view held is as relevant: keep it
                self._heap.remove(twin)
                del self._views[twin[2]]
                heapq.heapify(self._heap)
            self._views[entry[2]] = view
        if len(self._heap) < self.k:
            heapq.heappush(self._heap, entry)
        elif entry[:2] > self._heap[0][:2]:
            dropped = heapq.heapreplace(self._heap, entry)
            self._views.pop(dropped[2], None)
        else:
            self._views.pop(entry[2], None)

    def best(self) -> list[Ranked[T]]:
        """Best first (highest Sim, then earliest step)."""
        return [e[3] for e in sorted(self._heap, key=lambda e: (-e[0], -e[1]))]

    def __len__(self) -> int:
        return len(self._heap)


class RagAnswerer:
    """Answer from retrieved evidence: frame descriptions (text models) or RGB frames (VLMs).

    ``direct`` (DESIGN 8, beyond the paper): one greedy answer to a prompt with a hint for the
    question's form, its confidence the answer's token probability, instead of DESIGN 3.5's M
    verbalized guesses; it needs a model that gives logprobs. ``probability``: how a token
    answer's confidence is read from its tokens (``answer.calls.ANSWER_PROBABILITIES``);
    ``token_prompt``: which prompt a token-confidence answer that is not direct asks
    (``answer.calls.TOKEN_ANSWERS``)."""

    def __init__(self, model: ChatModel, grouper: Grouper, m: int = M,
                 confidence: Confidence = "verbalized", direct: bool = False,
                 probability: str = ANSWER_PROBABILITY, token_prompt: str = TOKEN_ANSWER) -> None:
        self.model, self.grouper, self.m, self.confidence = model, grouper, m, confidence
        self.direct, self.probability, self.token_prompt = direct, probability, token_prompt

    def answer(self, question: str, evidence: Sequence[str | np.ndarray],
               target: Target | None = None, counted: int | None = None) -> AnswerResult:
        """The answer from ``evidence``, best first. Images beyond the server's cap per request
        (``capabilities.max_images``, probed) are cut, the least relevant first, and the answer's
        problems say so: a capped server would refuse the whole request. ``target``: the
        agent's reading of the question (with its aliases), for the direct answer's notes;
        ``counted``: a count question's count from the episode's instance map, which the
        direct answer is told (``answer.views.count_note``)."""
        evidence, cut = cut_to_cap(evidence, getattr(self.model.capabilities, "max_images", None))
        result = self._answer(question, evidence, target, counted)
        return replace(result, problems=[cut, *result.problems]) if cut else result

    def _answer(self, question: str, evidence: Sequence[str | np.ndarray],
                target: Target | None = None, counted: int | None = None) -> AnswerResult:
        if not self.direct and self.confidence == "token" and self.token_prompt == "verbalized":
            return verbalized_token_probability(self.model, question, evidence,
                                                how=self.probability)
        if self.direct or self.confidence == "token":
            return answer_token_probability(self.model, question, evidence, hinted=self.direct,
                                            how=self.probability, target=target,
                                            counted=counted)
        return answer_with_confidence(self.model, question, evidence, self.grouper, m=self.m)


def cut_to_cap(evidence: Sequence[str | np.ndarray], cap: int | None
               ) -> tuple[list[str | np.ndarray], str]:
    """``evidence`` (best first) with at most ``cap`` images, and a note when some were cut."""
    items = list(evidence)
    images = sum(isinstance(e, np.ndarray) for e in items)
    if cap is None or images <= cap:
        return items, ""
    kept, n = [], 0
    for e in items:
        if isinstance(e, np.ndarray):
            if n == cap:
                continue
            n += 1
        kept.append(e)
    return kept, f"images cut from {images} to {cap}: the server takes {cap} per request"
