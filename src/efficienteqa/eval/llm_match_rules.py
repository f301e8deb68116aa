"""The rules around the LLM-Match judge (``eval.judge``): grades that need no model and bounds
on the grade the model gives.

The clear cases every judge must agree on are decided before an LLM-Match judge is asked (a
small judge gets exactly these wrong); ``rule_bounds`` holds the model's grade to what the words
alone make certain; the text helpers here are shared with the synthetic questions' rule judge
(``eval.synthetic_judge``).

Each rule of ``rule_score`` looks only at the question, the reference (and accepted answers)
and the response, never at an item's id, and says why it decided. In order, the first that
decides wins:

1. **same answer**: the response is the reference or an accepted answer once case, articles
   and punctuation are ignored: 5.
2. **count against count**: for a "how many" question, a reference and a response that are
   bare numbers (digits or words; "none", "no" and "zero" are 0; words of the question such as
   the counted noun may stand beside the number): the same number 5, one off 2, otherwise 1.
   Two numbers offered as alternatives ("two or three") are a guess: 2 when one is right,
   else 1.
3. **bare yes/no**: reference and response both reduce to a bare yes or no (only yes/no words,
   negations, on/off/open/closed and words the question already holds remain): the same
   polarity 5, the opposite 1. On/off and open/closed read as yes or no when the question asks
   about that state ("Is the lamp on?"); for a choice ("on or off?") they are compared as they
   are. A response with any more to it ("yes, in the kitchen") is left to the model.
4. **non-answer**: the response hedges ("I can't tell", "maybe", "not sure") without an
   explicit yes/no and shares no content word with the reference: 1.
5. **two guesses**: "either A or B" (or a short "A or B" when the question offers no choice):
   2 when exactly one alternative shares a content word with the reference, 1 when none does.
6. **no yes/no to a yes/no question**: the question asks yes or no (it opens with is, are,
   did, ... and offers no "or" choice), the reference is a bare yes/no, and the response
   holds no yes/no cue at all (no yes/no word, negation, state word, "there is", or a verb
   that restates the question): 1 ("a red bike" for "Is the bike next to the bed?").
7. **no place for "where"**: the question asks where, the reference names a place (a spatial
   word: in, on, next to, under, ...), and the response holds no spatial word and no word of
   the reference ("a robot vacuum cleaner" for "Where is the roomba?"): 1.
8. **echo**: every content word of the response is a word of the question and none is a word
   of the reference ("lamp" for "Is the lamp next to the bed on?"): 1.

Otherwise ``rule_score`` returns None and the model judges.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

MIN_SCORE, MAX_SCORE = 1, 5
NEAR_SCORE = 2  # one off, or two guesses of which one is right (the rubric's "mostly wrong")

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


def _opposite(a: str, b: str) -> bool:
    pairs = ({"yes", "no"}, {"on", "off"}, {"open", "closed"})
    return any({a, b} == pair for pair in pairs)


def _restates(tokens: Sequence[str]) -> bool:
    """A clause with a verb of being or a "there is": it restates the question's claim."""
    return any(t in ("is", "are", "was", "were") for t in tokens)


# --- the rules -------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Ruled:
    score: int
    rule: str  # which rule decided, and on what


def _numbers(text: str, question: str) -> tuple[list[int], bool]:
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


def _count_rule(question: str, reference: str, response: str) -> Ruled | None:
    if "how many" not in " ".join(words(question)):
        return None
    ref, ref_bare = _numbers(reference, question)
    got, got_bare = _numbers(response, question)
    if not (ref_bare and got_bare and len(ref) == 1 and got):
        return None
    want = ref[0]
    if len(got) > 1:
        return Ruled(NEAR_SCORE if want in got else MIN_SCORE,
                     f"two guesses {got} for the count {want}")
    if got[0] == want:
        return Ruled(MAX_SCORE, f"the count {want}")
    near = abs(got[0] - want) == 1 and 0 not in (want, got[0])
    return Ruled(NEAR_SCORE if near else MIN_SCORE, f"the count {got[0]}, not {want}")


def _polarity_rule(question: str, reference: str, response: str) -> Ruled | None:
    ref, got = stance(reference, question), stance(response, question)
    if not (ref.bare and got.bare and ref.value and got.value):
        return None
    if ref.value == got.value:
        return Ruled(MAX_SCORE, f"bare {got.value}, as the reference")
    if _opposite(ref.value, got.value):
        return Ruled(MIN_SCORE, f"bare {got.value} against {ref.value}")
    return None


def _alternatives(response: str, question: str) -> list[str] | None:
    """The guesses of "either A or B" (or a short "A or B" where the question offers no
    choice), None for anything else."""
    tokens = words(response)
    if "or" not in tokens:
        return None
    either = tokens[0] == "either"
    if not either and ("or" in words(question) or len(tokens) > 9):
        return None
    parts = " ".join(tokens[1:] if either else tokens).split(" or ")
    return parts if len(parts) >= 2 and all(p.strip() for p in parts) else None


def rule_score(question: str, reference: str, response: str, extra: Sequence[str] = ()
               ) -> Ruled | None:
    """The grade of a clear case (see the module docstring), or None when the model must judge."""
    if not words(response):
        return None
    if any(same_answer(ref, response) for ref in (reference, *extra)):
        return Ruled(MAX_SCORE, "the same answer")
    for rule in (_count_rule, _polarity_rule):
        ruled = rule(question, reference, response)
        if ruled is not None:
            return ruled
    accepted = set().union(*(content(r) for r in (reference, *extra)))
    said = content(response)
    got = stance(response, question)
    if hedges(response) and not any(w in YES_WORDS or w in ("no", "nope") for w in words(response)) \
            and not said & accepted:
        return Ruled(MIN_SCORE, "a non-answer")
    guesses = _alternatives(response, question)
    if guesses is not None:
        right = [g for g in guesses if content(g) & accepted]
        if len(right) == 1:
            return Ruled(NEAR_SCORE, "two guesses, one of them right")
        if not right:
            return Ruled(MIN_SCORE, "guesses, none of them right")
    ref = stance(reference, question)
    tokens = words(response)
    there_is = any(a == "there" and b in ("is", "are") for a, b in zip(tokens, tokens[1:]))
    if yes_no_question(question) and ref.bare and ref.value in ("yes", "no") and got.cues == 0 \
            and not there_is and not _restates(tokens):
        return Ruled(MIN_SCORE, "no yes or no to a yes/no question")
    if "where" in words(question) and any(w in SPATIAL for w in words(reference)) \
            and not any(w in SPATIAL for w in tokens) and not said & accepted:
        return Ruled(MIN_SCORE, "no place for a where question")
    asked = content(question)
    if said and said <= asked and not said & accepted \
            and not (yes_no_question(question) and _restates(tokens)):
        return Ruled(MIN_SCORE, "only repeats words of the question")
    return None


# --- bounds on the model's grade -------------------------------------------------------------------

# Spellings of one word that the rubric counts as the same answer (its own examples: grey/gray,
# fridge/refrigerator; couch/sofa and TV/television from the judge prompt), and digits for the
# number words: compared as one word when a response is checked for the reference's words.
SAME_WORDS = {"grey": "gray", "fridge": "refrigerator", "couch": "sofa", "tv": "television",
              **{str(n): w for n, w in enumerate(NUMBER_WORDS)}}
# Place words that are stop words elsewhere but change a place ("on" the shelf is not "under" it).
_PLACE_WORDS = SPATIAL & STOPWORDS


def _signature(text: str) -> set[str]:
    """The words of ``text`` that carry its answer: content words (singular, one spelling of
    each synonym above) and place words."""
    return {SAME_WORDS.get(s, s) for s in (stem(w) for w in words(text)
                                           if w not in STOPWORDS or w in _PLACE_WORDS)}


# Colour words by family: a colour of the same family is a close shade (the rubric's "navy" for
# "blue", "burgundy" for "red"), a colour of no shared family is another colour. Some shades
# sit in two families.
COLOUR_FAMILIES: tuple[frozenset[str], ...] = tuple(frozenset(f.split()) for f in (
    "red burgundy maroon crimson scarlet wine cherry rust ruby",
    "pink rose magenta fuchsia salmon coral blush",
    "orange peach coral apricot rust amber tangerine",
    "yellow gold golden mustard lemon amber cream",
    "green olive lime emerald mint sage teal khaki forest",
    "blue navy teal turquoise azure cobalt indigo cyan aqua sky denim",
    "purple violet lavender lilac mauve plum indigo magenta",
    "brown tan beige wheat khaki chocolate bronze caramel coffee walnut mahogany chestnut taupe",
    "white ivory cream offwhite eggshell pearl beige",
    "gray silver charcoal slate ash taupe steel",
    "black charcoal ebony jet",
))
_COLOURS = frozenset().union(*COLOUR_FAMILIES)


def _colours(text: str) -> set[str]:
    return {SAME_WORDS.get(w, w) for w in words(text)} & _COLOURS


def _other_colour(question: str, reference: str, response: str) -> int | None:
    """The most a response may score that names only colours of other families than the
    reference's, where the colour is the answer: 1 when the question asks for a colour or the
    answer is only a colour ("the white one" for "green one"); 2 when the colours are all that
    differ from a longer answer ("the black cabinet" for "the blue cabinet": the right thing,
    the wrong colour); None otherwise."""
    ref, got = _colours(reference), _colours(response)
    if not ref or not got or any(r in f and g in f for r in ref for g in got for f in COLOUR_FAMILIES):
        return None
    if {"colour", "color", "colours", "colors"} & set(words(question)):
        return MIN_SCORE
    asked = content(question) | _PLACE_WORDS
    rest = _signature(reference) - ref - asked
    if rest != _signature(response) - got - asked:
        return None
    return NEAR_SCORE if rest else MIN_SCORE


@dataclass(frozen=True)
class Bounds:
    """The range the model's grade is held to (``low`` <= grade <= ``high``) and why."""

    low: int
    high: int
    rule: str


def rule_bounds(question: str, reference: str, response: str, extra: Sequence[str] = ()
                ) -> Bounds | None:
    """Limits that the rubric puts on a grade the model gives (``rule_score`` said nothing), or
    None. A small judge under-grades right answers in other words and lifts wrong yes/no
    answers; these rules hold it to what the words alone make certain:

    1. **opposite yes/no**: reference and response state opposite polarities or states (with
       more words than a bare yes/no: "Yes, some dishes" for "No"): at most 1.
    2. **same yes/no**: both state the same polarity or state, the response not hedging: at
       least 4 when the reference is a bare yes/no ("Yes, by the window" for "Yes": the
       rubric's "right plus an unsupported claim"), at least 3 when the response is bare and
       the reference says more ("Yes" for "Yes, a plate of cookies": right, less specific).
       Neither when both say more ("yes, in the bedroom" for "yes, in the kitchen").
    3. **another colour**: the response names colours, none of the reference's family of shades
       (or of an accepted answer's), where the colour is the answer: 1 when the question asks
       for a colour or the answer is a bare colour ("the white one" for "green one"), at most
       2 when only the colour differs ("the black cabinet" for "the blue cabinet").
    4. **the reference's words**: every word that carries the reference (its content words that
       the question does not hold already, and its place words: "under" is not "on") is in
       the response, which neither negates, hedges nor offers alternatives, and, for "how
       many", states no other number: at least 4 ("Navy blue" for "Blue one"); at least 5 when
       the response adds no word of its own ("It's grey." for "gray").
    """
    tokens = words(response)
    if not tokens:
        return None
    got = stance(response, question)
    refs = [stance(ref_text, question).value for ref_text in (reference, *extra)]
    if got.value and got.value not in refs:
        against = next((r for r in refs if r and _opposite(r, got.value)), None)
        if against is not None:
            return Bounds(MIN_SCORE, MIN_SCORE, f"says {got.value} against {against}")
    if hedges(response) or "or" in tokens or any(t in NEGATORS for t in tokens):
        return None
    caps = [_other_colour(question, ref_text, response) for ref_text in (reference, *extra)]
    if all(cap is not None for cap in caps):
        cap = max(c for c in caps if c is not None)
        return Bounds(MIN_SCORE, cap, "another colour" if cap == MIN_SCORE
                      else "another colour of the same thing")
    for ref_text in (reference, *extra):
        ref = stance(ref_text, question)
        if ref.value and got.value == ref.value and ref.bare:
            return Bounds(MAX_SCORE - 1, MAX_SCORE, f"says {got.value}, as the bare reference")
        if ref.value and got.value == ref.value and got.bare:
            return Bounds(MAX_SCORE - 2, MAX_SCORE, f"a bare {got.value}, as the reference")
    asked = content(question)
    said = _signature(response)
    counting = "how many" in " ".join(words(question))
    for ref_text in (reference, *extra):
        needed = _signature(ref_text) - {SAME_WORDS.get(w, w) for w in asked}
        if not needed - _PLACE_WORDS or not needed <= said:
            continue
        if counting and _numbers(response, question)[0] != _numbers(ref_text, question)[0]:
            continue
        own = said - needed - {SAME_WORDS.get(w, w) for w in asked} - _PLACE_WORDS
        if own:
            return Bounds(MAX_SCORE - 1, MAX_SCORE, "holds the reference's words, and more")
        return Bounds(MAX_SCORE, MAX_SCORE, "the reference's words, nothing more")
    return None
