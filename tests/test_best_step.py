"""ExploreEQA's lazy best-step answer gives the answer of asking every frame, in fewer calls."""

import random

import pytest

from efficienteqa.answer.best_step import StepFrame, best_step_answer
from efficienteqa.vc.parse import AnswerResult


def _result(confidence: float) -> AnswerResult:
    return AnswerResult(f"answer {confidence}", confidence, [], [], [], "")


@pytest.mark.parametrize("seed", range(200))
def test_lazy_search_finds_the_step_asking_every_frame_finds(seed):
    rng = random.Random(seed)
    n = rng.randint(1, 30)
    # Ties on purpose: relevancies and confidences from small grids, some relevancies negative.
    sims = [rng.choice([-0.1, 0.0, 0.2, 0.4, 0.5, 0.5, 0.7, 0.9]) for _ in range(n)]
    confidences = {step: rng.choice([0.0, 0.25, 0.5, 1.0]) for step in range(1, n + 1)}
    candidates = [StepFrame(step, sim, f"frame {step}") for step, sim in enumerate(sims, 1)]
    calls: list[int] = []

    def ask(c):
        calls.append(c.step)
        return _result(confidences[c.step])

    lazy, asked = best_step_answer(candidates, ask)
    n_lazy = len(calls)
    eager, every = best_step_answer(candidates, ask, every_step=True)
    # The online rule, written out: the first step of the highest value.
    values = [max(s, 0.0) * confidences[step] for step, s in enumerate(sims, 1)]
    winner = values.index(max(values)) + 1
    assert eager.step == winner and len(every) == n
    assert (lazy.step, lazy.value, lazy.answer) == (eager.step, eager.value, eager.answer)
    assert n_lazy == len(asked) <= n


def test_lazy_search_stops_once_no_frame_can_win():
    candidates = [StepFrame(step, sim, step) for step, sim in enumerate([0.2, 0.9, 0.5, 0.8], 1)]
    best, asked = best_step_answer(candidates, lambda c: _result(0.95))
    # 0.9 x 0.95 = 0.855 beats the 0.8 frame's best case, so one call decides.
    assert best.step == 2 and [a.step for a in asked] == [2]


def test_no_frame_gives_no_answer_and_a_bad_confidence_is_an_error():
    assert best_step_answer([], lambda c: _result(1.0)) == (None, [])
    with pytest.raises(ValueError, match="not in"):
        best_step_answer([StepFrame(1, 0.5, None)], lambda c: _result(1.5))
