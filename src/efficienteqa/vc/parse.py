"""Parsing verbalized confidence: replies in, candidates and repairs out; never raises."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

M = 3  # answers asked for per reply (the paper's M)
DEFAULT_LETTERS = ("A", "B", "C")
# The letters of a closed-set question's choices (HM-EQA has four; up to eight are read).
CHOICE_LETTERS = "ABCDEFGH"
# A candidate listed without a confidence gets the uniform share 100 / m, but never more than
# MISSING_CONFIDENCE: with one answer asked for (M = 1, ExploreEQA's per-step answer, where the
# value is used as it is) a reply without a number is a coin flip, not certainty.
MISSING_CONFIDENCE = 50.0
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
_BARE_LETTER = re.compile(r"(?<![A-Za-z0-9'’])(?P<letter>[A-Z])(?![A-Za-z0-9'’])")
# Where the confidence of a letter or of "worth exploring" is, in order of preference: after a
# keyword ("confidence: 80"), a percentage anywhere, a number ending the part ("B - 40",
# "yes (0.8)"), else the first number that is not a distance or a count ("3 m", "2 rooms",
# "2nd").
_PERCENT = re.compile(_NUM + r"[ \t]*(?P<pct>%|percent\b|/[ \t]*100\b)", re.I)
_TRAILING = re.compile(r"(?:^|(?<=[\s:;,|=(\[\-–—]))" + _NUM + _PCT + r"[\s.,;)\]}*]*$", re.I)
_UNIT = (r"(?:m|cm|km|ft|feet|foot|metres?|meters?|steps?|rooms?|doors?|s|secs?|seconds?|mins?"
         r"|minutes?|degrees?|deg|°|x)(?![A-Za-z])")
_FREE_NUM = re.compile(r"(?<![0-9.])" + _NUM + _PCT + r"(?![ \t]*" + _UNIT + r")(?!\.?[0-9])(?![A-Za-z])",
                       re.I)
_CONF_LINE = re.compile(r"^[ \t]*(?:(?:" + "|".join(("confidence", "conf", "probability", "prob", "certainty",
                                                     "likelihood", "score")) + r")\b|" + _NUM + _PCT
                        + r"[ \t.]*$)", re.I)
# A capital letter followed by a lower-case word is the article "A" or the pronoun "I" unless
# the word is one that follows a direction's letter ("B is best", "A and B: 50").
_LETTER_AT = re.compile(r"(?<![A-Za-z0-9'’])(?P<letter>[A-Z])(?![A-Za-z0-9'’])(?=[ \t]+(?P<word>[a-z]+))?")
_AFTER_LETTER = frozenset((
    "is", "was", "seems", "looks", "has", "gets", "leads", "goes", "with", "and", "or", "then",
    "at", "for", "because", "since", "as", "first", "second", "third", "next", "last", "best",
    "probably", "likely", "maybe", "each", "both", "would", "could", "might"))
_LEAD_SEP = re.compile(r"^[ \t]*[-–—:=]")
_SHARED = re.compile(r"[)\]]?[ \t]*(?:[,&/+]|and|or)?[ \t]*", re.I)  # "A, B: 50 each"
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


def to_float(s: object) -> float | None:
    if isinstance(s, bool):
        return None
    if isinstance(s, (int, float)):
        return float(s)
    try:
        return float(str(s).strip())
    except (ValueError, OverflowError):
        return None


def _split_confidence(line: str) -> _Raw:
    """The text before the confidence and the confidence of one line (``num`` None when the
    line has none, and then the text is the whole line)."""
    hits = list(_KEYWORD.finditer(line))
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
                  or isinstance(v, str) and _ANY_NUM.fullmatch(v.strip())) and len(str(k)) <= 60:
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
        m = _ANY_NUM.search(conf)
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


def _find_confidence(part: str) -> re.Match[str] | None:
    """The confidence in one letter's part of a line or in the "worth exploring" answer."""
    hits = list(_KEYWORD.finditer(part))
    return (hits[-1] if hits else None) or _PERCENT.search(part) or _TRAILING.search(part) \
        or _FREE_NUM.search(part)


def _letter_parts(line: str) -> list[tuple[str, _Raw | None, str]]:
    """(letter, its confidence, the text after it) for each direction letter of ``line``; a
    letter's part runs to the next letter."""
    found = [m for m in _LETTER_AT.finditer(line) if m["word"] is None or m["word"] in _AFTER_LETTER]
    parts: list[tuple[str, _Raw | None, str]] = []
    for m, nxt in zip(found, [*found[1:], None]):
        part = line[m.end():nxt.start() if nxt else len(line)]
        hit = _find_confidence(_LEAD_SEP.sub("", part, count=1))  # "B-60" is B: 60, not -60
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
    text = _prepare(reply, problems)
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


# The problem that says a reply held neither a yes/no nor a confidence: nothing was read.
NO_YES_NO = "no worth-exploring answer"
NO_WORTH_LINE = "no 'worth exploring' line"  # a yes/no was read, from another line


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
            # look further while nothing is found, or for the confidence of a bare yes/no
            # given on the next line ("yes" then "confidence: 80")
            if _find_confidence(seg) or (_YES_NO.search(seg) and not _CONF_LINE.match(extra)):
                break
            seg += "\n" + extra
    else:
        seg = next((ln for ln in reversed(text.splitlines()) if _YES_NO.search(ln)), "")
        if seg:
            problems.append(f"{NO_WORTH_LINE}; used the last yes/no")
    words = list(_YES_NO.finditer(seg))
    hit = _find_confidence(seg)
    word = None
    if words:
        before = [w for w in words if hit is None or w.start() < hit.start()]
        word = (before[-1] if before else words[0])[1].lower()
    conf = None
    if hit:
        value = to_float(hit["num"])
        if value is not None and not math.isnan(value):
            conf = value / 100.0 if hit["pct"] or value > 1.0 else value
            if not 0.0 <= conf <= 1.0:
                problems.append(f"worth-exploring confidence {value:g} clipped")
                conf = min(max(conf, 0.0), 1.0)
    if word is None and negated:
        word = "no"
    if word is None and conf is None:
        problems.append(f"{NO_YES_NO}: default P(yes) = {DEFAULT_P_YES}")
        return DEFAULT_P_YES, problems
    if word is None:
        problems.append("worth-exploring number without yes/no: read as P(yes)")
        return float(conf), problems  # type: ignore[arg-type]
    if conf is None:
        problems.append(f"worth-exploring {word!r} without a confidence: {BARE_YES_NO_CONFIDENCE}")
        conf = BARE_YES_NO_CONFIDENCE
    return (conf if word in ("yes", "true") else 1.0 - conf), problems




# A JSON reply is read in bounded time whatever its size or shape (``json_reply``): at most
# MAX_JSON_CHARS characters (a reply that asks for one JSON object of a few fields is some
# hundred), MAX_JSON_TRIES places where an object may start, values nested at most
# MAX_JSON_DEPTH deep and MAX_JSON_VALUES values in all; numbers must be finite.
MAX_JSON_CHARS = 100_000
MAX_JSON_TRIES = 64
MAX_JSON_DEPTH = 16
MAX_JSON_VALUES = 2_000
NO_JSON = "no JSON object"


class _Refused(Exception):
    """A JSON reply read no further: why (``json_reply``)."""


def _constant(name: str) -> Any:
    raise _Refused(f"a JSON number that is not finite ({name})")


def _float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise _Refused(f"a JSON number that is not finite ({text[:20]})")
    return value


def _int(text: str) -> int:
    if len(text) > 300:  # beyond any float, and Python's int() of over 4300 digits raises
        raise _Refused(f"a JSON number of {len(text)} digits")
    return int(text)


_DECODER = json.JSONDecoder(parse_float=_float, parse_int=_int, parse_constant=_constant)


def _bounded(value: Any) -> str | None:
    """Why ``value`` (a parsed reply) is refused: nested too deep or too many values; None when
    it is within the bounds."""
    stack, seen = [(value, 1)], 0
    while stack:
        item, depth = stack.pop()
        seen += 1
        if seen > MAX_JSON_VALUES:
            return f"a JSON object of over {MAX_JSON_VALUES} values"
        if depth > MAX_JSON_DEPTH:
            return f"a JSON object nested over {MAX_JSON_DEPTH} deep"
        if isinstance(item, dict):
            stack += [(v, depth + 1) for v in item.values()]
        elif isinstance(item, list):
            stack += [(v, depth + 1) for v in item]
    return None


def json_reply(reply: str) -> tuple[dict[str, Any] | None, str]:
    """The first JSON object in ``reply`` (a model may wrap it in prose or a code fence) and "",
    or None and why not (``NO_JSON`` when there is none, or the first JSON value found is not
    an object). Never raises, in time bounded whatever the reply: one longer than
    ``MAX_JSON_CHARS``, an object nested deeper than ``MAX_JSON_DEPTH`` or of more than
    ``MAX_JSON_VALUES`` values, or one holding a number that is not finite (``NaN``,
    ``Infinity``, ``1e999``) is refused whole, and said so."""
    if not isinstance(reply, str):
        return None, NO_JSON
    if len(reply) > MAX_JSON_CHARS:
        return None, f"a reply of {len(reply)} characters (over {MAX_JSON_CHARS})"
    start = reply.find("{")
    for _ in range(MAX_JSON_TRIES):
        if start < 0:
            break
        try:
            value, _end = _DECODER.raw_decode(reply, start)
        except _Refused as refused:
            return None, str(refused)
        except RecursionError:
            return None, f"a JSON object nested over {MAX_JSON_DEPTH} deep"
        except ValueError:
            start = reply.find("{", start + 1)
            continue
        if not isinstance(value, dict):
            return None, NO_JSON
        beyond = _bounded(value)
        return (None, beyond) if beyond else (value, "")
    return None, NO_JSON


def yes_no_confidence(reply: str) -> tuple[float, list[str]]:
    """P(yes) of a "<yes or no> <confidence>" reply (``parse_worth_exploring`` without its
    "worth exploring" line), and what could not be read; NaN when the reply says neither yes
    nor no nor a number (a refusal, "N/A", prose cut short)."""
    p_yes, problems = parse_worth_exploring(reply)
    if any(p.startswith(NO_YES_NO) for p in problems):
        return math.nan, problems
    return float(p_yes), [p for p in problems if not p.startswith(NO_WORTH_LINE)]
