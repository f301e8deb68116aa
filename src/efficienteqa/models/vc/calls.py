"""The model calls of verbalized confidence, and token probabilities for white-box baselines."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.module import SemanticScore
from efficienteqa.models.base import ChatModel, ChatResponse, Message, TokenLogprob
from efficienteqa.models.vc.grouping import ExactGrouper, Grouper, argmax, group_answers, normalise
from efficienteqa.models.vc.parse import (
    DEFAULT_LETTERS,
    DEFAULT_P_YES,
    AnswerClass,
    AnswerResult,
    Candidate,
    M,
    _to_float,
    parse_candidates,
    parse_letters,
    parse_worth_exploring,
)
from efficienteqa.models.vc.prompts import answer_example, load_prompt

# ---------------------------------------------------------------------------- the model calls

def _usage(resp: ChatResponse) -> dict[str, Any]:
    return {"model": getattr(resp, "model", ""), "prompt_tokens": getattr(resp, "prompt_tokens", 0),
            "completion_tokens": getattr(resp, "completion_tokens", 0),
            "latency_s": getattr(resp, "latency_s", 0.0), "cached": getattr(resp, "cached", False)}


def explore_prompt(question: str, view: str, letters: Sequence[str],
                   descriptions: Mapping[str, str] | None, m: int = M) -> str:
    """The exploration prompt. Its fixed part (instructions and example) comes first and the
    question next: llama.cpp reuses the evaluated prefix shared with the previous request, so
    within an episode only the view and the directions are new tokens."""
    return load_prompt("explore").format(question=question, view=view,
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
                                         "usage": _usage(resp)})


def _vc_answer(model: ChatModel, prompt: str, images: tuple[np.ndarray, ...], question: str,
               grouper: Grouper, m: int, max_tokens: int) -> AnswerResult:
    resp = model.chat([Message("user", prompt, images)], max_tokens=max_tokens, temperature=0.0)
    raw = resp.text or ""
    parsed = parse_candidates(raw, m)
    problems = list(parsed.problems)
    classes = group_answers(question, parsed.candidates, grouper, problems)
    answer, confidence = argmax(classes)
    if m == 1 and len(parsed.candidates) == 1:
        # One guess (ExploreEQA's per-step answer): normalising would make every confidence 1,
        # so its own verbalized confidence (0-100) is the confidence.
        confidence = min(max(parsed.candidates[0].confidence / 100.0, 0.0), 1.0)
    return AnswerResult(answer, confidence, classes, normalise(parsed.candidates), problems, raw,
                        _usage(resp))


def answer_with_confidence(model: ChatModel, question: str, evidence: Sequence[str] | Sequence[np.ndarray],
                           grouper: Grouper, *, m: int = M, max_tokens: int = 96) -> AnswerResult:
    """The RAG answer (SPEC 3.5): ``evidence`` is the top-K frame descriptions (best first) or
    the top-K RGB frames; M guesses -> normalise -> group -> argmax."""
    text, images = _evidence_text(evidence)
    prompt = load_prompt("answer").format(question=question, evidence=text, m=m,
                                          example=answer_example(question))
    return _vc_answer(model, prompt, images, question, grouper, m, max_tokens)


def _evidence_text(evidence: Sequence[str] | Sequence[np.ndarray]) -> tuple[str, tuple[np.ndarray, ...]]:
    """The evidence as prompt text, and the images to attach (for VLMs)."""
    items = list(evidence)
    if items and all(isinstance(e, str) for e in items):
        return "\n".join(f"view {i + 1}: {e}" for i, e in enumerate(items)), ()
    images = tuple(e for e in items if isinstance(e, np.ndarray))
    return (f"the {len(images)} attached images" if images else "nothing"), images


def blind_answer(model: ChatModel, question: str, grouper: Grouper, *, m: int = M,
                 max_tokens: int = 96) -> AnswerResult:
    """The Blind LLM baseline (SPEC 3.6): the question only; the model guesses when unsure."""
    prompt = load_prompt("blind").format(question=question, m=m, example=answer_example(question))
    return _vc_answer(model, prompt, (), question, grouper, m, max_tokens)


# ---------------------------------------------------------------------------- token probabilities

LogprobInput = TokenLogprob | Sequence[TokenLogprob] | Sequence[tuple[str, float]] | Mapping[str, float]


def _positions(top: LogprobInput | None) -> list[list[tuple[str, float]]]:
    if top is None:
        return []
    if isinstance(top, Mapping):
        return [list(top.items())]
    if isinstance(top, TokenLogprob):
        top = [top]
    out: list[list[tuple[str, float]]] = []
    flat: list[tuple[str, float]] = []
    for item in top:
        if isinstance(item, TokenLogprob):
            alts = list(item.top)
            if all(t != item.token for t, _ in alts):
                alts.append((item.token, item.logprob))
            out.append(alts)
        elif isinstance(item, (tuple, list)) and len(item) == 2:
            flat.append((item[0], item[1]))
    return out + ([flat] if flat else [])


def _token_key(token: object) -> str:
    return str(token).replace("Ġ", " ").replace("▁", " ").strip().strip("()[]{}.:,*\"'").upper()


def _softmax_first(top: LogprobInput | None, allowed: Sequence[str]) -> dict[str, float] | None:
    """Softmax over ``allowed`` keys at the first position whose alternatives include one."""
    for alts in _positions(top):
        mass: dict[str, float] = {}
        for tok, lp in alts:
            key, value = _token_key(tok), _to_float(lp)
            if key in allowed and value is not None and math.isfinite(value):
                mass[key] = float(np.logaddexp(mass[key], value)) if key in mass else value
        if mass:
            hi = max(mass.values())
            exp = {k: math.exp(v - hi) for k, v in mass.items()}
            total = sum(exp.values())
            return {k: exp.get(k, 0.0) / total for k in allowed}
    return None


def letter_probs_from_logprobs(top_logprobs: LogprobInput | None, letters: Sequence[str]
                               ) -> dict[str, float]:
    """P(letter) from token log-probabilities, softmax-normalised over ``letters`` (tokens
    matched ignoring case, spaces and brackets); uniform when no letter is among them."""
    keys = [str(x).strip().upper() for x in letters]
    probs = _softmax_first(top_logprobs, keys)
    if not letters:
        return {}
    return {x: (probs[k] if probs else 1.0 / len(letters)) for x, k in zip(letters, keys)}


def yes_prob_from_logprobs(top_logprobs: LogprobInput | None) -> float:
    """P(yes) over {yes, no} from token log-probabilities; ``DEFAULT_P_YES`` when neither is there."""
    probs = _softmax_first(top_logprobs, ["YES", "NO"])
    return probs["YES"] if probs else DEFAULT_P_YES


# ---------------------------------------------------------------------------- white-box calls
# ExploreEQA's white-box variant (SPEC 3.6) reads confidence from token probabilities instead of
# asking for it: one greedy reply, with the top alternatives of every generated token.

TOP_LOGPROBS = 10


def require_logprobs(model: ChatModel) -> None:
    if not model.capabilities.logprobs:
        raise EfficientEQAError(f"model {model.name!r} does not return token log-probabilities",
                                fix="use explore-eqa-blackbox (verbalized confidence), or a server "
                                    "that gives logprobs (llama.cpp, vLLM)")


def explore_token_scores(model: ChatModel, question: str, view: str,
                         directions: Mapping[str, str] | Sequence[str] | None = None,
                         images: Sequence[np.ndarray] | None = None) -> SemanticScore:
    """One call, two lines (a letter, then yes/no): P(letter) is the softmax over the prompted
    letters at the first token where any of them is among the alternatives (the LSV); P(yes)
    likewise over yes/no (for the GSV). Uniform / ``DEFAULT_P_YES`` when absent."""
    require_logprobs(model)
    letters = list(directions) if directions else list(DEFAULT_LETTERS)
    descriptions = directions if isinstance(directions, Mapping) else None
    prompt = load_prompt("explore_token").format(
        question=question, view=view or ("the image" if images else "nothing visible"),
        directions=_directions_text(letters, descriptions))
    resp = model.chat([Message("user", prompt, tuple(images or ()))], max_tokens=8,
                      temperature=0.0, logprobs=TOP_LOGPROBS)
    tokens = resp.logprobs or []
    problems = [] if tokens else ["no logprobs in the reply: uniform"]
    scores = letter_probs_from_logprobs(tokens, letters)
    p_yes = yes_prob_from_logprobs(tokens)
    return SemanticScore(scores, p_yes, {"raw": resp.text or "", "problems": problems,
                                         "candidates": sorted(scores.items(), key=lambda kv: -kv[1]),
                                         "usage": _usage(resp)})


def answer_token_probability(model: ChatModel, question: str,
                             evidence: Sequence[str] | Sequence[np.ndarray], *,
                             max_tokens: int = 24) -> AnswerResult:
    """A short greedy answer; its confidence (0-1, as VC's after normalising) is the model's
    probability of that answer: the product of its tokens' probabilities, first line only."""
    require_logprobs(model)
    text, images = _evidence_text(evidence)
    prompt = load_prompt("answer_token").format(question=question, evidence=text)
    resp = model.chat([Message("user", prompt, images)], max_tokens=max_tokens, temperature=0.0,
                      logprobs=1)
    raw = resp.text or ""
    problems: list[str] = []
    logprob, started = 0.0, False
    for token in resp.logprobs or []:
        if not started and not token.token.strip():
            continue  # leading whitespace is not part of the answer (``raw.strip()``)
        if started and "\n" in token.token:
            break  # the first line is the answer
        started = True
        if math.isfinite(token.logprob):
            logprob += token.logprob
    if not resp.logprobs:
        problems.append("no logprobs in the reply: confidence 0")
    answer = raw.strip().splitlines()[0].strip() if raw.strip() else ""
    if not answer:
        problems.append("empty answer")
    confidence = math.exp(logprob) if resp.logprobs and answer else 0.0
    candidates = [Candidate(answer, confidence)] if answer else []
    classes = [AnswerClass(answer, candidates, confidence)] if answer else []
    return AnswerResult(answer, confidence, classes, candidates, problems, raw, _usage(resp))
