"""Fault trials of section 3: the parsers of model replies under hostile input. 3.1 ran 100,000
random inputs (1.2 million calls) for 224 s; here a seeded fuzz of a few thousand inputs holds
the same ranges: confidences in [0, 100], probabilities in [0, 1] summing to 1, judge grades
1-5, and no exception. 3.2-3.4 (p_yes underflow, an empty question, long digit runs) are held
by tests/test_judge.py and tests/test_answer_calls.py as well."""

from __future__ import annotations

import math
import random

import pytest

from efficienteqa.eval.judge import score_value
from efficienteqa.eval.judge_parse import openeqa_mark, p_yes, parse_score, trim_response
from efficienteqa.models.base import TokenLogprob
from efficienteqa.vc.json_reply import json_reply
from efficienteqa.vc.logprobs import letter_probs_from_logprobs, yes_prob_from_logprobs
from efficienteqa.vc.parse import parse_candidates, parse_letters
from efficienteqa.vc.yes_no import parse_worth_exploring, yes_no_confidence
from faults.harness import trial

PIECES = [
    "A", "B", "C", "D", "yes", "No", "YES", " ", "\n", "\r\n", "\t", ":", ";", ",", ".", "%", "-",
    "(", ")", "[", "]", "{", "}", '"', "'", "**", "```json", "```", "Score:", "score", "/5",
    "out of 5", "1-5", "3 or 4", "Your mark:", "confidence", "worth exploring", "not worth",
    "0", "1", "3", "5", "7", "60", "0.6", "-5", "150", "1e999", "-1e999", "nan", "NaN", "inf",
    "-inf", "4.0", "9" * 60, "0" * 40, '{"score": ', '{"answers": [', '{"answer": "red", '
    '"confidence": ', '"80%"', "“", "”", "\u202e", "\x00", "\x1b[31m", "🪑", "答案", "٣", "１２",
    "ⅷ", "\u2028", "\ufeff", "Direction ", "a red sofa", "the kitchen",
]
LOGPROBS = [0.0, -0.1, -1.0, -5.0, -745.0, -800.0, -1000.0, -9999.0, -1e308, 1e308, math.inf,
            -math.inf, math.nan, 3.0]
TOKENS = ["Yes", "No", "\u2581Yes", "\u0120no", " YES", "A", " (B", "c.", "D", "The", "", "\n"]


def replies(rng: random.Random, n: int) -> list[str]:
    out = []
    for _ in range(n):
        if rng.random() < 0.2:  # any characters at all
            out.append("".join(chr(rng.randrange(0x110000)) for _ in range(rng.randrange(40)))
                       .encode("utf-8", "replace").decode("utf-8", "replace"))
        else:
            out.append("".join(rng.choice(PIECES) for _ in range(rng.randrange(30))))
    return out


def logprobs(rng: random.Random) -> list[TokenLogprob]:
    return [TokenLogprob(rng.choice(TOKENS), rng.choice(LOGPROBS),
                         tuple((rng.choice(TOKENS), rng.choice(LOGPROBS))
                               for _ in range(rng.randrange(6))))
            for _ in range(rng.randrange(4))]


def check_candidates(result, m: int, allowed: set[str] | None = None) -> None:
    assert len(result.candidates) <= m
    for c in result.candidates:
        assert isinstance(c.text, str) and c.text
        assert math.isfinite(c.confidence) and 0.0 <= c.confidence <= 100.0
        assert allowed is None or c.text in allowed


def probability(p: float) -> bool:
    return isinstance(p, float) and 0.0 <= p <= 1.0


@trial("3.1")
def test_a_seeded_fuzz_of_the_reply_parsers_stays_in_range():
    rng = random.Random(42)
    texts = replies(rng, 2500)
    assert len(set(texts)) > 2000
    for text in texts:
        m = rng.randrange(1, 6)
        check_candidates(parse_candidates(text, m), m)
        check_candidates(parse_letters(text, list("ABC")), 3, set("ABC"))
        p, problems = parse_worth_exploring(text)
        assert probability(p) and all(isinstance(x, str) for x in problems)
        p, _ = yes_no_confidence(text)
        assert math.isnan(p) or probability(p)
        score, problems = parse_score(text)
        assert (score is None and problems) or (score in range(1, 6) and not problems)
        assert 0.0 <= score_value(score) <= 100.0
        assert openeqa_mark(text) in (None, 1, 2, 3, 4, 5)
        assert isinstance(trim_response(text), str)
        said, why = json_reply(text)
        assert (said is None and why) or (isinstance(said, dict) and why == "")
    for _ in range(1500):
        tokens = logprobs(rng)
        letters = letter_probs_from_logprobs(tokens, list("ABCD"))
        assert sorted(letters) == list("ABCD") and all(probability(v) for v in letters.values())
        assert sum(letters.values()) == pytest.approx(1.0)
        assert probability(yes_prob_from_logprobs(tokens))
        yes = p_yes(tokens)
        assert yes is None or probability(yes)


@trial("3.2")
@pytest.mark.parametrize("yes, no, expected", [
    (-1000.0, -1000.5, 1 / (1 + math.exp(-0.5))),  # 0.622: both underflow exp()
    (-9999.0, -9999.0, None),  # vLLM's mask on both: no answer
    (1e308, math.nan, 1.0),  # a logprob above 0 is 0; NaN holds nothing
    (-math.inf, -math.inf, None),
])
def test_p_yes_of_the_trials_logprobs(yes, no, expected):
    token = TokenLogprob("Yes", yes, (("Yes", yes), ("No", no)))
    if expected is None:
        assert p_yes([token]) is None
    else:
        assert p_yes([token]) == pytest.approx(expected, abs=1e-3)
