"""Parsing verbalized confidence: replies in, candidates and repairs out; never raises.

Lists of answers (``parse_candidates``) and of direction letters (``parse_letters``) with their
confidences. A yes/no with its confidence is read by ``yes_no``, a bounded JSON object by
``json_reply``; the number reading they share is in ``numbers``.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from efficienteqa.vc.numbers import ANY_NUM, KEYWORD, NUM, PCT, find_confidence, prepare, to_float

M = 3  # answers asked for per reply (the paper's M)
DEFAULT_LETTERS = ("A", "B", "C")
# The letters of a closed-set question's choices (HM-EQA has four; up to eight are read).
CHOICE_LETTERS = "ABCDEFGH"
# A candidate listed without a confidence gets the uniform share 100 / m, but never more than
# MISSING_CONFIDENCE: with one answer asked for (M = 1, ExploreEQA's per-step answer, where the
# value is used as it is) a reply without a number is a coin flip, not certainty.
MISSING_CONFIDENCE = 50.0

_PAREN = re.compile(r"[(\[][ \t]*" + NUM + PCT + r"[ \t]*[)\]][\s.*]*$", re.I)
_SEPARATED = re.compile(r"(?:[:;,|=]|\s[-–—]|[-–—](?=\s))[ \t]*" + NUM + PCT + r"[\s.)*]*$", re.I)
_BARE_PCT = re.compile(r"\s" + NUM + r"[ \t]*(?P<pct>%|percent\b)[\s.)*]*$", re.I)
_ENUMERATOR = re.compile(r"^\s*(?:[-*•·>]+|\(?[0-9]{1,2}[.)]|\(?[a-z][.)]|#[0-9]+:?)(?=\s)\s*")
_LABEL = re.compile(r"^(?:answer|option|candidate|guess|response)\s*[0-9]*\s*[:.)\-]\s*", re.I)
_BARE_LETTER = re.compile(r"(?<![A-Za-z0-9'’])(?P<letter>[A-Z])(?![A-Za-z0-9'’])")
# A capital letter followed by a lower-case word is the article "A" or the pronoun "I" unless
# the word is one that follows a direction's letter ("B is best", "A and B: 50").
_LETTER_AT = re.compile(r"(?<![A-Za-z0-9'’])(?P<letter>[A-Z])(?![A-Za-z0-9'’])(?=[ \t]+(?P<word>[a-z]+))?")
_AFTER_LETTER = frozenset((
    "is", "was", "seems", "looks", "has", "gets", "leads", "goes", "with", "and", "or", "then",
    "at", "for", "because", "since", "as", "first", "second", "third", "next", "last", "best",
    "probably", "likely", "maybe", "each", "both", "would", "could", "might"))
_LEAD_SEP = re.compile(r"^[ \t]*[-–—:=]")
_SHARED = re.compile(r"[)\]]?[ \t]*(?:[,&/+]|and|or)?[ \t]*", re.I)  # "A, B: 50 each"
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


# ---------------------------------------------------------------------------- parsing

@dataclass
class _Raw:
    text: str
    num: float | None  # as written
    pct: bool = False


def _split_confidence(line: str) -> _Raw:
    """The text before the confidence and the confidence of one line (``num`` None when the
    line has none, and then the text is the whole line)."""
    hits = list(KEYWORD.finditer(line))
    match = hits[-1] if hits else None
    for rx in (_PAREN, _SEPARATED, _BARE_PCT):
        if match is None:
            match = rx.search(line)
    if match is None:
        return _Raw(line, None)
    return _Raw(line[:match.start()], to_float(match["num"]), bool(match["pct"]))


def _clean_text(s: str) -> str:
    s = s.replace("**", "").replace("`", "").strip()
    s = _LABEL.sub("", _ENUMERATOR.sub("", s))
    return clean_answer(s.strip(" \t\"'“”‘’:;,|=-–—([{").rstrip(" .!?").strip())


_ANSWER_IS = re.compile(r"^(?:the\s+)?(?:final\s+|short\s+)?answer\s*(?:is\b\s*:?|:)\s*", re.I)
_ABBREVIATION = re.compile(r"(?:^|\s)(?:[A-Za-z]\.){2,}$")  # "a.m.", "U.S.": the dot is the word's
_QUOTES = (('"', '"'), ("'", "'"), ("“", "”"), ("‘", "’"), ("`", "`"))
_EMPHASIS = ("**", "__", "*", "_")


def clean_answer(text: str) -> str:
    """An answer as it is shown and recorded: without markdown emphasis (``**a lamp**``,
    ``*a lamp*``, ``__a lamp__``), a leading "The answer is", surrounding quotes and a final
    period. "The answer is **a lamp**." -> "a lamp". Only wrappers are removed: words, inner
    punctuation and an abbreviation's inner dots stay; an answer that is nothing but markup
    stays as it was. Pure and idempotent."""
    s = text.strip().replace("**", "").replace("__", "")
    for _ in range(4):  # wrappers can nest: '"*The answer is a lamp.*"'
        before = s
        s = _ANSWER_IS.sub("", s).strip()
        for left, right in _QUOTES + tuple((e, e) for e in _EMPHASIS):
            if len(s) > len(left) + len(right) and s.startswith(left) and s.endswith(right):
                s = s[len(left):-len(right)].strip()
        if s.endswith(".") and not s.endswith("..") and not _ABBREVIATION.search(s):
            s = s[:-1].rstrip()
        if s == before:
            break
    return s or text.strip()


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
                  or isinstance(v, str) and ANY_NUM.fullmatch(v.strip())) and len(str(k)) <= 60:
                out.append(_json_raw(str(k), v))  # {"A": 60} or {"red": "60%"}
    elif isinstance(obj, list):
        for item in obj:
            if isinstance(item, str):
                out.append(_split_confidence(item))
            elif isinstance(item, list) and len(item) == 2 and isinstance(item[0], str):
                out.append(_json_raw(item[0], item[1]))
            else:
                _walk_json(item, out, depth + 1)


def _json_raw(text: str, conf: object) -> _Raw:
    if isinstance(conf, str):
        m = ANY_NUM.search(conf)
        return _Raw(text, to_float(m["num"]) if m else None, bool(m and m["pct"]))
    return _Raw(text, to_float(conf))


_CONF_LABEL = re.compile(r"(?i)(?:" + "|".join(_CONF_KEYS) + r")?")


def _split_pairs(line: str) -> list[str]:
    """``red: 60, blue: 30`` -> two lines, but only if every part carries a confidence."""
    parts = re.split(r"(?<=[0-9%)])[ \t]*[,;|][ \t]+", line)
    if len(parts) > 1 and all(_split_confidence(p).num is not None for p in parts):
        return parts
    return [line]


def _from_lines(text: str, problems: list[str]) -> list[_Raw]:
    rows: list[_Raw] = []
    for line in text.splitlines():
        for part in _split_pairs(line):
            if not re.search(r"\w", part):
                continue
            row = _split_confidence(part)
            if (row.num is not None and rows and rows[-1].num is None
                    and _CONF_LABEL.fullmatch(row.text.strip(" \t:=-*"))):
                # "answer: red" then "confidence: 80" on the next line: one candidate
                rows[-1] = _Raw(rows[-1].text, row.num, row.pct)
                continue
            rows.append(row)
    if any(row.num is not None for row in rows):
        dropped = sum(row.num is None for row in rows)
        if dropped:
            problems.append(f"ignored {dropped} line(s) without a confidence")
        return [row for row in rows if row.num is not None]
    # No confidences anywhere: every line that is not a header is an answer.
    return [row for row in rows if not row.text.rstrip().endswith(":")]


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
    missing = min(100.0 / m, MISSING_CONFIDENCE)
    for text, num, _ in items:
        if num is None:
            problems.append(f"missing confidence for {text[:20]!r}: default {missing:.1f}")
            conf = missing
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
    text = prepare(reply, problems)
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


def _letter_parts(line: str) -> list[tuple[str, _Raw | None, str]]:
    """(letter, its confidence, the text after it) for each direction letter of ``line``; a
    letter's part runs to the next letter."""
    found = [m for m in _LETTER_AT.finditer(line) if m["word"] is None or m["word"] in _AFTER_LETTER]
    parts: list[tuple[str, _Raw | None, str]] = []
    for m, nxt in zip(found, [*found[1:], None]):
        part = line[m.end():nxt.start() if nxt else len(line)]
        hit = find_confidence(_LEAD_SEP.sub("", part, count=1))  # "B-60" is B: 60, not -60
        parts.append((m["letter"], _Raw(m["letter"], to_float(hit["num"]), bool(hit["pct"])) if hit else None,
                      part))
    for i in range(len(parts) - 2, -1, -1):  # "A, B: 50 each": A shares B's confidence
        letter, raw, part = parts[i]
        after = parts[i + 1][1]
        if raw is None and after is not None and _SHARED.fullmatch(part):
            parts[i] = (letter, _Raw(letter, after.num, after.pct), part)
    return parts


def parse_letters(reply: str, letters: Sequence[str] = DEFAULT_LETTERS, m: int = M) -> ParseResult:
    """Lettered directions with confidences (``A: 60``, ``B - 30%``, ``C (0.1)``, ``B is best
    (70%), then A (30%)``, ``A, B: 50 each``, JSON, one line or many). Only ``letters`` count;
    the "worth exploring" part is ignored; letters without a confidence are ignored when others
    have one. Never raises."""
    problems: list[str] = []
    allowed = {str(x).strip().upper(): str(x).strip() for x in letters if str(x).strip()}
    text = prepare(reply, problems)
    raws = _from_json(text, problems)
    if raws is None:
        parts: list[tuple[str, _Raw | None, str]] = []
        for line in text.splitlines():
            line = re.sub(r"[*`]", "", re.split(r"(?i)worth", line)[0])
            line = re.sub(r"^\s*([a-z])\s*(?=[:=)])", lambda g: g[1].upper(), line)
            parts += _letter_parts(line)
        raws = [raw for _, raw, _ in parts if raw is not None]
        bare = [x for x, raw, _ in parts if raw is None and x in allowed]
        if not raws:  # letters without numbers: "B, then A"
            raws = [_Raw(x, None) for x in bare]
        elif bare:
            problems.append(f"ignored letter(s) without a confidence: {', '.join(bare)}")
    if not raws:
        problems.append("no letters found")
    return _finish(raws, m, problems, allowed)
