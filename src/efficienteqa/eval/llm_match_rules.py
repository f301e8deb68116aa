"""The clear cases of the LLM-Match judge (``eval.judge``): grades that need no model.

The clear cases every judge must agree on are decided before an LLM-Match judge is asked (a
small judge gets exactly these wrong); the bounds on the grade the model gives are in
``eval.llm_match_bounds``, the words both read in ``eval.answer_words``.

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

from collections.abc import Sequence
from dataclasses import dataclass

from efficienteqa.eval.answer_words import (
    SPATIAL,
    YES_WORDS,
    content,
    hedges,
    numbers,
    opposite,
    same_answer,
    stance,
    words,
    yes_no_question,
)

MIN_SCORE, MAX_SCORE = 1, 5
NEAR_SCORE = 2  # one off, or two guesses of which one is right (the rubric's "mostly wrong")


@dataclass(frozen=True)
class Ruled:
    score: int
    rule: str  # which rule decided, and on what


def _restates(tokens: Sequence[str]) -> bool:
    """A clause with a verb of being or a "there is": it restates the question's claim."""
    return any(t in ("is", "are", "was", "were") for t in tokens)


def _count_rule(question: str, reference: str, response: str) -> Ruled | None:
    if "how many" not in " ".join(words(question)):
        return None
    ref, ref_bare = numbers(reference, question)
    got, got_bare = numbers(response, question)
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
    if opposite(ref.value, got.value):
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
