"""The Blind LLM baseline (DESIGN 3.6): the question only, no observations; the model must guess
when unsure. Open-ended: the same VC answer (M guesses -> group -> argmax) as the RAG answer.
Closed-set (HM-EQA's four choices): the letter with the highest token probability."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from efficienteqa.answer.calls import vc_answer
from efficienteqa.answer.prompting import PROMPTS, answer_example
from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import ChatModel, Message
from efficienteqa.vc.grouping import Grouper
from efficienteqa.vc.logprobs import TOP_LOGPROBS, letter_probs_from_logprobs, require_logprobs
from efficienteqa.vc.parse import CHOICE_LETTERS as LETTERS
from efficienteqa.vc.parse import AnswerResult, M
from efficienteqa.vc.prompts import load_prompt
from efficienteqa.vc.usage import usage_of


def blind_answer(model: ChatModel, question: str, grouper: Grouper, *, m: int = M,
                 max_tokens: int = 96) -> AnswerResult:
    """M guesses from the question alone (``answer/prompts/blind.txt``), grouped, argmax."""
    prompt = load_prompt("blind", PROMPTS).format(question=question, m=m, example=answer_example(question))
    return vc_answer(model, prompt, (), question, grouper, m, max_tokens)


@dataclass(frozen=True)
class ChoiceResult:
    """A closed-set answer: the chosen ``letter`` and its choice text, ``confidence`` = P(letter)
    normalised over the choices' letters (``letter_probs``), and what the model wrote."""

    letter: str
    answer: str
    confidence: float
    letter_probs: dict[str, float]
    problems: list[str]
    raw: str
    usage: dict[str, Any] = field(default_factory=dict)


def blind_choice(model: ChatModel, question: str, choices: Sequence[str], *,
                 max_tokens: int = 2) -> ChoiceResult:
    """The question and its lettered choices (``answer/prompts/blind_choices.txt``); the answer
    is the letter with the highest log-probability among the reply's top alternatives (the first
    position where any letter appears). Needs a model with token log-probabilities."""
    if not choices or len(choices) > len(LETTERS):
        raise EfficientEQAError(f"a closed-set question needs 1-{len(LETTERS)} choices, "
                                f"got {len(choices)}", fix="load the dataset with closed_set=True")
    require_logprobs(model)
    letters = list(LETTERS[:len(choices)])
    listed = "\n".join(f"{x}) {c}" for x, c in zip(letters, choices))
    prompt = load_prompt("blind_choices", PROMPTS).format(question=question, choices=listed)
    resp = model.chat([Message("user", prompt)], max_tokens=max_tokens, temperature=0.0,
                      logprobs=TOP_LOGPROBS)
    problems: list[str] = []
    if not resp.logprobs:
        problems.append("no logprobs in the reply: every letter equally likely")
    probs = letter_probs_from_logprobs(resp.logprobs, letters)
    if resp.logprobs and len(set(probs.values())) == 1 and len(letters) > 1:
        problems.append("no letter among the top log-probabilities: every letter equally likely")
    letter = max(letters, key=lambda x: probs[x])  # ties: the first letter
    return ChoiceResult(letter, choices[letters.index(letter)], probs[letter], probs, problems,
                        resp.text or "", usage_of(resp))
