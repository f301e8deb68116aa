"""Verbalized confidence below explore/ and answer/: parsers that never raise, grouping E(.),
C_k, argmax, token probabilities, the prompt loader."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from efficienteqa.models.base import TokenLogprob
from efficienteqa.models.stub import StubChatModel
from efficienteqa.vc.grouping import (
    ExactGrouper,
    LLMGrouper,
    RuleGrouper,
    argmax,
    contradictory,
    group_answers,
    normalise,
)
from efficienteqa.vc.logprobs import letter_probs_from_logprobs, yes_prob_from_logprobs
from efficienteqa.vc.parse import AnswerClass, Candidate, parse_candidates, parse_letters
from efficienteqa.vc.prompts import load_prompt
from efficienteqa.vc.yes_no import DEFAULT_P_YES, parse_worth_exploring

# ---------------------------------------------------------------------------- fuzz

FRAGMENTS = [
    "A", "B", "C", "D", "a", "Z", ":", ";", " - ", "—", "%", "(", ")", "[", "]", "{", "}", ",", "\n",
    " ", "60", "0.6", "-5", "150", "1e999", "-1e999", "NaN", "nan", "inf", "-inf", "Infinity",
    "99999999999999999999999999", "0", ".5", "1.", "yes", "No", "worth exploring", "not worth",
    "confidence", "conf:", "percent", "/100", '{"answers": [', '{"answer": "red", "confidence": ',
    '"confidence": "80%"', '[{"direction": "A", "confidence": 0.7}]', '"A": 60', "```json", "```",
    "1.", "2)", "- ", "**", "答案", "🙂", "\u2028", "\x00", "\t", "ⅷ", "٣", "１２", "Direction ",
]
adversarial = st.lists(st.sampled_from(FRAGMENTS), max_size=40).map("".join)
replies = st.one_of(st.text(max_size=300), adversarial)


def _check(result, m, allowed=None):
    assert len(result.candidates) <= m
    for c in result.candidates:
        assert isinstance(c.text, str) and c.text
        assert math.isfinite(c.confidence) and 0.0 <= c.confidence <= 100.0
        if allowed is not None:
            assert c.text in allowed
    assert all(isinstance(p, str) for p in result.problems)


# 500 examples a parser: a second each in the suite (tests/faults/test_faults_parsers.py fuzzes
# the reply parsers with seeded inputs beside these)
@pytest.mark.trial("3.1")
@settings(max_examples=500, deadline=None)
@given(replies, st.integers(1, 5))
def test_parse_candidates_never_raises(reply, m):
    _check(parse_candidates(reply, m), m)


@settings(max_examples=500, deadline=None)
@given(replies, st.sampled_from(["ABC", "AB", "A", "ABCD"]))
def test_parse_letters_never_raises(reply, letters):
    _check(parse_letters(reply, list(letters)), 3, set(letters))


@settings(max_examples=500, deadline=None)
@given(replies)
def test_parse_worth_exploring_never_raises(reply):
    p, problems = parse_worth_exploring(reply)
    assert math.isfinite(p) and 0.0 <= p <= 1.0
    assert all(isinstance(x, str) for x in problems)


def test_parsers_accept_non_strings_and_huge_replies():
    for reply in (None, 42, b"A: 60", "[" * 50_000, "A: 60\n" * 10_000):
        _check(parse_candidates(reply), 3)  # type: ignore[arg-type]
        _check(parse_letters(reply, "ABC"), 3, set("ABC"))  # type: ignore[arg-type]
        assert 0 <= parse_worth_exploring(reply)[0] <= 1  # type: ignore[arg-type]


@pytest.mark.parametrize("reply", [
    "A" + " " * 20_000 + "x", "A" + " \t" * 10_000, ": 5" + " ." * 10_000 + "x", "(" * 20_000,
    "A: 1 " * 5_000, "worth " * 5_000, "1" * 20_000, "{" + '"a": [' * 3_000, "\u2003" * 20_000 + "A",
])
def test_parsers_stay_fast_on_pathological_replies(reply):
    start = time.perf_counter()
    parse_candidates(reply)
    parse_letters(reply, "ABC")
    parse_worth_exploring(reply)
    assert time.perf_counter() - start < 1.0


# ---------------------------------------------------------------------------- parser tables

def _pairs(result):
    return [(c.text, pytest.approx(c.confidence)) for c in result.candidates]


@pytest.mark.parametrize("reply, expected, clean", [
    ("red sofa; 70\nblue sofa; 20\ngrey armchair; 10",
     [("red sofa", 70), ("blue sofa", 20), ("grey armchair", 10)], True),
    ("1. red sofa — 70%\n2. blue couch — 20%\n3. green (10%)",
     [("red sofa", 70), ("blue couch", 20), ("green", 10)], True),
    ("red (0.7)\nblue (0.3)", [("red", 70), ("blue", 30)], True),
    ("kitchen: 0.5\nbedroom: 1", [("kitchen", 50), ("bedroom", 100)], True),  # fractions
    ("red: 60, blue: 30, green: 10", [("red", 60), ("blue", 30), ("green", 10)], True),
    ("Answer 1: the sofa (confidence: 80%)\nAnswer 2: a bed, confidence 20",
     [("the sofa", 80), ("a bed", 20)], True),
    ("4; 80\n5; 20", [("4", 80), ("5", 20)], True),
    ("Here are my guesses:\n- 4 chairs: 0.5\n- four: 0.3\nHope this helps.",
     [("4 chairs", 50), ("four", 30)], False),
    ('```json\n{"answers": [{"answer": "red", "confidence": 80}, '
     '{"answer": "blue", "confidence": "20%"}]}\n```', [("red", 80), ("blue", 20)], True),
    ('Sure: [{"answer": "kitchen", "confidence": 0.9}]', [("kitchen", 90)], False),
    ('[["sofa", 60], ["bed", 40]]', [("sofa", 60), ("bed", 40)], True),
    ('{"question": "What?", "answers": {"sofa": "60%", "bed": 40}}', [("sofa", 60), ("bed", 40)], True),
    ("red; 150\nblue; -5", [("red", 100), ("blue", 0)], False),  # clip, floor at 0
    ("red; 1e999\nblue; 20", [("red", 100), ("blue", 20)], False),
    ("kitchen\nbedroom\n", [("kitchen", 100 / 3), ("bedroom", 100 / 3)], False),  # default 100/m
    ("red; 60\nred; 60\nblue; 40", [("red", 60), ("blue", 40)], False),  # exact duplicate line
    ("a; 40\nb; 30\nc; 20\nd; 10", [("a", 40), ("b", 30), ("c", 20)], False),  # more than m
    ("red; nan\nblue; 50", [("red", 100 / 3), ("blue", 50)], False),
    ("", [], False),
])
def test_parse_candidates_table(reply, expected, clean):
    result = parse_candidates(reply)
    assert _pairs(result) == expected
    assert (result.problems == []) is clean, result.problems


@pytest.mark.parametrize("reply, expected, clean", [
    ("A: 60\nC: 30\nB: 10\nworth exploring: yes 80", [("A", 60), ("C", 30), ("B", 10)], True),
    ("A - 60%\nB - 40%", [("A", 60), ("B", 40)], True),
    ("A (0.6)\nB (0.4)", [("A", 60), ("B", 40)], True),
    ("A: 60, C: 30, B: 10, worth exploring: yes 80", [("A", 60), ("C", 30), ("B", 10)], True),
    ("Sure! Here you go:\n**A**: 60\nB: 30", [("A", 60), ("B", 30)], True),
    ("Direction B: 70%\nDirection A: 30%", [("B", 70), ("A", 30)], True),
    ("a: 50\nb: 50", [("A", 50), ("B", 50)], True),
    ('```json\n{"A": 60, "B": 30, "worth_exploring": "yes 70"}\n```', [("A", 60), ("B", 30)], True),
    ('[{"direction": "B", "confidence": 0.7}, {"direction": "A", "confidence": 0.3}]',
     [("B", 70), ("A", 30)], True),
    ("A: 60\nD: 20\nB: 30", [("A", 60), ("B", 30)], False),  # unknown letter
    ("A: 150\nB: -5\nC: nan", [("A", 100), ("B", 0), ("C", 100 / 3)], False),
    ("I would go to B.", [("B", 100 / 3)], False),
    ("A: 60\nA: 60\nB: 40", [("A", 60), ("B", 40)], False),
    ("A (through the open door, 4 m): 60\nB - past the sofa: 40", [("A", 60), ("B", 40)], True),
    ("A sofa is near the door\nB: 40", [("B", 40)], True),
    ("nothing useful", [], False),
    # plain replies (B4): a confidence anywhere in the letter's part, shared "each", units skipped
    ("B is best (70%), then A (30%)", [("B", 70), ("A", 30)], True),
    ("A, B: 50 each", [("A", 50), ("B", 50)], True),
    ("B: 3 m away, 40", [("B", 40)], True),
    ("I think B: 70, A: 30", [("B", 70), ("A", 30)], True),  # the pronoun is no letter
    ("A and B: 50", [("A", 50), ("B", 50)], True),
    ("B-60 A-40", [("B", 60), ("A", 40)], True),  # a dash, not a minus
    ("B (70%) is better than A", [("B", 70)], False),  # A has no confidence of its own
    ("B, then A", [("B", 100 / 3), ("A", 100 / 3)], False),  # no numbers at all: defaults
])
def test_parse_letters_table(reply, expected, clean):
    result = parse_letters(reply, ["A", "B", "C"])
    assert _pairs(result) == expected
    assert (result.problems == []) is clean, result.problems


@pytest.mark.parametrize("reply, p_yes, clean", [
    ("A: 60\nworth exploring: yes 80", 0.8, True),
    ("worth exploring: Yes (0.8)", 0.8, True),
    ("worth exploring: no, 90", 0.1, True),
    ("worth exploring: no 90%", 0.1, True),
    ("Worth exploring?\nYes, 70", 0.7, True),
    ('{"worth_exploring": "yes", "confidence": 60}', 0.6, True),
    ("worth exploring: yes/no: no 75", 0.25, True),
    ("worth exploring: yes", 0.75, False),  # bare yes
    ("worth exploring: 30", 0.3, False),  # number alone = P(yes)
    ("not worth exploring", 0.25, False),
    ("worth exploring: yes 250", 1.0, False),
    ("Yes 70", 0.7, False),  # no 'worth' line
    ("A: 60\nB: 40", DEFAULT_P_YES, False),
    ("", DEFAULT_P_YES, False),
    # B5: the confidence, not the first number after "worth"; a labelled confidence on the next line
    ("worth exploring: yes (2 rooms ahead) 80", 0.8, True),
    ("worth exploring: yes\nconfidence: 80", 0.8, True),
    ("A: 60\nworth exploring: no\nconfidence: 70%", 0.3, True),
])
def test_parse_worth_exploring_table(reply, p_yes, clean):
    p, problems = parse_worth_exploring(reply)
    assert p == pytest.approx(p_yes)
    assert (problems == []) is clean, problems


@pytest.mark.parametrize("reply, m, expected", [
    (None, 3, []), (7, 1, [("7", 50)]),  # not a string: None is nothing, anything else its text
    ("red  \t sofa; 60", 3, [("red sofa", 60)]),  # runs of spaces are one
    ("   ```\nred; 60\n```", 3, [("red", 60)]),  # code fences, even indented
    ("---\nred; 60\nblue; 40", 3, [("red", 60), ("blue", 40)]),  # a line without words
    ("**red sofa**; 60\n`blue`; 40", 3, [("red sofa", 60), ("blue", 40)]),  # markdown
    ("XBOX!; 60\n'radio'; 40", 3, [("XBOX", 60), ("radio", 40)]),
    ("red (0.5%)\nblue (0.25%)", 3, [("red", 0.5), ("blue", 0.25)]),  # a percent is no fraction
    ("red: 1.5\nblue: 0.5", 3, [("red", 1.5), ("blue", 0.5)]),  # not all <= 1: not fractions
    ("red: 60, blue: 40", 3, [("red", 60), ("blue", 40)]),
    ("answer: red\n- confidence: 80", 3, [("red", 80)]),
    ("My guesses: \nkitchen\nbedroom", 3, [("kitchen", 100 / 3), ("bedroom", 100 / 3)]),
    ("red; 60\nblue; 40", 0, [("red", 60)]),  # m < 1 counts as 1
    ('[{"answer": "red", "confidence": "0.5%"}, {"answer": "blue", "confidence": "high"}]', 3,
     [("red", 0.5), ("blue", 100 / 3)]),
    ('[{"answer": "red"}, {"answer": "blue", "confidence": 40}]', 3, [("red", 100 / 3), ("blue", 40)]),
    ('["red; 60", "blue (30%)", "green"]', 3, [("red", 60), ("blue", 30), ("green", 100 / 3)]),
    ('note {x} [["sofa", 60]]', 3, [("sofa", 60)]),  # a broken object, then a good list
    ('a { [["sofa", 60]]', 3, [("sofa", 60)]),  # an object that never closes
    ('{"a": {"b": {"c": {"d": {"e": {"f": {"red": 60}}}}}}}', 3, [("red", 60)]),  # 6 levels deep
    ('{"' + "x" * 60 + '": 50, "' + "y" * 61 + '": 50}', 3, [("x" * 60, 50)]),  # keys up to 60
])
def test_parse_candidates_reads(reply, m, expected):
    assert _pairs(parse_candidates(reply, m)) == expected


def test_json_deeper_than_six_levels_is_not_read_as_json():
    deep = '{"a": {"b": {"c": {"d": {"e": {"f": {"g": {"red": 60}}}}}}}}'
    assert [c.text for c in parse_candidates(deep).candidates] == [deep[2:]]  # read as one odd line


@pytest.mark.parametrize("reply, m, problems", [
    ('Sure: [{"answer": "kitchen", "confidence": 0.9}]', 3, ["ignored text around the JSON"]),
    ('[["sofa", 60]]x', 3, ["ignored text around the JSON"]),
    ("red; nan\nblue; 50", 3, ["non-numeric confidence (NaN)", "missing confidence for 'red': default 33.3"]),
    ("red; 150\nblue; -5", 3, ["confidence 150 clipped to 100", "negative confidence -5 set to 0"]),
    ("red; 100.5\nblue; 0\ngreen; 0.5%", 3, ["confidence 100.5 clipped to 100"]),
    ("a; 40\nb; 30\nc; 20\nd; 10", 3, ["4 candidates, kept the first 3"]),
    ("red; 60\nred; 60\nblue; 40", 3, ["duplicate line 'red' dropped"]),
    ('"; 50\nred; 50', 3, ["empty answer dropped"]),
    ("kitchen", 1, ["missing confidence for 'kitchen': default 50.0"]),
    ("the abcdefghijklmnopqrstuvwxyz", 3,
     ["missing confidence for 'the abcdefghijklmnop': default 33.3"]),  # named by 20 characters
    ("", 3, ["no answers found"]),
    ("A" * 20_000, 3, ["missing confidence for 'AAAAAAAAAAAAAAAAAAAA': default 33.3"]),
    ("A" * 20_001, 3, ["reply cut to 20000 characters",
                       "missing confidence for 'AAAAAAAAAAAAAAAAAAAA': default 33.3"]),
])
def test_parse_candidates_names_each_repair(reply, m, problems):
    assert parse_candidates(reply, m).problems == problems


@pytest.mark.parametrize("reply, expected, problems", [
    ("A: 60\nD: 20\nB: 30", [("A", 60), ("B", 30)], ["unknown letter 'D' dropped"]),
    ('{"somewhere over the rainbow": 60, "A": 40}', [("A", 40)],
     ["unknown letter 'somewhere over the r' dropped"]),
    ("nothing useful", [], ["no letters found"]),
    ("B 70%, then A or C", [("B", 70)], ["ignored letter(s) without a confidence: A, C"]),
    ('Here: {"A": 60, "B": 40}', [("A", 60), ("B", 40)], ["ignored text around the JSON"]),
    ('{"worth_exploring": 70, "A": 60, "Worth it": 80}', [("A", 60)], []),  # worth keys skipped
    ('[{"direction": "Direction B", "confidence": 70}, {"direction": "(A)", "confidence": 30}]',
     [("B", 70), ("A", 30)], []),
    ('{"go to B": 60, "a": 40}', [("B", 60), ("A", 40)], []),
    ('{"A or B": 60, "x": 40}', [], ["unknown letter 'A or B' dropped", "unknown letter 'x' dropped"]),
    ("A: 0.6%\nB: 0.4%", [("A", 0.6), ("B", 0.4)], []),  # percent, not fractions
    ("A, B: 0.5% each", [("A", 0.5), ("B", 0.5)], []),
    ("A, B, C: 30 each", [("A", 30), ("B", 30), ("C", 30)], []),
    ("C: 20, A, B: 40", [("C", 20), ("A", 40), ("B", 40)], []),  # A shares with B, not C
    ("A or B", [("A", 100 / 3), ("B", 100 / 3)],
     ["missing confidence for 'A': default 33.3", "missing confidence for 'B': default 33.3"]),
    ("B: 70% sure, 2nd of 3", [("B", 70)], []),  # a percentage beats a trailing number
])
def test_parse_letters_reads_and_names_each_repair(reply, expected, problems):
    result = parse_letters(reply, ["A", "B", "C"])
    assert _pairs(result) == expected
    assert result.problems == problems


@pytest.mark.parametrize("reply, p_yes, problems", [
    ("Yes 70", 0.7, ["no 'worth exploring' line; used the last yes/no"]),
    ("worth exploring: yes 250", 1.0, ["worth-exploring confidence 250 clipped"]),
    ("worth exploring: yes 150", 1.0, ["worth-exploring confidence 150 clipped"]),
    ("worth exploring: yes -20", 0.0, ["worth-exploring confidence -20 clipped"]),
    ("worth exploring: yes 0", 0.0, []),
    ("worth exploring: yes 100", 1.0, []),
    ("worth exploring: yes 1", 1.0, []),  # at most 1 is a probability
    ("worth exploring: yes 1.5", 0.015, []),  # above 1 a percentage
    ("", DEFAULT_P_YES, ["no worth-exploring answer: default P(yes) = 0.5"]),
    ("worth exploring: 30", 0.3, ["worth-exploring number without yes/no: read as P(yes)"]),
    ("worth exploring: yes", 0.75, ["worth-exploring 'yes' without a confidence: 0.75"]),
    ("NOT worth exploring", 0.25, ["worth-exploring 'no' without a confidence: 0.75"]),
    ("worth exploring: yes nan", 0.75, ["worth-exploring 'yes' without a confidence: 0.75"]),
    ("worth exploring: true 80", 0.8, []),
    ("worth exploring: 80, yes", 0.8, []),  # the number first
    ("worth exploring: yes, confidence 80, 2nd door 3", 0.8, []),  # the labelled number
    ("worth exploring: yes 90%, confidence 80", 0.8, []),  # the label beats a percentage
    ("Is it worth it? yes\nworth exploring: no 80", 0.2, []),  # the last "worth"
    ("worth exploring: yes\nA: 60", 0.75, ["worth-exploring 'yes' without a confidence: 0.75"]),
    ("worth exploring: yes 80\nconfidence: 90", 0.8, []),  # the line's own number first
    ("worth exploring: no, 90\nthanks", pytest.approx(0.1), []),
    ("worth exploring:\n\nyes 70", 0.7, []),  # up to two lines further
    ("worth exploring:\n\n\nyes 70", DEFAULT_P_YES, ["no worth-exploring answer: default P(yes) = 0.5"]),
])
def test_parse_worth_exploring_reads_and_names_each_repair(reply, p_yes, problems):
    p, found = parse_worth_exploring(reply)
    assert p == pytest.approx(p_yes) and found == problems


# ---------------------------------------------------------------------------- normalise, group, argmax

def test_normalise():
    assert [c.confidence for c in normalise([Candidate("a", 60), Candidate("b", 20)])] == [0.75, 0.25]
    assert [c.confidence for c in normalise([Candidate("a", 0), Candidate("b", 0)])] == [0.5, 0.5]
    assert normalise([]) == []


def test_worked_example_from_the_paper():
    # {r_i, c_i} = (sofa, 60), (couch, 30), (armchair, 30): c' = 0.5, 0.25, 0.25;
    # E(sofa) = E(couch) -> C = 0.75 and 0.25; (R*, C*) = (sofa, 0.75).
    stub = StubChatModel(lambda msgs: "yes")
    cands = parse_candidates("sofa; 60\ncouch; 30\narmchair; 30").candidates
    grouper = LLMGrouper(stub, embedder=_toy_embedder)
    classes = group_answers("What can I sit on?", cands, grouper)
    assert [(c.text, pytest.approx(c.confidence)) for c in classes] == [("sofa", 0.75), ("armchair", 0.25)]
    assert [m.text for m in classes[0].members] == ["sofa", "couch"]
    answer, conf = argmax(classes)
    assert (answer, conf) == ("sofa", pytest.approx(0.75))
    assert sum(c.confidence for c in classes) == pytest.approx(1.0)


def test_argmax_ties_go_to_first_and_empty():
    classes = [AnswerClass("x", [], 0.5), AnswerClass("y", [], 0.5)]
    assert argmax(classes) == ("x", 0.5)
    assert argmax([]) == ("", 0.0)


def test_exact_grouper_for_letters():
    labels, _ = ExactGrouper().partition("", ["A", "b", " a ", "B.", "C"])
    assert labels == [0, 1, 0, 1, 2]


def test_rule_grouper_numbers_yes_no_plurals():
    rules = RuleGrouper()
    q = "How many chairs are at the table?"
    labels, _ = rules.partition(q, ["4", "four", "4 chairs", "There are 4 chairs", "5 chairs"])
    assert labels == [0, 0, 0, 0, 1]
    assert rules.partition("Is the light on?", ["yes", "Yes, it is on", "no", "No."])[0] == [0, 0, 1, 1]
    assert rules.partition("", ["the sofas", "Sofa", "a red sofa", "red sofa"])[0] == [0, 0, 1, 1]
    assert rules.partition("", ["the red one", "red"])[0] == [0, 1]  # "one" is no count here
    # the numeric rule never merges contradicting colours
    assert rules.partition("", ["4 red chairs", "4 blue chairs"])[0] == [0, 1]


def test_veto_list():
    assert contradictory("red", "dark red and blue")
    assert contradictory("2", "three")
    assert contradictory("yes", "no")
    assert contradictory("in the kitchen", "in the bedroom")
    assert not contradictory("sofa", "couch")
    assert not contradictory("grey", "gray sofa")
    assert not contradictory("4 chairs", "four")


def _toy_embedder(texts):
    vocab = {"sofa": 0, "couch": 0, "armchair": 1, "red": 2, "blue": 2, "kitchen": 3, "bedroom": 3}
    out = np.zeros((len(texts), 5))
    for i, t in enumerate(texts):
        out[i, vocab.get(t.split()[-1].lower(), 4)] = 1.0
    return out


def test_llm_grouper_merges_synonyms_confirmed_by_the_model():
    stub = StubChatModel(lambda msgs: "Yes")
    grouper = LLMGrouper(stub, embedder=_toy_embedder)
    labels, problems = grouper.partition("What is by the window?", ["sofa", "couch", "armchair"])
    assert labels == [0, 0, 1] and problems == []
    assert len(stub.requests) == 1  # armchair is not similar: no call
    prompt = stub.requests[0].messages[0].text
    assert "What is by the window?" in prompt and "sofa" in prompt and "couch" in prompt
    grouper.partition("What is by the window?", ["couch", "sofa"])
    assert len(stub.requests) == 1  # the verdict is cached


def test_llm_grouper_veto_beats_a_wrong_model():
    stub = StubChatModel(lambda msgs: "yes")  # says everything is the same
    grouper = LLMGrouper(stub)  # no embedder: every non-vetoed pair is asked
    assert grouper.partition("What colour is the sofa?", ["red", "blue", "red sofa"])[0] == [0, 1, 0]
    assert grouper.partition("Is it on?", ["yes", "no"])[0] == [0, 1]
    assert grouper.partition("How many?", ["2", "3"])[0] == [0, 1]
    assert grouper.partition("Where?", ["kitchen", "bedroom"])[0] == [0, 1]
    # a chain must not bridge a veto: red~thing, thing~blue, but red !~ blue
    assert grouper.partition("Which?", ["red", "thing", "blue"])[0] in ([0, 0, 1], [0, 1, 1])


def test_llm_grouper_rules_first_and_unreadable_replies():
    stub = StubChatModel(lambda msgs: "hmm, hard to say")
    labels, problems = LLMGrouper(stub).partition("How many?", ["4", "four", "4 chairs"])
    assert labels == [0, 0, 0] and stub.requests == []  # no call for obvious cases
    labels, problems = LLMGrouper(stub).partition("What?", ["sofa", "couch"])
    assert labels == [0, 1] and problems and "unreadable" in problems[0]


def test_llm_grouper_bad_embeddings_fall_back_to_asking():
    stub = StubChatModel(lambda msgs: "no")
    grouper = LLMGrouper(stub, embedder=lambda texts: np.full((len(texts), 3), np.nan))
    labels, problems = grouper.partition("What?", ["sofa", "couch"])
    assert labels == [0, 1] and len(stub.requests) == 1 and problems


def test_prompts_are_package_data_and_short():
    for name, package in (("explore", "efficienteqa.explore"), ("answer", "efficienteqa.answer"),
                          ("blind", "efficienteqa.answer"), ("group", "efficienteqa.vc")):
        text = load_prompt(name, package)
        assert text.strip() and len(text.split()) * 1.3 < 150


# ---------------------------------------------------------------------------- token probabilities

def test_letter_probs_from_logprobs():
    top = [(" A", math.log(0.5)), ("b", math.log(0.25)), ("(A", math.log(0.1)), ("the", -0.1)]
    probs = letter_probs_from_logprobs(top, ["A", "B", "C"])
    assert probs == pytest.approx({"A": 0.6 / 0.85, "B": 0.25 / 0.85, "C": 0.0})
    assert letter_probs_from_logprobs([], "AB") == {"A": 0.5, "B": 0.5}
    assert letter_probs_from_logprobs({"ĠC": 0.0, "A": float("nan")}, "ABC")["C"] == 1.0


def test_letter_probs_scan_token_positions():
    tokens = [TokenLogprob("Direction", -0.1, (("Direction", -0.1), ("I", -3.0))),
              TokenLogprob(" B", math.log(0.7), ((" B", math.log(0.7)), (" A", math.log(0.3))))]
    assert letter_probs_from_logprobs(tokens, "AB") == pytest.approx({"A": 0.3, "B": 0.7})


def test_yes_prob_from_logprobs():
    assert yes_prob_from_logprobs([("Yes", math.log(0.6)), (" no", math.log(0.2))]) == pytest.approx(0.75)
    assert yes_prob_from_logprobs(TokenLogprob("▁NO", 0.0)) == 0.0
    assert yes_prob_from_logprobs(None) == DEFAULT_P_YES


@pytest.mark.parametrize("yes, no", [("Yes!", "no?"), ("ĠYes;", "Ġno!"), ("▁yes!", "▁No.")])
def test_yes_prob_reads_yes_and_no_with_any_punctuation(yes, no):
    p = yes_prob_from_logprobs([(yes, math.log(0.3)), (no, math.log(0.1))])
    assert p == pytest.approx(0.75)


def test_answer_and_confidence_on_separate_labelled_lines():
    # Qwen2.5-Coder-1.5B wrote this for a count question in an agent episode
    reply = ("answer: brown chair\nconfidence: 80\nanswer: dining room\nconfidence: 75\n"
             "answer: yes\nconfidence: 90")
    r = parse_candidates(reply)
    assert [(c.text, c.confidence) for c in r.candidates] == [
        ("brown chair", 80.0), ("dining room", 75.0), ("yes", 90.0)]
    assert r.problems == []


@pytest.mark.parametrize("raw, clean", [
    ("**a lamp**", "a lamp"), ("The answer is a lamp.", "a lamp"), ('"a lamp"', "a lamp"),
    ("The answer is **a lamp**.", "a lamp"), ("*a lamp*", "a lamp"), ("__a lamp__", "a lamp"),
    ("the answer: “blue”.", "blue"), ('"*The answer is a lamp.*"', "a lamp"),
    ("Answer is black", "black"), ("a lamp", "a lamp"), ("3.5.", "3.5"),
    # only wrappers go: words, inner punctuation, abbreviations and non-answers stay
    ("St. Louis", "St. Louis"), ("at 5 p.m.", "at 5 p.m."), ("U.S.", "U.S."),
    ("Answer isn't known", "Answer isn't known"), ("answering machine", "answering machine"),
    ("it's on the table", "it's on the table"), ("**", "**"), ("", ""),
])
def test_clean_answer_strips_markup_only(raw, clean):
    """The answer shown and recorded, without markdown emphasis, a leading "The
    answer is", surrounding quotes and a final period."""
    from efficienteqa.vc.parse import clean_answer

    assert clean_answer(raw) == clean
    assert clean_answer(clean_answer(raw)) == clean_answer(raw)  # idempotent


def test_parsed_answers_come_without_markup():
    parsed = parse_candidates('The answer is **a lamp**.; 80\n"*a rug*" - 20', m=3)
    assert [c.text for c in parsed.candidates] == ["a lamp", "a rug"]
