"""ExploreEQA's answer (DESIGN 3.6): the answer of the frame with the highest relevancy x confidence.

ExploreEQA asks the model at every step. Without an early stop nothing during exploration
depends on those answers, so they can be asked after it, lazily: frames in decreasing relevancy,
until no frame left can beat the best value found. A confidence is at most 1, so a frame's value
is at most its relevancy. The result is the one asking every frame gives, the earliest step on
ties included; only the number of model calls differs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

from efficienteqa.vc.parse import AnswerResult

T = TypeVar("T")


@dataclass(frozen=True)
class StepFrame(Generic[T]):
    """A valid frame of the episode: its step, relevancy ``Sim(I_t, Q)`` and what the model reads."""

    step: int
    sim: float
    item: T


@dataclass(frozen=True)
class StepAnswer:
    step: int
    sim: float
    answer: AnswerResult

    @property
    def value(self) -> float:
        """ExploreEQA's score of a step: max(Sim, 0) x confidence."""
        return max(self.sim, 0.0) * self.answer.confidence


def _beats(value: float, step: int, best: StepAnswer | None) -> bool:
    """Whether (value, step) wins over ``best``: a higher value, or the same at an earlier step."""
    return best is None or value > best.value or (value == best.value and step < best.step)


def best_step_answer(candidates: Sequence[StepFrame[T]], ask: Callable[[StepFrame[T]], AnswerResult],
                     *, every_step: bool = False) -> tuple[StepAnswer | None, list[StepAnswer]]:
    """The winning step's answer (None without candidates) and every answer asked, in the order
    asked. ``every_step`` asks each frame in step order, as ExploreEQA does online."""
    if every_step:
        order = sorted(candidates, key=lambda c: c.step)
    else:
        order = sorted(candidates, key=lambda c: (-max(c.sim, 0.0), c.step))
    best: StepAnswer | None = None
    asked: list[StepAnswer] = []
    for c in order:
        if not every_step and not _beats(max(c.sim, 0.0), c.step, best):
            break  # sorted: no later frame can beat the best either
        said = StepAnswer(c.step, c.sim, ask(c))
        if not 0.0 <= said.answer.confidence <= 1.0:
            raise ValueError(f"confidence {said.answer.confidence} of step {c.step} is not in [0, 1]")
        asked.append(said)
        if _beats(said.value, said.step, best):
            best = said
    return best, asked
