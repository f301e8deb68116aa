"""The answer module's model calls (``calls``: what it asks a model; apart from the ``vc`` package).

The answer with its confidence (DESIGN 3.5, 3.6): the prompt with its hint for the question's
form, then M guesses with verbalized confidences -> normalise -> group -> argmax, or, for the
white-box baseline, one greedy answer whose confidence is its token probability. ``evidence``
is the top-K frame descriptions (best first) or the top-K RGB frames.

The prompts are built in ``answer.prompting``; the direct answer's views are cut to what the
question names in ``answer.views``."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from efficienteqa.answer.prompting import PROMPTS, answer_example, evidence_text, question_hint
from efficienteqa.answer.views import absence_note, count_note, focus_views
from efficienteqa.models.base import ChatModel, ChatResponse, Message
from efficienteqa.question import Target
from efficienteqa.vc.grouping import Grouper, argmax, group_answers, normalise
from efficienteqa.vc.logprobs import require_logprobs
from efficienteqa.vc.numbers import to_float
from efficienteqa.vc.parse import (
    AnswerClass,
    AnswerResult,
    Candidate,
    M,
    clean_answer,
    parse_candidates,
)
from efficienteqa.vc.prompts import load_prompt
from efficienteqa.vc.usage import usage_of


def vc_answer(model: ChatModel, prompt: str, images: tuple[np.ndarray, ...], question: str,
              grouper: Grouper, m: int, max_tokens: int) -> AnswerResult:
    """One VC call: the reply's M candidates -> normalise -> group -> argmax ``(R*, C*)``."""
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
                        usage_of(resp))


def answer_with_confidence(model: ChatModel, question: str, evidence: Sequence[str | np.ndarray],
                           grouper: Grouper, *, m: int = M, max_tokens: int = 96) -> AnswerResult:
    """The RAG answer (DESIGN 3.5): M guesses -> normalise -> group -> argmax."""
    prompt, images = _verbalized_prompt(question, evidence, m)
    return vc_answer(model, prompt, images, question, grouper, m, max_tokens)


def _verbalized_prompt(question: str, evidence: Sequence[str | np.ndarray],
                       m: int) -> tuple[str, tuple[np.ndarray, ...]]:
    """DESIGN 3.5's answer prompt for ``m`` guesses, with a worked example of the question's form."""
    text, images = evidence_text(evidence)
    prompt = load_prompt("answer", PROMPTS).format(question=question, evidence=text, m=m,
                                                   example=answer_example(question))
    return prompt, images


# How an answer's token probabilities make its confidence: "product", the probability of the
# whole answer (the default), or "per-token", their geometric mean (length-normalised: a long
# answer is not less sure for having more tokens).
ANSWER_PROBABILITY = "product"  # the default, AgentConfig.answer_probability's
ANSWER_PROBABILITIES = (ANSWER_PROBABILITY, "per-token")
# The prompt of a token-probability answer that is not the direct one (white-box ExploreEQA's
# per-frame answer): "short", one line (``answer_token``), or "verbalized", DESIGN 3.5's prompt
# with one guess, the black-box answer's (``verbalized_token_probability``).
TOKEN_ANSWER = "short"  # the default, AgentConfig.token_answer's
TOKEN_ANSWERS = (TOKEN_ANSWER, "verbalized")


def answer_token_probability(model: ChatModel, question: str,
                             evidence: Sequence[str | np.ndarray], *, hinted: bool = False,
                             max_tokens: int = 24, how: str = ANSWER_PROBABILITY,
                             target: Target | None = None,
                             counted: int | None = None) -> AnswerResult:
    """A short greedy answer; its confidence (0-1, as VC's after normalising) is the model's
    probability of that answer: the product of its tokens' probabilities, first line only
    (``how="per-token"``: their geometric mean, ``ANSWER_PROBABILITIES``). A token at -inf or
    with an unreadable (NaN) logprob makes it 0; positive logprobs (rounding) count as
    probability 1. ``hinted``: the direct answer (DESIGN 8), whose prompt adds the hint of the
    question's form (``question_hint``) and reads text views cut to what the question names
    (``focus_views``); ``target``: the agent's reading of the question, so the notes match its
    words as the gate and the steering do (an alias: "couch" is the sofa the views list);
    ``counted``: a count question's count from the episode's instance map (``count_note``),
    told to the direct answer over text views and images alike."""
    _check_how(how)
    require_logprobs(model)
    note = ""
    if hinted and evidence and all(isinstance(e, str) for e in evidence):
        views = [str(e) for e in evidence]
        note = (absence_note(question, views, target)
                or count_note(question, views, target, counted))
        evidence = focus_views(question, views, target)
    elif hinted and counted is not None:  # images: the map's count, said as a number
        note = count_note(question, [], target, counted)
    text, images = evidence_text(evidence)
    template = load_prompt("answer_direct" if hinted else "answer_token", PROMPTS)
    hint = question_hint(question, "image" if images else "text")
    prompt = template.format(question=question, evidence=text,
                             hint=f"{note}\n{hint}" if note else hint)
    if images:  # a VLM server may write a sentence or a code fence before the answer
        max_tokens = max(max_tokens, IMAGE_ANSWER_TOKENS)
    resp = model.chat([Message("user", prompt, images)], max_tokens=max_tokens, temperature=0.0,
                      logprobs=1)
    answer, line = reply_answer(resp.text or "")
    return _token_answer(resp, answer, how, end="\n", skip_lines=line)


# Room for a chatty VLM's preamble or code fence before a one-line answer over images.
IMAGE_ANSWER_TOKENS = 96
# A line that introduces the answer rather than giving it ("Sure! Here is my answer.").
_PREAMBLE = re.compile(r"^(?:sure|okay|ok|certainly|of course|here\b|based on|looking at|let me|"
                       r"from (?:the|what)|i (?:can|see|think|looked|will))", re.IGNORECASE)
_INTRODUCES = re.compile(r"\b(?:(?:let me|i will|i'll) answer|here is (?:my|the) answer|"
                         r"requested format)\b", re.IGNORECASE)
_ANSWER_LINE = re.compile(r"^(?:final )?answer\s*[:\-]\s*(.+)$", re.IGNORECASE)


def reply_answer(raw: str) -> tuple[str, int]:
    """The answer of a reply to a one-line answer prompt, cleaned of markup
    (``vc.parse.clean_answer``), and the index of the reply's line that holds it: an "answer"
    field of a JSON object, an "Answer: ..." line, else the first line that does not introduce
    the answer ("Sure! Here is my answer.", "... Let me answer in the requested format.") when
    more lines follow. A one-line reply is its own answer."""
    lines = raw.split("\n")
    body = [(i, line.strip()) for i, line in enumerate(lines)
            if line.strip() and not line.strip().startswith("```")]
    if not body:
        return "", 0
    if "{" in raw:
        try:
            data = json.loads(raw[raw.index("{"):raw.rindex("}") + 1])
        except ValueError:
            data = None
        if isinstance(data, dict) and isinstance(data.get("answer"), str):
            line = next((i for i, text in body if '"answer"' in text), body[0][0])
            return clean_answer(data["answer"]), line
    for i, text in body:
        said = _ANSWER_LINE.match(text)
        if said:
            return clean_answer(said.group(1)), i
    for n, (i, text) in enumerate(body):
        if n == len(body) - 1 or not (_PREAMBLE.match(text) or _INTRODUCES.search(text)
                                      or text.endswith(":")):
            return clean_answer(text), i
    raise AssertionError("the last line is always taken")


def verbalized_token_probability(model: ChatModel, question: str,
                                 evidence: Sequence[str | np.ndarray], *, how: str = ANSWER_PROBABILITY,
                                 max_tokens: int = 96) -> AnswerResult:
    """DESIGN 3.5's prompt with one guess ("answer; confidence", the black-box per-frame answer),
    read white-box: its confidence is the token probability of the answer before the ';'
    (``how`` as in ``answer_token_probability``), not the number the model wrote. The two
    ExploreEQA baselines then differ only in how they read confidence."""
    _check_how(how)
    require_logprobs(model)
    prompt, images = _verbalized_prompt(question, evidence, 1)
    resp = model.chat([Message("user", prompt, images)], max_tokens=max_tokens, temperature=0.0,
                      logprobs=1)
    parsed = parse_candidates(resp.text or "", 1)
    answer = parsed.candidates[0].text if parsed.candidates else ""
    result = _token_answer(resp, answer, how, end="\n;")
    return replace(result, problems=[*parsed.problems, *result.problems])


def _check_how(how: str) -> None:
    """Before any call: a reading of token probabilities that ``_token_answer`` knows."""
    if how not in ANSWER_PROBABILITIES:
        raise ValueError(f"how must be one of {ANSWER_PROBABILITIES}, not {how!r}")


def _token_answer(resp: ChatResponse, answer: str, how: str, end: str,
                  skip_lines: int = 0) -> AnswerResult:
    """``answer`` with the probability of the reply's first tokens up to one holding a character
    of ``end`` (leading whitespace skipped), after the tokens of the first ``skip_lines`` lines
    (a preamble). A token at -inf or with an unreadable (NaN) logprob makes it 0; positive
    logprobs (rounding) count as probability 1."""
    problems: list[str] = []
    logprob, started, n_tokens, newlines = 0.0, False, 0, 0
    for token in resp.logprobs or []:
        if newlines < skip_lines:
            newlines += token.token.count("\n")
            continue
        if not started and not token.token.strip():
            continue  # leading whitespace is not part of the answer (``raw.strip()``)
        ends = [token.token.find(c) for c in end if c in token.token]
        if ends and (started or not token.token[:min(ends)].strip()):
            break  # the answer ends here ("\n": its first line; ";": before the confidence)
        started = True
        value = to_float(token.logprob)
        if value is None or math.isnan(value):
            problems.append(f"unreadable probability of token {token.token!r}: confidence 0")
            value = -math.inf
        logprob += min(value, 0.0)  # a probability is at most 1; -inf (probability 0) counts
        n_tokens += 1
        if ends:
            break  # the answer's first token also ends it ("no;")
    if not resp.logprobs:
        problems.append("no logprobs in the reply: confidence 0")
    if not answer:
        problems.append("empty answer")
    if how == "per-token" and n_tokens:
        logprob /= n_tokens
    confidence = math.exp(logprob) if resp.logprobs and answer else 0.0
    candidates = [Candidate(answer, confidence)] if answer else []
    classes = [AnswerClass(answer, candidates, confidence)] if answer else []
    return AnswerResult(answer, confidence, classes, candidates, problems, resp.text or "",
                        usage_of(resp))
