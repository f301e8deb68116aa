"""The text on either side of a judge's call: the response cut as it is graded, and the grade
read back from the judge's reply (a 1-5 score, an OpenEQA-style mark, or P(yes) from the token
probabilities of a one-token reply).

Kept apart from the judge itself (``eval.judge``) because these are pure functions of text and
tokens, with no model and no cache: each must read a bad reply leniently and in time linear in
its length, and is tested (and fuzzed) on its own. A reply that holds no grade gives None and the
problems found, never an exception.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

from efficienteqa.eval.llm_match_rules import MAX_SCORE, MIN_SCORE
from efficienteqa.models.base import TokenLogprob

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


# --- OpenEQA's protocol ------------------------------------------------------------------------

# The words before the mark in an OpenEQA-style reply.
OPENEQA_TAG = "Your mark:"


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


# --- yes-prob ----------------------------------------------------------------------------------

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
