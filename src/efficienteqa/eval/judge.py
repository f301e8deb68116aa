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
hand-graded set the mean agreed better than either question alone. ``llm_match_rules.rule_bounds``
then holds the grade to what the words alone make certain (an opposite yes/no, another colour,
the reference's words).
``mode="grade"`` (the OpenEQA form) is the default for capable judges such as GPT-4o.

Bad judge output never raises: replies are parsed leniently, retried once, and otherwise scored
with a documented default and a recorded problem. Grades are cached in sqlite, keyed on the judge
(its name, and its server where it is named by URL), the prompt text and the inputs, so a resumed
or parallel evaluation never pays twice for one grade; a default grade given for a reply that
held none is never stored, so a judge that misbehaved once does not grade so forever.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import re
import sqlite3
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from efficienteqa.cache import cache_dir
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.llm_match_rules import MAX_SCORE, MIN_SCORE, rule_bounds, rule_score
from efficienteqa.models.base import ChatModel, Message, TokenLogprob
from efficienteqa.models.local.weights import DEFAULT_MODEL
from efficienteqa.vc.prompts import load_prompt

PROMPTS = "efficienteqa.eval"  # the judge's templates: eval/prompts/*.txt

# A grade that stays unreadable after the retry counts as wrong: a broken judge must never
# raise the metric.
DEFAULT_SCORE = MIN_SCORE
MISSING_ANSWER = "missing answer"
REMINDER = "Reply with the score only: one whole number from 1 to 5, nothing else."
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


# --- trimming -----------------------------------------------------------------------------------

# Runs of word characters and periods: a sentence ends at the period that closes one, when a
# space or the end of the text follows ("T.V", "e.g", "mug" before it). Read run by run, in one
# pass: a pattern that backtracks into each run ("([\w.]*)\.(?=\s|$)") took time quadratic in
# its length (12 s for 30,000 digits).
_RUN = re.compile(r"[\w.]+")
# Abbreviations that end in a period inside a sentence.
_ABBREVIATIONS = frozenset({"dr", "mr", "mrs", "ms", "st", "prof", "sr", "jr", "vs", "etc",
                            "approx", "fig", "cf", "ca", "inc", "ltd", "co", "mt", "ft", "sq"})


def _sentence_ends(text: str) -> list[int]:
    """Where sentences end: after a period that is followed by a space or the end of the text
    and does not close an abbreviation ("Dr.", "etc."), an initialism ("e.g.", "T.V.", a single
    letter) or sit inside a number ("3.5")."""
    ends = []
    for run in _RUN.finditer(text):
        end = run.end()
        if not run.group().endswith(".") or (end < len(text) and not text[end].isspace()):
            continue
        word = run.group()[:-1]
        if "." in word or (len(word) == 1 and word.isalpha()) or word.lower() in _ABBREVIATIONS:
            continue
        ends.append(end)
    return ends


def trim_response(text: str) -> str:
    """``text`` cut after its last full stop when one occurs before the end, as the reference
    pipeline did to drop a sentence cut off by a token limit: "A red mug. It is on" -> "A red
    mug.". Only a sentence end counts: not a decimal point, an abbreviation or an initialism
    ("Dr.", "e.g.", "T.V.")."""
    text = text.strip()
    ends = _sentence_ends(text)
    if ends and ends[-1] < len(text):
        return text[:ends[-1]]
    return text


# --- parsing ------------------------------------------------------------------------------------

_NUMBER = r"[-+]?[0-9]+(?:\.[0-9]+)?"  # ASCII digits only: "²" and "٣" are no grade
# A grade has one digit. A longer run is cut to MAX_DIGITS before the rules read the reply: still
# a number far out of range (a problem, not a grade), and each rule's pattern then backtracks
# over at most MAX_DIGITS digits, so parsing stays linear in the reply (an absurd reply of
# 30,000 digits took 45 s).
MAX_DIGITS = 32
_LONG_DIGITS = re.compile(rf"\d{{{MAX_DIGITS + 1},}}")
_JSON_SCORE = re.compile(r'"score"\s*:\s*"?(' + _NUMBER + ")", re.IGNORECASE)
# A curly quote ends at the next opening one too: otherwise every unclosed "“" scans to the end
# of its line again, quadratic in a reply of many (17 s for 100,000).
_QUOTED = re.compile(r'"[^"\n]*"|“[^“”\n]*”')
_SCALE = re.compile(r"\b1\s*(?:-|–|to|and)\s*5\b")
_MARKED = re.compile(
    r"\b(?:score|rating|grade|rate)\b[^\d\n]{0,20}?(" + _NUMBER + ")"  # Score: **4**; rate it a 4
    r"|(" + _NUMBER + r")\s*(?:/|out\s+of)\s*5\b"  # 4/5; 3 out of 5
    r"|\bgive\b[^\d\n]{0,25}?(" + _NUMBER + ")",  # I would give it a 5
    re.IGNORECASE)
# "3 or 4", "between 3 and 4": the judge hedged between two grades.
_HEDGE = re.compile(r"(?<![\w.])([1-5])\s*(?:or|to|and|-|–)\s*([1-5])(?![\w.]?\d)", re.IGNORECASE)
_LEADING = re.compile(r"^[\s*#_`>(\[]*(" + _NUMBER + r")(?![\w.]\d|\w)")
_BARE = re.compile(r"(?<![\w.])(" + _NUMBER + r")(?!\w|\.\d)")


def _read(tokens: Sequence[str]) -> tuple[int | None, list[str]]:
    """One score from the candidate numbers found by one rule: they must agree, be whole and be
    in range."""
    values = list(dict.fromkeys(float(t) for t in tokens))
    if len(values) > 1:
        return None, ["conflicting scores " + ", ".join(f"{v:g}" for v in values)]
    value = values[0]
    if not value.is_integer():
        return None, [f"score {value:g} is not a whole number"]
    if not MIN_SCORE <= value <= MAX_SCORE:
        return None, [f"score {value:g} is out of range {MIN_SCORE}-{MAX_SCORE}"]
    return int(value), []


def parse_score(text: str) -> tuple[int | None, list[str]]:
    """The 1-5 grade in a judge's reply, or None and the problems found.

    Rules, first that finds a number wins: (1) a JSON ``"score"`` field. Then, with quoted text
    (a response the judge repeats, "2 cups") and the scale ("1-5", "1 to 5") removed: (2)
    numbers marked as the score ("Score: 4", "**4**/5", "3 out of 5", "give it a 5"), a conflict
    when the marked score is itself a hedge ("Score: 3 or 4"); the explicit score wins over
    numbers elsewhere ("Score 4 (both say 2 to 3 chairs)"); else a hedge between two grades
    ("3 or 4") is a conflict; else (3) a number that opens the reply ("4", "**4** - the same
    object"); (4) every other number in the reply. The numbers a rule finds must agree (one
    value), be whole and lie in 1-5; otherwise that is a problem, not a guess."""
    if not text or not text.strip():
        return None, ["empty reply"]
    text = _LONG_DIGITS.sub(lambda run: run.group()[:MAX_DIGITS], text)
    found = _JSON_SCORE.findall(text)
    if found:
        return _read(found)
    prose = _SCALE.sub(" ", _QUOTED.sub(" ", text))
    marks = list(_MARKED.finditer(prose))
    if marks:
        for mark in marks:
            hedged = _HEDGE.match(prose, mark.start(mark.lastindex or 0))
            if hedged and hedged.group(1) != hedged.group(2):
                return _read(hedged.groups())
        return _read([mark.group(mark.lastindex or 0) for mark in marks])
    hedge = next((h for h in _HEDGE.findall(prose) if h[0] != h[1]), None)
    if hedge:
        return _read(hedge)
    leading = _LEADING.match(prose)
    if leading:
        return _read([leading.group(1)])
    bare = _BARE.findall(prose)
    if bare:
        return _read(bare)
    return None, ["no score in reply"]


# --- the judge ----------------------------------------------------------------------------------

def openeqa_cut(response: str) -> str:
    """The response as OpenEQA grades it: up to and with its last "." when text follows it
    ("A lamp. It is on." stays; "A lamp. It is" becomes "A lamp.")."""
    end = response.rfind(".")
    return response[:end + 1] if 0 <= end < len(response) - 1 else response


_ASCII_MARK = re.compile(r"[0-9]{1,2}")


def openeqa_mark(reply: str) -> int | None:
    """The mark of an OpenEQA-style reply: the reply itself when it is a number, else the
    number after the last "Your mark:" (to the end of its line); None when neither is a whole
    number from 1 to 5. Only ASCII digits are a mark: "²", "5²" or "٣" (which ``isdigit`` takes
    for digits) are none."""
    text = reply.strip()
    if not _ASCII_MARK.fullmatch(text):
        at = text.rfind(OPENEQA_TAG)
        text = text[at + len(OPENEQA_TAG):].split("\n", 1)[0].strip() if at >= 0 else text
        found = re.match(r"^\**\s*([0-9]{1,2})\b", text)  # a bold mark is a mark
        text = found.group(1) if found else ""
    if not _ASCII_MARK.fullmatch(text):
        return None
    mark = int(text)
    return mark if MIN_SCORE <= mark <= MAX_SCORE else None


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
OPENEQA_TAG = "Your mark:"
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


# yes-prob: the templates asked, and how their P(yes) become one (see the module docstring).
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


_TABLE = """CREATE TABLE IF NOT EXISTS llm_match (
    key TEXT PRIMARY KEY, judge TEXT NOT NULL, score INTEGER, value REAL NOT NULL,
    raw TEXT NOT NULL, problems TEXT NOT NULL)"""


# How many alternatives a yes-prob call asks for at its one token.
TOP_LOGPROBS = 10


def token_word(token: str) -> str:
    """A generated token as a word: SentencePiece/BPE space markers ("▁", "Ġ"), spaces,
    punctuation and case removed ("▁Yes" -> "yes", "Yes." -> "yes", "ĠNO" -> "no")."""
    return re.sub(r"[\W_]+", "", token.replace("▁", " ").replace("Ġ", " ")).lower()


# vLLM reports -9999 for a token its sampler masked out: such a token holds no probability.
MASKED_LOGPROB = -9999.0


def _log_add(a: float, b: float) -> float:
    """log(exp(a) + exp(b)) without leaving log space (exp() is 0.0 below about -745)."""
    if a == -math.inf:
        return b
    high, low = max(a, b), min(a, b)
    return high + math.log1p(math.exp(low - high))


def p_yes(tokens: Sequence[TokenLogprob]) -> float | None:
    """P(yes) over {yes, no} at the first generated token whose alternatives hold either (each
    spelling adds to its word's probability); None when no token does. Computed from the
    logprobs themselves (``1 / (1 + exp(log P(no) - log P(yes)))``), so words whose logprobs
    underflow ``exp()`` are still compared (they once divided zero by zero); a masked token
    (-9999 or below, -inf, NaN) counts as absent."""
    for token in tokens:
        mass = {"yes": -math.inf, "no": -math.inf}
        alternatives = dict(token.top)
        alternatives.setdefault(token.token, token.logprob)
        for text, logprob in alternatives.items():
            word = token_word(text)
            if word in mass and math.isfinite(logprob) and logprob > MASKED_LOGPROB:
                mass[word] = _log_add(mass[word], min(logprob, 0.0))
        if mass["yes"] == -math.inf and mass["no"] == -math.inf:
            continue
        if mass["no"] == -math.inf:
            return 1.0
        gap = mass["no"] - mass["yes"]
        return 0.0 if gap > 700.0 else 1.0 / (1.0 + math.exp(gap))
    return None


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
