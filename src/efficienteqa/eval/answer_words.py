"""The words of short answers, shared by the LLM-Match rules (``eval.llm_match_rules``,
``eval.llm_match_bounds``) and the synthetic questions' rule judge (``eval.synthetic_judge``).

Text split into words with contractions spelled out, plurals made singular, the vocabularies
that carry no answer or carry a yes/no, the numbers a text states, and what a text says as
yes or no (its ``stance``). Nothing here grades: the judges decide what the words are worth,
so these helpers live apart from any one of them.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

ARTICLES = frozenset({"a", "an", "the"})
# Words that carry no answer: articles, pronouns, copulas and auxiliaries, prepositions,
# conjunctions, question words.
STOPWORDS = ARTICLES | frozenset({
    "i", "me", "my", "you", "your", "we", "our", "they", "them", "their", "he", "she", "his",
    "her", "it", "its", "this", "that", "these", "those", "there", "here", "is", "are", "was",
    "were", "be", "been", "being", "am", "do", "does", "did", "have", "has", "had", "can",
    "could", "will", "would", "should", "shall", "may", "in", "on", "at", "to", "of", "for",
    "with", "by", "from", "into", "onto", "next", "and", "or", "but", "so", "what", "where",
    "which", "who", "how", "when", "why", "whether", "any", "some", "one", "ones", "s", "up",
    "if", "as", "about", "all", "just", "also", "too",
})
# Words a yes/no answer may carry beside its polarity without saying anything more.
POLARITY_FILLER = STOPWORDS | frozenset({
    "currently", "still", "right", "now", "already", "turned", "switched", "fully", "definitely",
    "certainly", "indeed", "yet", "completely", "totally", "absolutely", "really",
})
YES_WORDS = frozenset({"yes", "yeah", "yep", "yup", "affirmative", "correct"})
NO_WORDS = frozenset({"no", "nope", "none", "nothing", "negative", "nowhere"})
NEGATORS = frozenset({"not", "never"})
STATES = {"on": "off", "off": "on", "open": "closed", "closed": "open", "shut": "open"}
# "on" is a state at the end of a clause ("it is on", "on right now"), a preposition before
# anything else ("on the table").
_STATE_ON_BEFORE = frozenset({"and", "but", "right", "now", "currently", "still", "already",
                              "again", "too", "as", "yet", "so", "or"})
# Words that place something: a "where" answer holds at least one.
SPATIAL = frozenset({
    "in", "on", "at", "under", "underneath", "beneath", "below", "above", "over", "behind",
    "beside", "besides", "next", "near", "nearby", "by", "between", "inside", "outside", "against",
    "around", "atop", "top", "bottom", "front", "back", "corner", "left", "right", "hanging",
    "leaning", "upstairs", "downstairs", "here", "there", "room", "floor", "wall",
})
AUXILIARIES = frozenset({"is", "are", "was", "were", "am", "do", "does", "did", "has", "have",
                         "had", "can", "could", "will", "would", "should"})
NUMBER_WORDS = ("zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine",
                "ten", "eleven", "twelve", "thirteen", "fourteen", "fifteen", "sixteen",
                "seventeen", "eighteen", "nineteen", "twenty")
_ZERO_WORDS = frozenset({"none", "no", "zero", "nothing"})
_HEDGES = re.compile(
    r"\b(?:can not|could not|unable to|do not|does not|hard to|difficult to|impossible to)"
    r"(?: \w+){0,2} (?:tell|say|know|determine|confirm|answer|be sure)\b"
    r"|\b(?:can not|could not|unable to) (?:see|find|spot)\b"
    r"|\bnot (?:sure|certain)\b|\b(?:unsure|uncertain|unclear|unknown)\b|\bno idea\b"
    r"|\b(?:maybe|perhaps|possibly|might)\b")
_CONTRACTIONS = (
    (re.compile(r"\bcan't\b|\bcannot\b"), "can not"), (re.compile(r"\bwon't\b"), "will not"),
    (re.compile(r"n't\b"), " not"), (re.compile(r"'re\b"), " are"), (re.compile(r"'m\b"), " am"),
    (re.compile(r"'ll\b"), " will"), (re.compile(r"'ve\b"), " have"),
    (re.compile(r"\b(it|there|that|he|she|here|what|where|who)'s\b"), r"\1 is"),
)


# --- words -----------------------------------------------------------------------------------------

def words(text: str) -> list[str]:
    """Lower-case words and numbers, contractions spelled out ("isn't" -> "is not", "it's" ->
    "it is"); every other character separates words."""
    text = text.lower().replace("’", "'").replace("‘", "'")
    for pattern, replacement in _CONTRACTIONS:
        text = pattern.sub(replacement, text)
    return re.findall(r"[a-z0-9]+", text)


def stem(word: str) -> str:
    """A plural's singular, roughly and the same way on both sides ("towels" -> "towel",
    "boxes" -> "box", "shelves" stays): enough to compare the words of two short texts."""
    if len(word) <= 3 or word in STOPWORDS:
        return word
    if word.endswith("ies"):
        return word[:-3] + "y"
    if word.endswith(("ches", "shes", "xes", "sses")):
        return word[:-2]
    if word.endswith("s") and not word.endswith(("ss", "us", "is")):
        return word[:-1]
    return word


def content(text: str) -> set[str]:
    """The words of ``text`` that carry meaning, singular."""
    return {stem(w) for w in words(text) if w not in STOPWORDS}


def same_answer(a: str, b: str) -> bool:
    """Equal once case, articles and punctuation are ignored."""
    strip = [w for w in words(a) if w not in ARTICLES]
    return bool(strip) and strip == [w for w in words(b) if w not in ARTICLES]


# A count has a few digits. A longer number is read as its first MAX_COUNT_DIGITS (leading
# zeros dropped): as far from any count as the whole, and converted in bounded time (Python
# refuses to convert a string of more than 4,300 digits).
MAX_COUNT_DIGITS = 18


def number_value(word: str) -> int | None:
    if word.isdigit():
        return int(word.lstrip("0")[:MAX_COUNT_DIGITS] or "0")
    return NUMBER_WORDS.index(word) if word in NUMBER_WORDS else None


def is_state(tokens: Sequence[str], i: int) -> bool:
    """Whether ``tokens[i]`` is a state word (on/off/open/closed/shut) rather than "on" the
    preposition."""
    word = tokens[i]
    if word not in STATES:
        return False
    return word != "on" or i + 1 == len(tokens) or tokens[i + 1] in _STATE_ON_BEFORE


def negated(tokens: Sequence[str], i: int, reach: int = 3) -> bool:
    """Whether a "not"/"never"/"no" stands at most ``reach`` words before ``tokens[i]``."""
    return any(t in NEGATORS or t == "no" for t in tokens[max(0, i - reach):i])


def hedges(text: str) -> bool:
    return _HEDGES.search(" ".join(words(text))) is not None


# --- yes and no ------------------------------------------------------------------------------------

def question_state(question: str) -> str | None:
    """The state a yes/no question asks about ("Is the lamp on?" -> "on"), None for other
    questions and for a choice between both states ("on or off?")."""
    tokens = words(question)
    if not tokens or tokens[0] not in AUXILIARIES:
        return None
    found = [t for i, t in enumerate(tokens) if is_state(tokens, i)]
    if not found or any(STATES[t] in found or (t == "shut" and "open" in found) for t in found):
        return None
    return "closed" if found[-1] == "shut" else found[-1]


def yes_no_question(question: str) -> bool:
    """Asks yes or no: opens with an auxiliary ("Is", "Did") and offers no choice ("or")."""
    tokens = words(question)
    return bool(tokens) and tokens[0] in AUXILIARIES and "or" not in tokens


@dataclass(frozen=True)
class Stance:
    """What a text says as yes/no: ``value`` is "yes", "no", or a state word where the question
    does not turn it into yes/no; None when it says nothing or contradicts itself. ``bare``:
    nothing else is said (filler and the question's own words aside)."""

    value: str | None
    bare: bool
    cues: int


def stance(text: str, question: str) -> Stance:
    tokens = words(text)
    frame = question_state(question)
    asked = content(question)
    values: set[str] = set()
    consumed: set[int] = set()
    bare = bool(tokens)
    for i, word in enumerate(tokens):
        if is_state(tokens, i):
            state = "closed" if word == "shut" else word
            flip = next((j for j in range(max(0, i - 3), i) if tokens[j] in NEGATORS), None)
            if flip is not None:
                consumed.add(flip)
                state = STATES[state]
            if frame is not None:
                values.add("yes" if state == frame else "no")
            else:
                values.add(state)
        elif word in YES_WORDS:
            values.add("yes")
        elif word in NO_WORDS:
            values.add("no")
        elif word in NEGATORS:
            continue  # read once the whole text is seen: it may negate a state word
        elif word not in POLARITY_FILLER and stem(word) not in asked:
            bare = False
    values |= {"no" for i, w in enumerate(tokens) if w in NEGATORS and i not in consumed}
    cues = sum(1 for i, w in enumerate(tokens)
               if w in YES_WORDS or w in NO_WORDS or w in NEGATORS or is_state(tokens, i))
    return Stance(values.pop() if len(values) == 1 else None, bare, cues)


def opposite(a: str, b: str) -> bool:
    """Yes against no, on against off, open against closed."""
    pairs = ({"yes", "no"}, {"on", "off"}, {"open", "closed"})
    return any({a, b} == pair for pair in pairs)


# --- numbers ---------------------------------------------------------------------------------------

def numbers(text: str, question: str) -> tuple[list[int], bool]:
    """The numbers a text states (in order, repeats dropped) and whether it is bare: only
    numbers, filler and the question's words (the counted noun) besides them."""
    asked = content(question)
    found: list[int] = []
    bare = True
    for word in words(text):
        value = number_value(word)
        if value is None and word in _ZERO_WORDS:
            value = 0
        if value is not None:
            if value not in found:
                found.append(value)
        elif word not in POLARITY_FILLER and word not in ("or", "either", "maybe", "just", "only",
                                                           "exactly", "about", "around") \
                and stem(word) not in asked:
            bare = False
    return found, bare
