"""LLM-Match, OpenEQA's metric: a judge model grades each response against the reference answer
from 1 to 5, mapped to 0-100 and averaged over questions.

Clear cases are graded without the model, because a small judge gets them wrong and any judge
must agree (``llm_match_rules``): the same answer, a count against another count, a bare yes/no
against a bare yes/no, a non-answer, guesses, an answer that only repeats the question. Such
grades say so in ``raw``. Synthetic questions, whose every accepted answer is known, are graded
by ``synthetic_judge`` instead, with LLM-Match beside it when a judge model is given.

``mode="yes-prob"`` is for judges too small to grade 1-5 (the embedded 1.5B model's grades were
nearly uniform over 1-5, whatever the answers): the judge is asked two yes/no questions, and
the grade is ``1 + round(4 * P)`` where ``P`` is the geometric mean of the two P(yes) read from
the token probabilities of its one-token replies (tokens read as words: "▁Yes", "Yes." and
" yes" are yes). The two questions lean opposite ways, and their mean holds the lean of
neither: prompts/judge_same.txt asks whether the response says the same thing as the correct
answer (strict: a right answer in other words or with more detail often gets P(yes) < 0.5);
prompts/judge_correct.txt asks whether it gives the correct answer, with the rubric's yes and
no cases and six worked examples (lenient: wrong answers get 0.5-0.75). On the shared
hand-graded set the mean agreed better than either question alone. ``llm_match_bounds.rule_bounds``
then holds the grade to what the words alone make certain (an opposite yes/no, another colour,
the reference's words).
``mode="grade"`` (the OpenEQA form) is the default for capable judges such as GPT-4o.

Bad judge output never raises: replies are parsed leniently, retried once, and otherwise scored
with a documented default and a recorded problem. Grades are cached in sqlite, keyed on the judge
(its name, and its server where it is named by URL), the prompt text and the inputs, so a resumed
or parallel evaluation never pays twice for one grade; a default grade given for a reply that
held none is never stored, so a judge that misbehaved once does not grade so forever.

What the judge is asked and in which mode is ``eval.judge_prompts``; how a response is cut and a
grade read from a reply is ``eval.judge_parse``. This module makes the calls and keeps the cache.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import sqlite3
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from efficienteqa.cache import cache_dir
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.judge_parse import openeqa_cut, openeqa_mark, p_yes, parse_score, trim_response
from efficienteqa.eval.judge_prompts import (
    JUDGE_MODES,
    JUDGE_TEMPERATURE,
    OPENEQA_MAX_TOKENS,
    OPENEQA_SEED,
    OPENEQA_TEMPERATURE,
    PROMPTS,
    REMINDER,
    YES_PROMPTS,
    prompt_version,
    render_prompt,
)
from efficienteqa.eval.llm_match_bounds import rule_bounds
from efficienteqa.eval.llm_match_rules import MAX_SCORE, MIN_SCORE, rule_score
from efficienteqa.models.base import ChatModel, Message
from efficienteqa.vc.prompts import load_prompt

# A grade that stays unreadable after the retry counts as wrong: a broken judge must never
# raise the metric.
DEFAULT_SCORE = MIN_SCORE
MISSING_ANSWER = "missing answer"
SCORE_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {"score": {"type": "integer", "minimum": MIN_SCORE, "maximum": MAX_SCORE}},
    "required": ["score"],
}
# Enough for "Score: 4" or {"score": 4}; a judge that writes an essay first is cut short and
# retried rather than paid for.
MAX_TOKENS = 16


@dataclass(frozen=True)
class Judgement:
    """One grade. ``score``: 1-5, or None for a missing answer; ``value``: 0-100 (LLM-Match
    units); ``judge``: the judge model's name; ``raw``: the reply the score was read from;
    ``problems``: what went wrong on the way (retries, defaults); ``cached``: read from the cache."""

    score: int | None
    value: float
    judge: str
    raw: str = ""
    problems: tuple[str, ...] = ()
    cached: bool = False

    def to_dict(self) -> dict[str, Any]:
        record = asdict(self)
        record["problems"] = list(self.problems)
        return record


def score_value(score: int | None) -> float:
    """A 1-5 grade in LLM-Match units: ``100 * (score - 1) / 4``; no grade is 0."""
    return 0.0 if score is None else 100.0 * (score - MIN_SCORE) / (MAX_SCORE - MIN_SCORE)


_TABLE = """CREATE TABLE IF NOT EXISTS llm_match (
    key TEXT PRIMARY KEY, judge TEXT NOT NULL, score INTEGER, value REAL NOT NULL,
    raw TEXT NOT NULL, problems TEXT NOT NULL)"""


# How many alternatives a yes-prob call asks for at its one token.
TOP_LOGPROBS = 10


class LLMMatchJudge:
    """Grades responses with ``model`` (injected; any ``ChatModel``). ``cache_path``: the sqlite
    file of past grades, shared safely by several processes (default:
    ``cache_dir("judge")/llm_match.sqlite``, created on first use)."""

    def __init__(self, model: ChatModel, cache_path: Path | None = None, mode: str = "grade") -> None:
        if mode not in JUDGE_MODES:
            raise EfficientEQAError(f"unknown judge mode {mode!r}",
                                    fix=f"use one of {', '.join(JUDGE_MODES)}")
        if mode == "yes-prob" and not model.capabilities.logprobs:
            raise EfficientEQAError(f"judge {model.name!r} gives no token probabilities for yes-prob",
                                    fix="use --judge-mode grade")
        self.model = model
        # The name recorded with every grade says how it was obtained.
        self.name = model.name if mode == "grade" else f"{model.name} ({mode})"
        self.mode = mode
        self._cache_path = cache_path
        # the server a judge named by URL is on (``OpenAIChatClient.server``, its password as
        # ***), which keys its grades; None for the embedded model or a stub
        server = getattr(model, "server", None)
        self.server: str | None = server if isinstance(server, str) else None

    def __repr__(self) -> str:
        return f"LLMMatchJudge(model={self.name!r})"

    @property
    def cache_path(self) -> Path:
        if self._cache_path is None:
            self._cache_path = cache_dir("judge") / "llm_match.sqlite"
        return self._cache_path

    def judge(self, question: str, reference: str, response: str | None,
              extra: Sequence[str] = ()) -> Judgement:
        """Grade ``response``. A missing (None or blank) response scores 0 without a model call;
        model failures (network, server) raise ``EfficientEQAError`` from the client, bad replies
        do not raise."""
        if response is None or not response.strip():
            return Judgement(score=None, value=0.0, judge=self.name, problems=(MISSING_ANSWER,))
        if self.mode == "openeqa":  # the protocol as it runs: no rules, its own cut
            response = openeqa_cut(response)
            key = self._key(question, reference, extra, response)
            judgement = self._lookup(key)
            if judgement is None:
                judgement, read = self._openeqa(question, reference, response, extra)
                if read:
                    self._store(key, judgement)
            return judgement
        response = trim_response(response)
        ruled = rule_score(question, reference, response, extra)
        if ruled is not None:
            return Judgement(ruled.score, score_value(ruled.score), self.name,
                             f"(by rule, no model call: {ruled.rule}: {ruled.score})")
        bounds = rule_bounds(question, reference, response, extra)
        if bounds is not None and bounds.low == bounds.high:
            return Judgement(bounds.low, score_value(bounds.low), self.name,
                             f"(by rule, no model call: {bounds.rule}: {bounds.low})")
        key = self._key(question, reference, extra, response)
        judgement = self._lookup(key)
        if judgement is None:
            if self.mode == "yes-prob":
                judgement, read = self._yes_prob([render_prompt(question, reference, response,
                                                                extra, template=t)
                                                  for t in YES_PROMPTS])
            else:
                judgement, read = self._grade(render_prompt(question, reference, response, extra))
            if read:
                self._store(key, judgement)
        if bounds is None or judgement.score is None \
                or bounds.low <= judgement.score <= bounds.high:
            return judgement
        score = min(max(judgement.score, bounds.low), bounds.high)
        return replace(judgement, score=score, value=score_value(score),
                       raw=f"{judgement.raw} (held to {bounds.low}-{bounds.high} by rule: "
                           f"{bounds.rule}: {score})")

    def _openeqa(self, question: str, reference: str, response: str,
                 extra: Sequence[str]) -> tuple[Judgement, bool]:
        """One call as OpenEQA makes it, and whether a mark was read; an unreadable mark
        (OpenEQA raises) is the default grade with a problem."""
        accepted = [e.strip() for e in extra if e and e.strip()]
        prompt = load_prompt("judge_openeqa", PROMPTS).format(
            question=question.strip(), answer=reference.strip(), response=response,
            extra=f"\nOther accepted answers: {'; '.join(accepted)}" if accepted else "")
        reply = self.model.chat([Message("user", prompt)], max_tokens=OPENEQA_MAX_TOKENS,
                                temperature=OPENEQA_TEMPERATURE, seed=OPENEQA_SEED)
        score = openeqa_mark(reply.text or "")
        if score is None:
            return Judgement(DEFAULT_SCORE, score_value(DEFAULT_SCORE), self.name, reply.text,
                             (f"no mark from 1 to 5 in {(reply.text or '')[:40]!r}, scored "
                              f"{DEFAULT_SCORE}",)), False
        return Judgement(score, score_value(score), self.name, reply.text), True

    def _yes_prob(self, prompts: Sequence[str]) -> tuple[Judgement, bool]:
        """One call per prompt; the grade from the geometric mean of their P(yes), and whether
        any was read. A prompt whose reply holds no yes/no is left out (and said); none at all
        is the default grade."""
        found: list[float] = []
        parts, problems = [], []
        for template, prompt in zip(YES_PROMPTS, prompts, strict=True):
            reply = self.model.chat([Message("user", prompt)], max_tokens=1, temperature=JUDGE_TEMPERATURE,
                                    logprobs=TOP_LOGPROBS)
            p = p_yes(reply.logprobs or [])
            if p is None:
                parts.append(f"{template} {reply.text!r}")
                problems.append(f"no yes/no among the {template} reply's tokens")
            else:
                parts.append(f"{template} {p:.3f}")
                found.append(p)
        if not found:
            return Judgement(DEFAULT_SCORE, score_value(DEFAULT_SCORE), self.name,
                             "; ".join(parts), (*problems, f"scored {DEFAULT_SCORE}")), False
        p = math.prod(found) ** (1.0 / len(found))
        score = MIN_SCORE + round((MAX_SCORE - MIN_SCORE) * p)
        return Judgement(score, score_value(score), self.name,
                         f"P(yes)={p:.3f} ({'; '.join(parts)})", tuple(problems)), True

    def _grade(self, prompt: str) -> tuple[Judgement, bool]:
        """The grade of one call (and one retry where it is unreadable), and whether one was
        read."""
        caps = self.model.capabilities
        schema = SCORE_SCHEMA if caps.json_schema or caps.grammar else None
        messages = [Message("user", prompt)]
        reply = self.model.chat(messages, max_tokens=MAX_TOKENS, temperature=JUDGE_TEMPERATURE,
                                json_schema=schema)
        score, problems = parse_score(reply.text)
        if score is not None:
            return Judgement(score, score_value(score), self.name, reply.text), True
        retried = [f"retried after: {p}" for p in problems]
        messages += [Message("assistant", reply.text), Message("user", REMINDER)]
        reply = self.model.chat(messages, max_tokens=MAX_TOKENS, temperature=JUDGE_TEMPERATURE,
                                json_schema=schema)
        score, problems = parse_score(reply.text)
        if score is not None:
            return Judgement(score, score_value(score), self.name, reply.text, tuple(retried)), True
        problems = [*retried, *problems, f"unreadable grade, scored {DEFAULT_SCORE}"]
        return Judgement(DEFAULT_SCORE, score_value(DEFAULT_SCORE), self.name, reply.text,
                         tuple(problems)), False

    # --- cache ---

    def _key(self, question: str, reference: str, extra: Sequence[str], response: str) -> str:
        """The grade's cache key: the prompt version, the judge's name, the server it is on
        (a judge named by URL: two servers of one model name may grade apart, as the response
        cache keys them), the inputs."""
        parts = [prompt_version(self.mode), self.name, question, reference, list(extra), response]
        if self.server is not None:  # left out otherwise: the key of the releases before it
            parts.append(self.server)
        return hashlib.sha256(json.dumps(parts).encode()).hexdigest()

    @contextlib.contextmanager
    def _db(self) -> Iterator[sqlite3.Connection]:
        """A short-lived connection in one transaction; the timeout waits out other writers."""
        path = self.cache_path
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with contextlib.closing(sqlite3.connect(path, timeout=60.0)) as db, db:
                db.execute(_TABLE)
                yield db
        except sqlite3.DatabaseError as error:
            raise EfficientEQAError(f"judge cache {path} is unusable: {error}",
                                    fix=f"delete {path} or pass another cache_path") from error

    def _lookup(self, key: str) -> Judgement | None:
        with self._db() as db:
            row = db.execute("SELECT judge, score, value, raw, problems FROM llm_match WHERE key = ?",
                             (key,)).fetchone()
        if row is None:
            return None
        judge, score, value, raw, problems = row
        return Judgement(score, value, judge, raw, tuple(json.loads(problems)), cached=True)

    def _store(self, key: str, judgement: Judgement) -> None:
        with self._db() as db:
            db.execute("INSERT OR REPLACE INTO llm_match VALUES (?, ?, ?, ?, ?, ?)",
                       (key, judgement.judge, judgement.score, judgement.value, judgement.raw,
                        json.dumps(list(judgement.problems))))
