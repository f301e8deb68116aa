"""What the LLM-Match judge is asked, and in which mode: the modes (grade, yes-prob, openeqa)
and the default judge and mode, the prompts rendered from eval/prompts/*.txt, the settings of
OpenEQA's protocol, and the version hash of all of it that keys the cached grades.

Kept apart from the judge (``eval.judge``) because choosing a judge and its mode (``eval.plan``,
``eval.methods``, the CLI) needs none of the model calls or the cache, and because a changed
prompt must change ``prompt_version`` in one place.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.local.weights import DEFAULT_MODEL
from efficienteqa.vc.prompts import load_prompt

PROMPTS = "efficienteqa.eval"  # the judge's templates: eval/prompts/*.txt
REMINDER = "Reply with the score only: one whole number from 1 to 5, nothing else."


def render_prompt(question: str, reference: str, response: str, extra: Sequence[str] = (),
                  template: str = "judge") -> str:
    """The judge prompt: fixed instructions and examples first (llama.cpp reuses that prefix
    across calls), the question, the accepted answers and the response last."""
    answers = f"Correct answer: {reference.strip()}"
    accepted = [e.strip() for e in extra if e and e.strip()]
    if accepted:
        answers += "\nAlso accepted: " + "; ".join(accepted)
    return load_prompt(template, PROMPTS).format(question=question.strip(), answers=answers,
                                                 response=response)


JUDGE_MODES = ("grade", "yes-prob", "openeqa")
# openeqa: the protocol of OpenEQA's LLM-Match (its evaluation code and MMBench-style prompt,
# read, not copied): a prompt with three worked examples and the mark after "Your mark:", at
# temperature 0.2 with seed 1234 and at most 32 tokens, no rule grading first, the response cut
# after its last "." (where text follows it). Figures in this mode compare with OpenEQA-style
# ones; the project's own rubric (grade) and yes-prob do not.
OPENEQA_TEMPERATURE = 0.2
OPENEQA_SEED = 1234
OPENEQA_MAX_TOKENS = 32
# The judge of a run that names none (``eval.methods.default_judge``) and the mode of one that
# names none, for `efficienteqa eval`, `efficienteqa judge` and ``RunSpec`` alike: "auto",
# yes-prob for the local models (the published tables' judge: every judged run under results/
# is local:qwen2.5-coder-1.5b in yes-prob), grade for any other (the OpenEQA form).
DEFAULT_JUDGE = f"local:{DEFAULT_MODEL}"
DEFAULT_JUDGE_MODE = "auto"
# Every judge call is greedy, whatever the run's --temperature (the judge is built without it).
JUDGE_TEMPERATURE = 0.0


def judge_mode(mode: str, judge: str | None) -> str:
    """The mode ``mode`` names for the judge ``judge`` (a VLM spec, None for none): "auto" is
    yes-prob for local models, grade otherwise; an unknown mode is one error."""
    if mode == "auto":
        return "yes-prob" if (judge or "").startswith("local:") else "grade"
    if mode not in JUDGE_MODES:
        raise EfficientEQAError(f"unknown judge mode {mode!r}",
                                fix="use grade, yes-prob, openeqa or auto")
    return mode


# yes-prob: the templates asked, and how their P(yes) become one (see ``eval.judge``).
YES_PROMPTS = ("judge_same", "judge_correct")
YES_COMBINE = "geometric mean"


def prompt_version(mode: str = "grade") -> str:
    """A hash of everything the judge is told and of how its replies become a grade, so a
    changed prompt or mapping does not reuse old grades."""
    if mode == "openeqa":
        text = (f"{load_prompt('judge_openeqa', PROMPTS)}\n{OPENEQA_TEMPERATURE} {OPENEQA_SEED} "
                f"{OPENEQA_MAX_TOKENS}")
    else:
        text = (load_prompt("judge", PROMPTS) + "\n" + REMINDER if mode == "grade"
                else "\n".join([*(load_prompt(t, PROMPTS) for t in YES_PROMPTS), YES_COMBINE]))
    return hashlib.sha256(f"{mode}\n{text}".encode()).hexdigest()[:16]
