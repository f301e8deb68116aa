"""The synthetic questions' judge, ``rule``: answers graded by the generator's key, with no model.

A synthetic question carries every accepted form of its answer (``EvalQuestion.accepted``:
synonyms, digits or words, grey/gray, "on"/"open" for yes), and ``envs.synthetic.answers``
knows every value an answer of its kind could take. A response is right (5) when, after
normalisation (case, punctuation, contractions, plurals), it states an accepted answer and does
not also state a contradicting one; otherwise it is wrong (1). In detail:

- **hedges** ("I can't tell", "maybe", "not sure") state nothing: 1;
- **counts**: the numbers stated (digits, words, "none"/"zero") must be exactly the answer's:
  "two or three" states a contradicting number;
- **yes/no** (existence and state questions): the response's stance (``answer_words.stance``:
  yes/no words, negations, "on"/"off" and "open"/"closed" read against the question,
  "there is" for existence) must be the answer's and not both: "yes and no" is wrong;
- **colours, objects, rooms**: mentions are found by longest match over the accepted forms and
  the kind's lexicon; a negated mention ("not red") states nothing; a word that only modifies
  the next one ("glass vase", "navy blue") is not a mention; words of the question are not
  answers ("the bread on the bookshelf" names the bookshelf the question asked about). For a
  location, another room contradicts, and so does another surface after "on" when the object
  stands on one ("on the desk" for "on the table in the kitchen"); the room alone or the
  surface alone is right, as the generator's alternatives say.

A missing answer scores 0 like any LLM-Match grade. The grade's ``raw`` says which answer was
found and what contradicted it.
"""

from __future__ import annotations

from collections.abc import Sequence

from efficienteqa.eval.answer_words import NEGATORS, hedges, number_value, stance, stem, words
from efficienteqa.eval.judge import MISSING_ANSWER, Judgement, score_value
from efficienteqa.eval.judge_parse import trim_response
from efficienteqa.eval.llm_match_rules import MAX_SCORE, MIN_SCORE

RULE_JUDGE = "rule"
RULE_CATEGORIES = frozenset({"count", "existence", "state", "colour", "identification", "location"})
_MAX_PHRASE = 4
_SURFACE_MARKERS = ("on", "atop", "top")
_LEAD = frozenset({"the", "a", "an", "of", "my", "your", "top"})


def _key(text: str) -> tuple[str, ...]:
    return tuple(stem(w) for w in words(text))


def _verdict(right: bool, raw: str) -> Judgement:
    score = MAX_SCORE if right else MIN_SCORE
    return Judgement(score, score_value(score), RULE_JUDGE, raw)


def rule_judgement(question: str, category: str, accepted: Sequence[str],
                   response: str | None) -> Judgement:
    """The grade of ``response`` to a synthetic question of ``category`` whose accepted answers
    are ``accepted`` (see the module docstring)."""
    if response is None or not response.strip():
        return Judgement(None, 0.0, RULE_JUDGE, problems=(MISSING_ANSWER,))
    if not accepted:
        raise ValueError("the rule judge needs the question's accepted answers")
    response = trim_response(response)
    if hedges(response):
        return _verdict(False, "rule: a hedge states no answer")
    if category == "count":
        return _count(accepted, response)
    if category in ("existence", "state"):
        return _polarity(question, accepted, response)
    return _mentions(question, category, accepted, response)


def _count(accepted: Sequence[str], response: str) -> Judgement:
    want = {v for v in (number_value(a) for a in accepted) if v is not None}
    tokens = words(response)
    stated: set[int] = set()
    for i, word in enumerate(tokens):
        value = number_value(word)
        if value is None and word in ("none", "zero", "nothing"):
            value = 0
        if value is None and word == "no" and (i + 1 == len(tokens) or number_value(tokens[i + 1]) is None):
            value = 0
        if value is not None and not (i > 0 and tokens[i - 1] in NEGATORS):
            stated.add(value)
    right = bool(stated) and stated <= want
    return _verdict(right, f"rule: states {sorted(stated) or 'no number'}, accepted {sorted(want)}")


def _polarity(question: str, accepted: Sequence[str], response: str) -> Judgement:
    want = "yes" if "yes" in accepted else "no"
    said = stance(response, question)
    value = said.value
    if said.cues == 0:
        tokens = words(response)
        if any(a == "there" and b in ("is", "are") for a, b in zip(tokens, tokens[1:])):
            value = "yes"  # "there is a sofa" with no negation anywhere
    if value in ("on", "open"):  # a state word where the question asks about none
        value = "yes"
    elif value in ("off", "closed"):
        value = "no"
    return _verdict(value == want, f"rule: says {value or 'neither or both'}, accepted {want}")


def _lexicon(category: str, accepted: Sequence[str]) -> dict[tuple[str, ...], tuple[str, bool]]:
    """Phrase (stemmed words) -> (kind, accepted?) for every form the response may use."""
    from efficienteqa.envs.synthetic.answers import lexicon

    kinds = {"colour": ("colour",), "identification": ("object",),
             "location": ("room", "object")}.get(category)
    if kinds is None:
        raise ValueError(f"the rule judge does not grade {category!r} questions")
    table: dict[tuple[str, ...], tuple[str, bool]] = {}
    for kind in kinds:
        for form in lexicon(kind):
            table.setdefault(_key(form), (kind, False))
    for form in accepted:
        key = _key(form)
        kind = table.get(key, (kinds[0], False))[0]
        table[key] = (kind, True)
    return table


def _mentions(question: str, category: str, accepted: Sequence[str], response: str) -> Judgement:
    table = _lexicon(category, accepted)
    asked = {key for key in table if _contains(_key(question), key)}
    has_surface = category == "location" and any(
        table.get(_key(a), ("", False))[0] == "object" for a in accepted)
    tokens = [stem(w) for w in words(response)]
    found: list[tuple[int, int, str, bool]] = []  # (start, end, kind, accepted)
    i = 0
    while i < len(tokens):
        for n in range(min(_MAX_PHRASE, len(tokens) - i), 0, -1):
            hit = table.get(tuple(tokens[i:i + n]))
            if hit is not None:
                found.append((i, i + n, *hit))
                i += n
                break
        else:
            i += 1
    stated, contradicting = [], []
    for k, (start, end, kind, ok) in enumerate(found):
        phrase = " ".join(tokens[start:end])
        if any(t in NEGATORS for t in tokens[max(0, start - 2):start]):
            continue  # "not red"
        if kind != "room" and k + 1 < len(found) and found[k + 1][0] == end \
                and found[k + 1][2] == kind:
            continue  # "glass vase", "navy blue": a modifier of the next word
        if ok:
            stated.append(phrase)
        elif tuple(tokens[start:end]) in asked:
            continue  # the question's own objects and rooms
        elif kind == "object" and category == "location" and not (
                has_surface and _after_on(tokens, start)):
            continue  # a landmark ("next to the sofa"), not the object's support
        else:
            contradicting.append(phrase)
    right = bool(stated) and not contradicting
    raw = f"rule: states {stated or 'no accepted answer'}"
    if contradicting:
        raw += f", contradicted by {contradicting}"
    return _verdict(right, raw)


def _contains(haystack: tuple[str, ...], needle: tuple[str, ...]) -> bool:
    n = len(needle)
    return any(haystack[i:i + n] == needle for i in range(len(haystack) - n + 1))


def _after_on(tokens: Sequence[str], start: int) -> bool:
    """Whether the mention at ``start`` is what something stands on ("on the desk", "on top of
    the desk")."""
    j = start - 1
    while j >= 0 and tokens[j] in _LEAD:
        j -= 1
    return j >= 0 and tokens[j] in _SURFACE_MARKERS
