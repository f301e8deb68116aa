"""Verbalized confidence (paper, "Exploration - VC"; SPEC 3.3, 3.5, 3.6, 7).

One reply holds M answers with confidences ``{r_i, c_i}``; they are parsed, normalised
(``c_i' = c_i / sum c``), grouped into semantic classes ``R_k = E(r_i)`` with ``C_k = sum c_i'``,
and the class of highest ``C_k`` is the answer. Parsers never raise: whatever can be read is
kept, documented defaults fill the gaps, and every repair is a short string in ``problems``
so that an episode can count them.

Confidences of parsed candidates are on a 0-100 scale; normalised ones and ``p_yes`` on 0-1.
"""

from __future__ import annotations

import functools
import json
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from typing import Any, Protocol

import numpy as np

from efficienteqa.explore.module import SemanticScore
from efficienteqa.models.base import ChatModel, ChatResponse, Message, TokenLogprob

M = 3  # answers asked for per reply (the paper's M)
DEFAULT_LETTERS = ("A", "B", "C")
# A candidate listed without a confidence gets the uniform share 100 / m.
# "worth exploring" with no yes/no at all: P(yes) = 0.5; a bare "yes"/"no" without a number
# is read as 75 % sure.
DEFAULT_P_YES = 0.5
BARE_YES_NO_CONFIDENCE = 0.75
MAX_REPLY_CHARS = 20_000  # longer replies are cut
MAX_LINE_CHARS = 400  # and so are longer lines (no answer line is that long)

_NUM = (r"(?P<num>[-+]?(?:[0-9]+(?:\.[0-9]+)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?(?<![A-Za-z])(?:nan|inf(?:inity)?)(?![A-Za-z]))")
_PCT = r"[ \t]*(?P<pct>%|percent\b|/[ \t]*100\b)?"
_KEYWORD = re.compile(r"(?:confidence|conf|probability|prob|certainty|likelihood|score)[ \t]*"
                      r"(?:[:=]|is|of)?[ \t]*" + _NUM + _PCT, re.I)
_PAREN = re.compile(r"[(\[][ \t]*" + _NUM + _PCT + r"[ \t]*[)\]][\s.*]*$", re.I)
_SEPARATED = re.compile(r"(?:[:;,|=]|\s[-–—]|[-–—](?=\s))[ \t]*" + _NUM + _PCT + r"[\s.)*]*$", re.I)
_BARE_PCT = re.compile(r"\s" + _NUM + r"[ \t]*(?P<pct>%|percent\b)[\s.)*]*$", re.I)
_ANY_NUM = re.compile(_NUM + _PCT, re.I)
_ENUMERATOR = re.compile(r"^\s*(?:[-*•·>]+|\(?[0-9]{1,2}[.)]|\(?[a-z][.)]|#[0-9]+:?)(?=\s)\s*")
_LABEL = re.compile(r"^(?:answer|option|candidate|guess|response)\s*[0-9]*\s*[:.)\-]\s*", re.I)
_PAIR = re.compile(r"(?<![A-Za-z0-9])(?:(?i:direction|option|point|letter)\s+)?[(\[]?(?P<letter>[A-Z])"
                   r"[)\]]?(?![A-Za-z0-9])[ \t]*(?:[:=\-–—,]|\bis\b|\bwith\b)?[ \t]*[(\[]?[ \t]*"
                   + _NUM + _PCT)
_LETTER_HEAD = re.compile(r"^\W*(?:(?i:direction|option|point|letter)\s+)?[(\[]?(?P<letter>[A-Z])[)\]]?"
                          r"(?![A-Za-z0-9]) ?[(:=\-–—]")
_BARE_LETTER = re.compile(r"(?<![A-Za-z0-9'’])(?P<letter>[A-Z])(?![A-Za-z0-9'’])")
_YES_NO = re.compile(r"(?<![A-Za-z])(yes|no|true|false)(?![A-Za-z])", re.I)
_TEXT_KEYS = ("answer", "text", "direction", "letter", "option", "choice", "name", "label")
_CONF_KEYS = ("confidence", "conf", "probability", "prob", "score", "certainty", "likelihood", "p")


@dataclass(frozen=True)
class Candidate:
    """One answer ``r_i`` and its confidence ``c_i`` (0-100 parsed, 0-1 once normalised)."""

    text: str
    confidence: float


@dataclass
class ParseResult:
    candidates: list[Candidate]
    problems: list[str] = field(default_factory=list)


@dataclass
class AnswerClass:
    """A semantic equivalence class ``R_k``: its representative text, members, ``C_k``."""

    text: str
    members: list[Candidate]
    confidence: float


@dataclass
class AnswerResult:
    answer: str
    confidence: float
    classes: list[AnswerClass]
    candidates: list[Candidate]  # normalised
    problems: list[str]
    raw: str
    usage: dict[str, Any] = field(default_factory=dict)


# ---------------------------------------------------------------------------- prompts

@functools.cache
def load_prompt(name: str) -> str:
    """The prompt template ``prompts/<name>.txt`` (package data)."""
    return (resources.files("efficienteqa.models") / "prompts" / f"{name}.txt").read_text("utf-8")


# ---------------------------------------------------------------------------- parsing

@dataclass
class _Raw:
    text: str
    num: float | None  # as written
    pct: bool = False


def _prepare(reply: object, problems: list[str]) -> str:
    text = reply if isinstance(reply, str) else ("" if reply is None else str(reply))
    if len(text) > MAX_REPLY_CHARS:
        problems.append(f"reply cut to {MAX_REPLY_CHARS} characters")
        text = text[:MAX_REPLY_CHARS]
    # One space per run and short lines keep every regex below linear-time.
    lines = [re.sub(r"[^\S\n]+", " ", ln)[:MAX_LINE_CHARS] for ln in text.splitlines()]
    return "\n".join(ln for ln in lines if not ln.lstrip().startswith("```"))


def _to_float(s: object) -> float | None:
    if isinstance(s, bool):
        return None
    if isinstance(s, (int, float)):
        return float(s)
    try:
        return float(str(s).strip())
    except (ValueError, OverflowError):
        return None


def _split_confidence(line: str) -> tuple[str, _Raw | None]:
    """(text before the confidence, the confidence) of one line; (line, None) when it has none."""
    hits = list(_KEYWORD.finditer(line))
    match = hits[-1] if hits else None
    for rx in (_PAREN, _SEPARATED, _BARE_PCT):
        if match is None:
            match = rx.search(line)
    if match is None:
        return line, None
    return line[:match.start()], _Raw("", _to_float(match["num"]), bool(match["pct"]))


def _clean_text(s: str) -> str:
    s = s.replace("**", "").replace("`", "").strip()
    s = _LABEL.sub("", _ENUMERATOR.sub("", s))
    return s.strip(" \t\"'“”‘’:;,|=-–—([{").rstrip(" .!?").strip()


def _from_json(text: str, problems: list[str]) -> list[_Raw] | None:
    starts = [i for i in (text.find("{"), text.find("[")) if i >= 0]
    for start in sorted(starts):
        end = text.rfind("}" if text[start] == "{" else "]")
        if end <= start:
            continue
        try:
            obj = json.loads(text[start:end + 1])
        except Exception:  # noqa: BLE001 - any malformed JSON (incl. RecursionError) falls back
            continue
        out: list[_Raw] = []
        _walk_json(obj, out, 0)
        if out:
            if text[:start].strip() or text[end + 1:].strip():
                problems.append("ignored text around the JSON")
            return out
    return None


def _walk_json(obj: object, out: list[_Raw], depth: int) -> None:
    if depth > 6:
        return
    if isinstance(obj, dict):
        low = {str(k).lower(): v for k, v in obj.items()}
        text = next((low[k] for k in _TEXT_KEYS if k in low and isinstance(low[k], (str, int, float))),
                    None)
        if text is not None and not isinstance(text, bool):
            conf = next((low[k] for k in _CONF_KEYS if k in low), None)
            out.append(_json_raw(str(text), conf))
            return
        for k, v in obj.items():
            if "worth" in str(k).lower():
                continue
            if isinstance(v, (dict, list)):
                _walk_json(v, out, depth + 1)
            elif (isinstance(v, (int, float)) and not isinstance(v, bool)
                  or isinstance(v, str) and _ANY_NUM.fullmatch(v.strip())) and len(str(k)) <= 60:
                out.append(_json_raw(str(k), v))  # {"A": 60} or {"red": "60%"}
    elif isinstance(obj, list):
        for item in obj:
            if isinstance(item, str):
                head, raw = _split_confidence(item)
                out.append(_Raw(head, raw.num, raw.pct) if raw else _Raw(item, None))
            elif isinstance(item, list) and len(item) == 2 and isinstance(item[0], str):
                out.append(_json_raw(item[0], item[1]))
            else:
                _walk_json(item, out, depth + 1)


def _json_raw(text: str, conf: object) -> _Raw:
    if isinstance(conf, str):
        m = _ANY_NUM.search(conf)
        return _Raw(text, _to_float(m["num"]) if m else None, bool(m and m["pct"]))
    return _Raw(text, _to_float(conf))


def _split_pairs(line: str) -> list[str]:
    """``red: 60, blue: 30`` -> two lines, but only if every part carries a confidence."""
    parts = re.split(r"(?<=[0-9%)])[ \t]*[,;|][ \t]+", line)
    if len(parts) > 1 and all(_split_confidence(p)[1] is not None for p in parts):
        return parts
    return [line]


def _from_lines(text: str, problems: list[str]) -> list[_Raw]:
    rows: list[tuple[str, _Raw | None]] = []
    for line in text.splitlines():
        for part in _split_pairs(line):
            if not re.search(r"\w", part):
                continue
            head, raw = _split_confidence(part)
            rows.append((head, raw))
    if any(raw is not None for _, raw in rows):
        dropped = sum(raw is None for _, raw in rows)
        if dropped:
            problems.append(f"ignored {dropped} line(s) without a confidence")
        return [_Raw(head, raw.num, raw.pct) for head, raw in rows if raw is not None]
    # No confidences anywhere: every line that is not a header is an answer.
    return [_Raw(head, None) for head, _ in rows if not head.rstrip().endswith(":")]


def _finish(raws: list[_Raw], m: int, problems: list[str], allowed: Mapping[str, str] | None = None
            ) -> ParseResult:
    m = max(int(m), 1)
    items: list[tuple[str, float | None, bool]] = []
    for r in raws:
        text = _clean_text(r.text)
        if allowed is not None:
            key = _letter_of(text, allowed)
            if key is None:
                problems.append(f"unknown letter {text[:20]!r} dropped")
                continue
            text = key
        if not text:
            problems.append("empty answer dropped")
            continue
        num = r.num
        if num is not None and math.isnan(num):
            problems.append("non-numeric confidence (NaN)")
            num = None
        items.append((text, num, r.pct))
    finite = [n for _, n, _ in items if n is not None]
    fractions = bool(finite) and not any(p for _, _, p in items) and all(n <= 1.0 for n in finite)
    out: list[Candidate] = []
    seen: set[tuple[str, float]] = set()
    for text, num, _ in items:
        if num is None:
            problems.append(f"missing confidence for {text[:20]!r}: default {100.0 / m:.1f}")
            conf = 100.0 / m
        else:
            conf = num * 100.0 if fractions else num
            if conf > 100.0:
                problems.append(f"confidence {num:g} clipped to 100")
                conf = 100.0
            elif conf < 0.0:
                problems.append(f"negative confidence {num:g} set to 0")
                conf = 0.0
        line_key = (text.casefold(), conf)
        if line_key in seen:
            problems.append(f"duplicate line {text[:20]!r} dropped")
            continue
        seen.add(line_key)
        out.append(Candidate(text, conf))
    if len(out) > m:
        problems.append(f"{len(out)} candidates, kept the first {m}")
        out = out[:m]
    return ParseResult(out, problems)


def parse_candidates(reply: str, m: int = M) -> ParseResult:
    """Free-form answers with confidences (0-100): ``answer; 45``, ``1. red sofa — 70%``,
    ``red (0.7)``, JSON, prose around the list. At most ``m``; never raises."""
    problems: list[str] = []
    text = _prepare(reply, problems)
    raws = _from_json(text, problems)
    if raws is None:
        raws = _from_lines(text, problems)
    if not raws:
        problems.append("no answers found")
    return _finish(raws, m, problems)


def _letter_of(text: str, allowed: Mapping[str, str]) -> str | None:
    t = re.sub(r"^(?i:direction|option|point|letter)\s+", "", text.strip(" ()[]{}.:*\"'"))
    if len(t) == 1:
        return allowed.get(t.upper())
    found = [allowed[x] for x in _BARE_LETTER.findall(t) if x in allowed]
    return found[0] if len(set(found)) == 1 else None


def parse_letters(reply: str, letters: Sequence[str] = DEFAULT_LETTERS, m: int = M) -> ParseResult:
    """Lettered directions with confidences (``A: 60``, ``B - 30%``, ``C (0.1)``, JSON, one line or
    many). Only ``letters`` count; the "worth exploring" part is ignored. Never raises."""
    problems: list[str] = []
    allowed = {str(x).strip().upper(): str(x).strip() for x in letters if str(x).strip()}
    text = _prepare(reply, problems)
    raws = _from_json(text, problems)
    if raws is None:
        raws = []
        lines = [re.split(r"(?i)worth", ln)[0] for ln in text.splitlines()]
        for line in lines:
            line = re.sub(r"[*`]", "", line)
            line = re.sub(r"^\s*([a-z])\s*(?=[:=)])", lambda g: g[1].upper(), line)
            pairs = [_Raw(p["letter"], _to_float(p["num"]), bool(p["pct"])) for p in _PAIR.finditer(line)]
            head = _LETTER_HEAD.match(line)
            if not pairs and head:  # "A (through the door, 4 m): 60"
                conf = _split_confidence(line)[1]
                pairs = [_Raw(head["letter"], conf.num if conf else None, bool(conf and conf.pct))]
            raws += pairs
        if not raws:  # letters without numbers: "B, then A"
            raws = [_Raw(x, None) for ln in lines for x in _BARE_LETTER.findall(ln) if x in allowed]
    if not raws:
        problems.append("no letters found")
    return _finish(raws, m, problems, allowed)


def parse_worth_exploring(reply: str) -> tuple[float, list[str]]:
    """P(yes) in [0, 1] from ``worth exploring: yes 80`` / ``Yes (0.8)`` / ``no, 90`` (-> 0.1).

    A bare yes/no reads as ``BARE_YES_NO_CONFIDENCE``; a number alone as P(yes); nothing readable
    gives ``DEFAULT_P_YES``. Never raises."""
    problems: list[str] = []
    text = _prepare(reply, problems)
    idx = text.lower().rfind("worth")
    negated = False
    if idx >= 0:
        negated = bool(re.search(r"not\s*$", text[max(0, idx - 8):idx], re.I))
        lines = text[idx + 5:].split("\n")
        seg = lines[0]
        for extra in lines[1:3]:
            if _YES_NO.search(seg) or _ANY_NUM.search(seg):
                break
            seg += "\n" + extra
    else:
        seg = next((ln for ln in reversed(text.splitlines()) if _YES_NO.search(ln)), "")
        if seg:
            problems.append("no 'worth exploring' line; used the last yes/no")
    words = list(_YES_NO.finditer(seg))
    nums = list(_ANY_NUM.finditer(seg))
    word = None
    if words:
        before = [w for w in words if not nums or w.start() < nums[0].start()]
        word = (before[-1] if before else words[0])[1].lower()
    conf = None
    if nums:
        value = _to_float(nums[0]["num"])
        if value is not None and not math.isnan(value):
            conf = value / 100.0 if nums[0]["pct"] or value > 1.0 else value
            if not 0.0 <= conf <= 1.0:
                problems.append(f"worth-exploring confidence {value:g} clipped")
                conf = min(max(conf, 0.0), 1.0)
    if word is None and negated:
        word = "no"
    if word is None and conf is None:
        problems.append(f"no worth-exploring answer: default P(yes) = {DEFAULT_P_YES}")
        return DEFAULT_P_YES, problems
    if word is None:
        problems.append("worth-exploring number without yes/no: read as P(yes)")
        return float(conf), problems  # type: ignore[arg-type]
    if conf is None:
        problems.append(f"worth-exploring {word!r} without a confidence: {BARE_YES_NO_CONFIDENCE}")
        conf = BARE_YES_NO_CONFIDENCE
    return (conf if word in ("yes", "true") else 1.0 - conf), problems


# ---------------------------------------------------------------------------- VC pipeline

def normalise(candidates: Sequence[Candidate]) -> list[Candidate]:
    """``c_i' = c_i / sum c`` (non-finite or negative count as 0; all zero -> uniform)."""
    conf = [c.confidence if math.isfinite(c.confidence) and c.confidence > 0 else 0.0
            for c in candidates]
    total = sum(conf)
    if total <= 0:
        return [Candidate(c.text, 1.0 / len(candidates)) for c in candidates]
    return [Candidate(c.text, x / total) for c, x in zip(candidates, conf)]


class Grouper(Protocol):
    """The semantic grouping E(.): a class label per answer, labels numbered by first appearance,
    plus the repairs made on the way."""

    def partition(self, question: str, texts: Sequence[str]) -> tuple[list[int], list[str]]: ...


def _tokens(text: str) -> list[str]:
    return re.findall(r"[a-z]+|[0-9]+(?:\.[0-9]+)?", text.casefold())


_ARTICLES = {"a", "an", "the"}
_FILLER = {"there", "are", "is", "it", "its", "i", "see", "about", "around", "approximately",
           "roughly", "maybe", "probably", "likely", "total", "in", "of"}
_NUMBER_WORDS = {w: i for i, w in enumerate((
    "zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten", "eleven",
    "twelve", "thirteen", "fourteen", "fifteen", "sixteen", "seventeen", "eighteen", "nineteen",
    "twenty"))} | {"none": 0}
_YES = {"yes", "yeah", "yep", "correct", "true"}
_NO = {"no", "nope", "false", "incorrect"}
# The veto lists: answers naming different members of one of these sets never merge.
_COLOURS = {"red", "orange", "yellow", "green", "blue", "purple", "pink", "brown", "black", "white",
            "grey", "gray", "beige", "silver", "gold"}
_ROOMS = {"kitchen", "bedroom", "bathroom", "living", "dining", "hallway", "hall", "corridor",
          "office", "study", "garage", "laundry", "closet", "basement", "attic", "balcony"}
_SYNONYMS = {"gray": "grey", "hall": "hallway", "corridor": "hallway"}


def _singular(w: str) -> str:
    if len(w) > 4 and w.endswith("ies"):
        return w[:-3] + "y"
    if len(w) > 4 and w.endswith(("ches", "shes", "xes", "sses")):
        return w[:-2]
    if len(w) > 3 and w.endswith("s") and not w.endswith(("ss", "us", "is")):
        return w[:-1]
    return w


@dataclass(frozen=True)
class _Facts:
    key: str
    numbers: frozenset[float]
    polarity: str | None
    colours: frozenset[str]
    rooms: frozenset[str]


def _facts(text: str) -> _Facts:
    toks = _tokens(text)
    numbers: set[float] = set()
    content: list[str] = []
    for i, t in enumerate(toks):
        if t[0].isdigit():
            numbers.add(float(t))
        elif t in _NUMBER_WORDS and (t != "one" or i == 0):  # "the red one" is not a count
            numbers.add(float(_NUMBER_WORDS[t]))
        elif t not in _ARTICLES and t not in _FILLER:
            content.append(_singular(t))
    polarity = "yes" if toks and toks[0] in _YES else "no" if toks and toks[0] in _NO else None
    if polarity:
        key = polarity
    elif len(numbers) == 1 and len(content) <= 2:
        key = f"#{next(iter(numbers)):g}"
    else:
        key = " ".join(content) or " ".join(text.casefold().split())
    words = {_SYNONYMS.get(t, t) for t in toks}
    return _Facts(key, frozenset(numbers), polarity, frozenset(words & _COLOURS - {"gray"}),
                  frozenset(words & _ROOMS - {"hall", "corridor"}))


def contradictory(a: str, b: str) -> bool:
    """The veto: different numbers, yes vs no, different colour words, different room words."""
    fa, fb = _facts(a), _facts(b)
    return any(x and y and x != y for x, y in ((fa.numbers, fb.numbers), (fa.polarity, fb.polarity),
                                               (fa.colours, fb.colours), (fa.rooms, fb.rooms)))


class _Classes:
    """Union of answers into classes; a merge is refused if any two members contradict."""

    def __init__(self, texts: Sequence[str]) -> None:
        self.texts = list(texts)
        self.label = list(range(len(texts)))

    def members(self, k: int) -> list[int]:
        return [i for i, lab in enumerate(self.label) if lab == k]

    def merge(self, i: int, j: int) -> bool:
        a, b = self.label[i], self.label[j]
        if a == b:
            return True
        if any(contradictory(self.texts[x], self.texts[y]) for x in self.members(a) for y in self.members(b)):
            return False
        lo, hi = min(a, b), max(a, b)
        self.label = [lo if lab == hi else lab for lab in self.label]
        return True

    def labels(self) -> list[int]:
        order: dict[int, int] = {}
        return [order.setdefault(lab, len(order)) for lab in self.label]


class ExactGrouper:
    """For letters: equal after case folding and whitespace/punctuation trimming."""

    def partition(self, question: str, texts: Sequence[str]) -> tuple[list[int], list[str]]:
        order: dict[str, int] = {}
        return [order.setdefault(" ".join(t.casefold().split()).strip(" .!?,;:'\""), len(order))
                for t in texts], []


class RuleGrouper:
    """Cheap rules: case, articles, plurals; one number with at most two other words ("4",
    "four", "4 chairs"); yes/no by the first word ("yes, it is on"). Vetoed pairs stay apart."""

    def partition(self, question: str, texts: Sequence[str]) -> tuple[list[int], list[str]]:
        classes = _Classes(texts)
        keys = [_facts(t).key for t in texts]
        for j in range(len(texts)):
            for i in range(j):
                if keys[i] == keys[j]:
                    classes.merge(i, j)
        return classes.labels(), []


class LLMGrouper:
    """Rules first; the remaining classes are compared pairwise. With an ``embedder``
    (``embed(texts) -> (n, d) array``) only pairs of cosine >= ``threshold`` are proposed; each
    proposal is confirmed by the model with ``group.txt`` (one yes/no per pair: the easiest
    output for a 1.5B model to get right, and M = 3 leaves at most three pairs). Vetoed pairs
    never reach the model."""

    def __init__(self, model: ChatModel, embedder: Callable[[list[str]], np.ndarray] | None = None,
                 threshold: float = 0.8, max_pairs: int = 6) -> None:
        self.model, self.embedder = model, embedder
        self.threshold, self.max_pairs = threshold, max_pairs
        self.rules = RuleGrouper()
        self._answers: dict[tuple[str, ...], bool] = {}

    def partition(self, question: str, texts: Sequence[str]) -> tuple[list[int], list[str]]:
        labels, problems = self.rules.partition(question, texts)
        classes = _Classes(texts)
        for j, lab in enumerate(labels):
            classes.merge(labels.index(lab), j)
        reps = [labels.index(k) for k in range(max(labels, default=-1) + 1)]
        sims = self._similarity([texts[r] for r in reps], problems)
        asked = 0
        for b in range(len(reps)):
            for a in range(b):
                i, j = reps[a], reps[b]
                if contradictory(texts[i], texts[j]) or (sims is not None and sims[a, b] < self.threshold):
                    continue
                if asked >= self.max_pairs:
                    problems.append("grouping: pair budget spent")
                    return classes.labels(), problems
                asked += 1
                if self._same(question, texts[i], texts[j], problems):
                    classes.merge(i, j)
        return classes.labels(), problems

    def _similarity(self, texts: list[str], problems: list[str]) -> np.ndarray | None:
        if self.embedder is None or len(texts) < 2:
            return None
        emb = np.asarray(self.embedder(texts), dtype=float)
        if emb.ndim != 2 or len(emb) != len(texts) or not np.isfinite(emb).all():
            problems.append("grouping: unusable embeddings, asking about every pair")
            return None
        unit = emb / np.maximum(np.linalg.norm(emb, axis=1, keepdims=True), 1e-12)
        return unit @ unit.T

    def _same(self, question: str, a: str, b: str, problems: list[str]) -> bool:
        key = (question, *sorted((a, b)))
        if key not in self._answers:
            prompt = load_prompt("group").format(question=question, first=a, second=b)
            reply = self.model.chat([Message("user", prompt)], max_tokens=4, temperature=0.0).text or ""
            words = re.findall(r"[a-z]+", reply.lower())
            verdict = next((w for w in words if w in ("yes", "same", "no", "different")), None)
            if verdict is None:
                problems.append(f"grouping: unreadable reply {reply[:20]!r}, kept apart")
            self._answers[key] = verdict in ("yes", "same")
        return self._answers[key]


def group_answers(question: str, candidates: Sequence[Candidate], grouper: Grouper,
                  problems: list[str] | None = None) -> list[AnswerClass]:
    """Normalise, apply E(.) and sum ``C_k = sum c_i'`` per class (classes by first appearance;
    a class is named by its most confident member)."""
    norm = normalise(candidates)
    if not norm:
        return []
    labels, found = grouper.partition(question, [c.text for c in norm])
    if problems is not None:
        problems.extend(found)
    classes: list[AnswerClass] = []
    for k in range(max(labels) + 1):
        members = [c for c, lab in zip(norm, labels) if lab == k]
        if members:
            best = max(members, key=lambda c: c.confidence)  # first on ties
            classes.append(AnswerClass(best.text, members, sum(c.confidence for c in members)))
    return classes


def argmax(classes: Sequence[AnswerClass]) -> tuple[str, float]:
    """``(R*, C*)``; ties go to the first class; no classes -> ``("", 0.0)``."""
    best = None
    for c in classes:
        if best is None or c.confidence > best.confidence:
            best = c
    return (best.text, best.confidence) if best else ("", 0.0)


# ---------------------------------------------------------------------------- the model calls

def _usage(resp: ChatResponse) -> dict[str, Any]:
    return {"model": getattr(resp, "model", ""), "prompt_tokens": getattr(resp, "prompt_tokens", 0),
            "completion_tokens": getattr(resp, "completion_tokens", 0),
            "latency_s": getattr(resp, "latency_s", 0.0), "cached": getattr(resp, "cached", False)}


def explore_prompt(question: str, view: str, letters: Sequence[str],
                   descriptions: Mapping[str, str] | None, m: int = M) -> str:
    k = max(1, min(m, len(letters)))
    if descriptions:
        directions = "\n".join(f"{x}: {descriptions.get(x) or 'no description'}" for x in letters)
    else:
        directions = ", ".join(letters) + " (the lettered circles in the image)"
    order = list(letters[1:2]) + list(letters[:1]) + list(letters[2:])  # best first, not A-B-C
    example = "\n".join(f"{x}: {c}" for x, c in zip(order[:k], {1: [100], 2: [70, 30]}.get(k, [60, 30, 10])))
    return load_prompt("explore").format(question=question, view=view, directions=directions, k=k,
                                         lines=k + 1, example=example)


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
    return AnswerResult(answer, confidence, classes, normalise(parsed.candidates), problems, raw,
                        _usage(resp))


def answer_with_confidence(model: ChatModel, question: str, evidence: Sequence[str] | Sequence[np.ndarray],
                           grouper: Grouper, *, m: int = M, max_tokens: int = 96) -> AnswerResult:
    """The RAG answer (SPEC 3.5): ``evidence`` is the top-K frame descriptions (best first) or
    the top-K RGB frames; M guesses -> normalise -> group -> argmax."""
    items = list(evidence)
    images: tuple[np.ndarray, ...] = ()
    if items and all(isinstance(e, str) for e in items):
        text = "\n".join(f"view {i + 1}: {e}" for i, e in enumerate(items))
    else:
        images = tuple(e for e in items if isinstance(e, np.ndarray))
        text = f"the {len(images)} attached images" if images else "nothing"
    prompt = load_prompt("answer").format(question=question, evidence=text, m=m)
    return _vc_answer(model, prompt, images, question, grouper, m, max_tokens)


def blind_answer(model: ChatModel, question: str, grouper: Grouper, *, m: int = M,
                 max_tokens: int = 96) -> AnswerResult:
    """The Blind LLM baseline (SPEC 3.6): the question only; the model guesses when unsure."""
    prompt = load_prompt("blind").format(question=question, m=m)
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
