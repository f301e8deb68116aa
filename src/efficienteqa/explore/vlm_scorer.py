"""Semantic values from a (vision-)language model (SPEC 3.3, 3.6): the exploration call of
verbalized confidence (M lettered directions with confidences and "worth exploring?" in one
reply) and its white-box counterpart read from token probabilities."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from efficienteqa.explore.module import SemanticScore
from efficienteqa.models.base import ChatModel, Message
from efficienteqa.observation import Observation, PromptPoint
from efficienteqa.perception.base import Perception
from efficienteqa.vc.grouping import ExactGrouper, group_answers
from efficienteqa.vc.logprobs import TOP_LOGPROBS, letter_and_yes_probs, require_logprobs
from efficienteqa.vc.parse import DEFAULT_LETTERS, M, parse_letters, parse_worth_exploring
from efficienteqa.vc.prompts import load_prompt
from efficienteqa.vc.usage import usage_of

PROMPTS = "efficienteqa.explore"  # explore/prompts/*.txt


class VLMScorer:
    """The ``SemanticScorer`` of the agent: one VC call per prompted frame gives the per-letter
    LSV distribution and P(worth exploring) for the GSV. What the model reads (text or pixels)
    is the perception back-end's business. ``confidence="token"`` is the white-box baseline's
    reading: the same two values from token probabilities instead of words."""

    def __init__(self, model: ChatModel, perception: Perception, m: int = M,
                 confidence: str = "verbalized") -> None:
        self.model, self.perception, self.m, self.confidence = model, perception, m, confidence

    def score(self, obs: Observation, prompts: list[PromptPoint], question: str) -> SemanticScore:
        request = self.perception.explore_request(obs, prompts)
        if self.confidence == "token":
            return explore_token_scores(self.model, question, request.view, request.directions,
                                        request.images or None)
        return explore_scores(self.model, question, request.view, request.directions,
                              request.images or None, m=self.m)


def explore_prompt(question: str, view: str, letters: Sequence[str],
                   descriptions: Mapping[str, str] | None, m: int = M) -> str:
    """The exploration prompt. Its fixed part (instructions and example) comes first and the
    question next: llama.cpp reuses the evaluated prefix shared with the previous request, so
    within an episode only the view and the directions are new tokens."""
    return load_prompt("explore", PROMPTS).format(question=question, view=view,
                                                  directions=_directions_text(letters, descriptions))


def _directions_text(letters: Sequence[str], descriptions: Mapping[str, str] | None) -> str:
    """One line per lettered direction for text models; the letters alone for VLMs."""
    if descriptions:
        return "\n".join(f"{x}: {descriptions.get(x) or 'no description'}" for x in letters)
    return ", ".join(letters) + " (the lettered circles in the image)"


def explore_scores(model: ChatModel, question: str, view: str,
                   directions: Mapping[str, str] | Sequence[str] | None = None,
                   images: Sequence[np.ndarray] | None = None, *, m: int = M,
                   max_tokens: int = 48) -> SemanticScore:
    """One call: per-letter confidences (the LSV distribution, normalised over the prompted
    letters; uniform if none is readable) and P(worth exploring) for the GSV.

    ``directions``: letter -> description for text models, or just the letters for a VLM that
    reads them off ``images``; None means A, B, C. ``view``: the scene description, or empty
    with ``images`` ("the image" is used)."""
    letters = list(directions) if directions else list(DEFAULT_LETTERS)
    descriptions = directions if isinstance(directions, Mapping) else None
    view = view or ("the image" if images else "nothing visible")
    prompt = explore_prompt(question, view, letters, descriptions, m)
    resp = model.chat([Message("user", prompt, tuple(images or ()))], max_tokens=max_tokens,
                      temperature=0.0)
    raw = resp.text or ""
    parsed = parse_letters(raw, letters, m)
    problems = list(parsed.problems)
    classes = group_answers(question, parsed.candidates, ExactGrouper(), problems)
    mass = {c.text: c.confidence for c in classes}
    total = sum(mass.get(x, 0.0) for x in letters)
    if total <= 0:
        problems.append("no usable letter confidences: uniform")
    scores = {x: (mass.get(x, 0.0) / total if total > 0 else 1.0 / len(letters)) for x in letters}
    p_yes, worth_problems = parse_worth_exploring(raw)
    return SemanticScore(scores, p_yes, {"raw": raw, "problems": problems + worth_problems,
                                         "candidates": [(c.text, c.confidence) for c in parsed.candidates],
                                         "usage": usage_of(resp)})


def explore_token_scores(model: ChatModel, question: str, view: str,
                         directions: Mapping[str, str] | Sequence[str] | None = None,
                         images: Sequence[np.ndarray] | None = None) -> SemanticScore:
    """ExploreEQA's white-box reading (SPEC 3.6): one greedy reply of two lines (a letter, then
    yes/no) with the top alternatives of every token. P(letter) is the softmax over the prompted
    letters at the first token of line 1 where any of them is among the alternatives (the LSV);
    P(yes) likewise over yes/no on the yes/no line (for the GSV). Uniform / ``DEFAULT_P_YES``
    when absent."""
    require_logprobs(model)
    letters = list(directions) if directions else list(DEFAULT_LETTERS)
    descriptions = directions if isinstance(directions, Mapping) else None
    prompt = load_prompt("explore_token", PROMPTS).format(
        question=question, view=view or ("the image" if images else "nothing visible"),
        directions=_directions_text(letters, descriptions))
    resp = model.chat([Message("user", prompt, tuple(images or ()))], max_tokens=8,
                      temperature=0.0, logprobs=TOP_LOGPROBS)
    tokens = resp.logprobs or []
    problems = [] if tokens else ["no logprobs in the reply: uniform"]
    scores, p_yes = letter_and_yes_probs(tokens, letters)
    return SemanticScore(scores, p_yes, {"raw": resp.text or "", "problems": problems,
                                         "candidates": sorted(scores.items(), key=lambda kv: -kv[1]),
                                         "usage": usage_of(resp)})
