"""Bounds on the grade an LLM-Match judge's model gives (``eval.judge``), from the words alone.

A small judge under-grades right answers in other words and lifts wrong yes/no answers;
``rule_bounds`` holds its grade to what the words make certain: opposite yes/no, the same
yes/no, another colour, the reference's own words. They act on the model's grade where
``rule_score`` (``eval.llm_match_rules``) decided nothing, rather than instead of the model, and
bring their own vocabulary (colour families, synonyms): a second set of rules, kept apart.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from efficienteqa.eval.answer_words import (
    NEGATORS,
    NUMBER_WORDS,
    SPATIAL,
    STOPWORDS,
    content,
    hedges,
    numbers,
    opposite,
    stance,
    stem,
    words,
)
from efficienteqa.eval.llm_match_rules import MAX_SCORE, MIN_SCORE, NEAR_SCORE

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
        against = next((r for r in refs if r and opposite(r, got.value)), None)
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
        if counting and numbers(response, question)[0] != numbers(ref_text, question)[0]:
            continue
        own = said - needed - {SAME_WORDS.get(w, w) for w in asked} - _PLACE_WORDS
        if own:
            return Bounds(MAX_SCORE - 1, MAX_SCORE, "holds the reference's words, and more")
        return Bounds(MAX_SCORE, MAX_SCORE, "the reference's words, nothing more")
    return None
