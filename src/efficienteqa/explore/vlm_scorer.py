"""Semantic values from a (vision-)language model (DESIGN 3.3, 3.6): the exploration call of
verbalized confidence (M lettered directions with confidences and "worth exploring?") and its
white-box counterpart read from token probabilities.

Text models (semantic perception) are asked both in one call: the view and the directions are
text, and the question of the view is the same with or without the directions listed.

Image models get two calls per prompted frame, as the paper specifies (DESIGN 3.3): the lettered
directions on the frame with the circles drawn (``explore_letters``; white-box:
``explore_choice``), and "is this direction worth exploring?" on the plain RGB frame
(``explore_worth``; white-box: ``explore_worth_token``), so the circles, which cover the floor
the robot would walk on, never hide what the GSV judges. The other way left
open, one call with both images (the unmarked one first, labelled), was not taken: no vision
model can be run here to measure whether it answers as well, and it would make the
exploration call the only one with two images and letters that refer to the second. The cost
is one more call per prompted step (the GSV prompt is short: the question and one image) and no
change for text models. Every configuration, ``--explore.prompts paper`` included, does this.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from efficienteqa.explore.module import SemanticScore
from efficienteqa.models.base import ChatModel, Message
from efficienteqa.observation import Observation, PromptPoint
from efficienteqa.perception.base import Perception
from efficienteqa.vc.grouping import ExactGrouper, group_answers
from efficienteqa.vc.logprobs import (
    TOP_LOGPROBS,
    letter_and_yes_probs,
    letter_probs_from_logprobs,
    letter_read,
    require_logprobs,
    yes_prob_from_logprobs,
    yes_prob_or_none,
)
from efficienteqa.vc.parse import DEFAULT_LETTERS, M, parse_letters
from efficienteqa.vc.prompts import load_prompt
from efficienteqa.vc.usage import usage_of
from efficienteqa.vc.yes_no import DEFAULT_P_YES, parse_worth_exploring

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
        if request.images and self.perception.modality == "image":
            plain = np.asarray(self.perception.frame(obs))
            return explore_image_scores(self.model, question, list(request.directions),
                                        request.images, plain, m=self.m,
                                        token=self.confidence == "token")
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
                                                  directions=directions_text(letters, descriptions))


def directions_text(letters: Sequence[str], descriptions: Mapping[str, str] | None) -> str:
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
    scores, problems, candidates = _letter_scores(question, raw, letters, m)
    p_yes, worth_problems = parse_worth_exploring(raw)
    return SemanticScore(scores, p_yes, {"raw": raw, "problems": problems + worth_problems,
                                         "candidates": candidates, "usage": usage_of(resp)})


def _letter_scores(question: str, raw: str, letters: Sequence[str], m: int
                   ) -> tuple[dict[str, float], list[str], list[tuple[str, float]]]:
    """The verbalized per-letter confidences of a reply, normalised over ``letters`` (uniform
    when none is usable), with the parse problems and the candidates as read."""
    parsed = parse_letters(raw, list(letters), m)
    problems = list(parsed.problems)
    classes = group_answers(question, parsed.candidates, ExactGrouper(), problems)
    mass = {c.text: c.confidence for c in classes}
    total = sum(mass.get(x, 0.0) for x in letters)
    if total <= 0:
        problems.append("no usable letter confidences: uniform")
    scores = {x: (mass.get(x, 0.0) / total if total > 0 else 1.0 / len(letters)) for x in letters}
    return scores, problems, [(c.text, c.confidence) for c in parsed.candidates]


def explore_token_scores(model: ChatModel, question: str, view: str,
                         directions: Mapping[str, str] | Sequence[str] | None = None,
                         images: Sequence[np.ndarray] | None = None) -> SemanticScore:
    """ExploreEQA's white-box reading (DESIGN 3.6): one greedy reply of two lines (a letter, then
    yes/no) with the top alternatives of every token. P(letter) is the softmax over the prompted
    letters at the first token of line 1 where any of them is among the alternatives (the LSV);
    P(yes) likewise over yes/no on the yes/no line (for the GSV). Uniform / ``DEFAULT_P_YES``
    when absent."""
    require_logprobs(model)
    letters = list(directions) if directions else list(DEFAULT_LETTERS)
    descriptions = directions if isinstance(directions, Mapping) else None
    prompt = load_prompt("explore_token", PROMPTS).format(
        question=question, view=view or ("the image" if images else "nothing visible"),
        directions=directions_text(letters, descriptions))
    resp = model.chat([Message("user", prompt, tuple(images or ()))], max_tokens=8,
                      temperature=0.0, logprobs=TOP_LOGPROBS)
    tokens = resp.logprobs or []
    problems = [] if tokens else ["no logprobs in the reply: uniform"]
    if tokens and not letter_read(tokens, letters, first_line=True):
        problems.append("no direction letter among the reply's top logprobs: uniform")
    scores, p_yes = letter_and_yes_probs(tokens, letters)
    return SemanticScore(scores, p_yes, {"raw": resp.text or "", "problems": problems,
                                         "candidates": sorted(scores.items(), key=lambda kv: -kv[1]),
                                         "usage": usage_of(resp)})


def explore_image_scores(model: ChatModel, question: str, letters: Sequence[str],
                         marked: Sequence[np.ndarray], plain: np.ndarray, *, m: int = M,
                         token: bool = False, max_tokens: int = 48) -> SemanticScore:
    """The exploration of an image model (DESIGN 3.3): the per-letter confidences from the frame
    with the lettered circles (``marked``), then P(worth exploring) from the plain frame, in a
    call of its own. ``token``: both read from token probabilities (the white-box baseline):
    the letter of a one-letter reply, and yes/no. ``info`` keeps both replies and usages."""
    letters = list(letters) or list(DEFAULT_LETTERS)
    directions = directions_text(letters, None)
    if token:
        require_logprobs(model)
        prompt = load_prompt("explore_choice", PROMPTS).format(
            question=question, view="the image", directions=directions)
        resp = model.chat([Message("user", prompt, tuple(marked))], max_tokens=1,
                          temperature=0.0, logprobs=TOP_LOGPROBS)
        problems = [] if resp.logprobs else ["no logprobs in the letter reply: uniform"]
        if resp.logprobs and not letter_read(resp.logprobs, letters):
            problems.append("no direction letter among the reply's top logprobs: uniform")
        scores = letter_probs_from_logprobs(resp.logprobs, letters)
        candidates = sorted(scores.items(), key=lambda kv: -kv[1])
    else:
        prompt = load_prompt("explore_letters", PROMPTS).format(
            question=question, view="the image", directions=directions)
        resp = model.chat([Message("user", prompt, tuple(marked))], max_tokens=max_tokens,
                          temperature=0.0)
        scores, problems, candidates = _letter_scores(question, resp.text or "", letters, m)
    p_yes, worth = worth_exploring(model, question, plain, token=token)
    return SemanticScore(scores, p_yes, {
        "raw": resp.text or "", "worth_raw": worth["raw"],
        "problems": problems + worth["problems"], "candidates": candidates,
        "usage": usage_of(resp), "worth_usage": worth["usage"]})


def worth_exploring(model: ChatModel, question: str, plain: np.ndarray, *, token: bool = False,
                    max_tokens: int = 16) -> tuple[float, dict[str, Any]]:
    """P(yes) for "is this view worth exploring?" asked on the unmarked frame ``plain`` (DESIGN
    3.3's GSV): verbalized (``parse_worth_exploring``), or with ``token`` read from the first
    reply token's yes/no probabilities (``DEFAULT_P_YES`` when neither is among them)."""
    name = "explore_worth_token" if token else "explore_worth"
    prompt = load_prompt(name, PROMPTS).format(question=question)
    message = [Message("user", prompt, (plain,))]
    if token:
        resp = model.chat(message, max_tokens=1, temperature=0.0, logprobs=TOP_LOGPROBS)
        p_yes = yes_prob_from_logprobs(resp.logprobs)
        problems = ([] if yes_prob_or_none(resp.logprobs) is not None else
                    [f"no yes/no among the worth-exploring reply's tokens: P(yes) = {DEFAULT_P_YES}"])
    else:
        resp = model.chat(message, max_tokens=max_tokens, temperature=0.0)
        p_yes, problems = parse_worth_exploring(resp.text or "")
    return p_yes, {"raw": resp.text or "", "problems": problems, "usage": usage_of(resp)}
