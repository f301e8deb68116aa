"""P(yes) of a yes/no reply with a confidence: "worth exploring: yes 80", "no (0.9)".

The exploration's "worth exploring" answer and the yes/no questions of answering and matching
are read here; it is apart from ``parse`` (the lists of answers or letters with confidences)
because it reads one yes/no, not a list. It finds the number as ``numbers`` does, and stays
as light as ``parse``: the standard library only.
"""

from __future__ import annotations

import math
import re

from efficienteqa.vc.numbers import NUM, PCT, find_confidence, prepare, to_float

# "worth exploring" with no yes/no at all: P(yes) = 0.5; a bare "yes"/"no" without a number
# is read as 75 % sure.
DEFAULT_P_YES = 0.5
BARE_YES_NO_CONFIDENCE = 0.75

_CONF_LINE = re.compile(r"^[ \t]*(?:(?:" + "|".join(("confidence", "conf", "probability", "prob", "certainty",
                                                     "likelihood", "score")) + r")\b|" + NUM + PCT
                        + r"[ \t.]*$)", re.I)
_YES_NO = re.compile(r"(?<![A-Za-z])(yes|no|true|false)(?![A-Za-z])", re.I)

# The problem that says a reply held neither a yes/no nor a confidence: nothing was read.
NO_YES_NO = "no worth-exploring answer"
NO_WORTH_LINE = "no 'worth exploring' line"  # a yes/no was read, from another line


def parse_worth_exploring(reply: str) -> tuple[float, list[str]]:
    """P(yes) in [0, 1] from ``worth exploring: yes 80`` / ``Yes (0.8)`` / ``no, 90`` (-> 0.1).

    A bare yes/no reads as ``BARE_YES_NO_CONFIDENCE``; a number alone as P(yes); nothing readable
    gives ``DEFAULT_P_YES``. Never raises."""
    problems: list[str] = []
    text = prepare(reply, problems)
    idx = text.lower().rfind("worth")
    negated = False
    if idx >= 0:
        negated = bool(re.search(r"not\s*$", text[max(0, idx - 8):idx], re.I))
        lines = text[idx + 5:].split("\n")
        seg = lines[0]
        for extra in lines[1:3]:
            # look further while nothing is found, or for the confidence of a bare yes/no
            # given on the next line ("yes" then "confidence: 80")
            if find_confidence(seg) or (_YES_NO.search(seg) and not _CONF_LINE.match(extra)):
                break
            seg += "\n" + extra
    else:
        seg = next((ln for ln in reversed(text.splitlines()) if _YES_NO.search(ln)), "")
        if seg:
            problems.append(f"{NO_WORTH_LINE}; used the last yes/no")
    words = list(_YES_NO.finditer(seg))
    hit = find_confidence(seg)
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


def yes_no_confidence(reply: str) -> tuple[float, list[str]]:
    """P(yes) of a "<yes or no> <confidence>" reply (``parse_worth_exploring`` without its
    "worth exploring" line), and what could not be read; NaN when the reply says neither yes
    nor no nor a number (a refusal, "N/A", prose cut short)."""
    p_yes, problems = parse_worth_exploring(reply)
    if any(p.startswith(NO_YES_NO) for p in problems):
        return math.nan, problems
    return float(p_yes), [p for p in problems if not p.startswith(NO_WORTH_LINE)]
