"""Finding the confidence in a piece of a model's reply: "confidence: 80", "70%", "(0.7)".

``parse`` (answers and letters with confidences) and ``yes_no`` (one yes/no with its
confidence) both read numbers the same way; that shared reading is here, with the trimming of
a reply that keeps every pattern linear-time. The standard library only, like ``parse``.
"""

from __future__ import annotations

import re

MAX_REPLY_CHARS = 20_000  # longer replies are cut
MAX_LINE_CHARS = 400  # and so are longer lines (no answer line is that long)

NUM = (r"(?P<num>[-+]?(?:[0-9]+(?:\.[0-9]+)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
       r"|[-+]?(?<![A-Za-z])(?:nan|inf(?:inity)?)(?![A-Za-z]))")
PCT = r"[ \t]*(?P<pct>%|percent\b|/[ \t]*100\b)?"
KEYWORD = re.compile(r"(?:confidence|conf|probability|prob|certainty|likelihood|score)[ \t]*"
                     r"(?:[:=]|is|of)?[ \t]*" + NUM + PCT, re.I)
ANY_NUM = re.compile(NUM + PCT, re.I)
# Where the confidence of a letter or of "worth exploring" is, in order of preference: after a
# keyword ("confidence: 80"), a percentage anywhere, a number ending the part ("B - 40",
# "yes (0.8)"), else the first number that is not a distance or a count ("3 m", "2 rooms",
# "2nd").
_PERCENT = re.compile(NUM + r"[ \t]*(?P<pct>%|percent\b|/[ \t]*100\b)", re.I)
_TRAILING = re.compile(r"(?:^|(?<=[\s:;,|=(\[\-–—]))" + NUM + PCT + r"[\s.,;)\]}*]*$", re.I)
_UNIT = (r"(?:m|cm|km|ft|feet|foot|metres?|meters?|steps?|rooms?|doors?|s|secs?|seconds?|mins?"
         r"|minutes?|degrees?|deg|°|x)(?![A-Za-z])")
_FREE_NUM = re.compile(r"(?<![0-9.])" + NUM + PCT + r"(?![ \t]*" + _UNIT + r")(?!\.?[0-9])(?![A-Za-z])",
                       re.I)


def prepare(reply: object, problems: list[str]) -> str:
    """The reply as text, cut to ``MAX_REPLY_CHARS`` and its lines to ``MAX_LINE_CHARS``, code
    fences dropped (a cut is said in ``problems``)."""
    text = reply if isinstance(reply, str) else ("" if reply is None else str(reply))
    if len(text) > MAX_REPLY_CHARS:
        problems.append(f"reply cut to {MAX_REPLY_CHARS} characters")
        text = text[:MAX_REPLY_CHARS]
    # One space per run and short lines keep every pattern of the parsers linear-time.
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


def find_confidence(part: str) -> re.Match[str] | None:
    """The confidence in one letter's part of a line or in the "worth exploring" answer."""
    hits = list(KEYWORD.finditer(part))
    return (hits[-1] if hits else None) or _PERCENT.search(part) or _TRAILING.search(part) \
        or _FREE_NUM.search(part)
