"""LLM-Match judge: parsing, the 0-100 mapping, trimming, the retry/default path and the cache."""

from __future__ import annotations

import math

import pytest

from conftest import needs_small_model
from efficienteqa.eval.judge import (
    DEFAULT_SCORE,
    MISSING_ANSWER,
    SCORE_SCHEMA,
    Judgement,
    LLMMatchJudge,
    score_value,
)
from efficienteqa.eval.judge_parse import parse_score, trim_response
from efficienteqa.eval.judge_prompts import render_prompt
from efficienteqa.eval.llm_match_rules import rule_score
from efficienteqa.models.base import Capabilities
from efficienteqa.models.stub import StubChatModel

PLAIN = Capabilities()  # no constrained output: the judge must read prose


@pytest.mark.parametrize("reply, score", [
    ("4", 4), ("Score: 4", 4), ("**4**", 4), ("4/5", 4), ("I would give it a 5.", 5),
    ("Rating: 3 out of 5", 3), ("The response names the same object, so 5.", 5),
    ('{"score": 2}', 2), ('{ "score": 5 }', 5), ("Score: **4** (close enough)", 4),
    ("4\n\nThe response matches the reference.", 4), ("On a 1-5 scale I rate it 2", 2),
    ('The response "3 mugs" is wrong. Score: 1', 1),  # the number in the quote is not the score
])
def test_parse_reads_the_score(reply, score):
    assert parse_score(reply) == (score, [])


@pytest.mark.parametrize("reply, problem", [
    ("7", "out of range"), ("Score: 0", "out of range"), ('{"score": 9}', "out of range"),
    ("4.5", "not a whole number"), ("", "empty reply"), ("The response is fine.", "no score"),
    ("3 or 4", "conflicting"), ("Score: 4. On reflection, score: 2", "conflicting"),
])
def test_parse_reports_problems_instead_of_guessing(reply, problem):
    score, problems = parse_score(reply)
    assert score is None and len(problems) == 1 and problem in problems[0]


def test_score_value_maps_1_to_5_onto_0_to_100():
    assert [score_value(s) for s in (1, 2, 3, 4, 5, None)] == [0.0, 25.0, 50.0, 75.0, 100.0, 0.0]


@pytest.mark.parametrize("text, trimmed", [
    ("A red mug. It is on", "A red mug."), ("A red mug.", "A red mug."), ("a red mug", "a red mug"),
    ("It is 3.5 cm", "It is 3.5 cm"), ("It is 3.5 cm wide. Near the", "It is 3.5 cm wide."),
    ("Two mugs. Both red.", "Two mugs. Both red."), ("  in the kitchen  ", "in the kitchen"),
])
def test_trim_cuts_after_the_last_full_stop_but_not_inside_a_number(text, trimmed):
    assert trim_response(text) == trimmed


def test_prompt_puts_the_fixed_part_first_and_lists_extra_answers():
    a = render_prompt("Where is the {mug}?", "kitchen", "in the kitchen", ["the cooking area", " "])
    b = render_prompt("What colour is the rug?", "red", "red")
    prefix = a.index("Question: Where is the {mug}?")
    assert a[:prefix] == b[:prefix] and prefix > 500  # fixed instructions and examples first
    assert a[prefix:] == ("Question: Where is the {mug}?\nCorrect answer: kitchen\n"
                          "Also accepted: the cooking area\nResponse: in the kitchen\nScore:")
    assert "Also accepted" not in b[prefix:]


@pytest.mark.parametrize("response", [None, "", "   \n"])
def test_a_missing_answer_scores_zero_without_a_model_call(tmp_path, response):
    model = StubChatModel([], name="judge-model")
    judgement = LLMMatchJudge(model, tmp_path / "j.sqlite").judge("Q?", "red", response)
    assert judgement == Judgement(None, 0.0, "judge-model", problems=(MISSING_ANSWER,))
    assert model.requests == []


def test_a_grade_records_the_judge_and_asks_for_a_short_deterministic_json_reply(tmp_path):
    model = StubChatModel(['{"score": 4}'], name="qwen-judge")
    judge = LLMMatchJudge(model, tmp_path / "j.sqlite")
    judgement = judge.judge("Where is the kettle?", "on the counter", "in the kitchen. It is", ["x"])
    assert (judgement.score, judgement.value, judgement.judge) == (4, 75.0, "qwen-judge")
    assert judge.name == "qwen-judge" and not judgement.cached and judgement.problems == ()
    assert judgement.to_dict()["problems"] == [] and judgement.to_dict()["judge"] == "qwen-judge"
    (request,) = model.requests
    assert request.json_schema == SCORE_SCHEMA and request.temperature == 0.0
    assert request.max_tokens <= 32
    assert request.messages[0].text.endswith("Response: in the kitchen.\nScore:")  # trimmed


def test_grammar_servers_are_constrained_too_and_plain_ones_are_not(tmp_path):
    grammar = StubChatModel(['{"score": 5}'], capabilities=Capabilities(grammar=True))
    plain = StubChatModel(["Score: 5"], capabilities=PLAIN)
    for model in (grammar, plain):
        assert LLMMatchJudge(model, tmp_path / f"{id(model)}.sqlite").judge("Q?", "red", "crimson").score == 5
    assert grammar.requests[0].json_schema == SCORE_SCHEMA
    assert plain.requests[0].json_schema is None


def test_an_unreadable_reply_is_retried_with_a_reminder(tmp_path):
    model = StubChatModel(["The response is quite good.", "4"], capabilities=PLAIN)
    judgement = LLMMatchJudge(model, tmp_path / "j.sqlite").judge("Q?", "red", "dark red")
    assert (judgement.score, judgement.raw) == (4, "4")
    assert judgement.problems == ("retried after: no score in reply",)
    first, second = model.requests
    assert [m.role for m in second.messages] == ["user", "assistant", "user"]
    assert second.messages[0] == first.messages[0] and "1 to 5" in second.messages[2].text


def test_unreadable_twice_falls_back_to_the_default_and_says_so(tmp_path):
    model = StubChatModel(["Hmm.", "Score: 9"], capabilities=PLAIN)
    judgement = LLMMatchJudge(model, tmp_path / "j.sqlite").judge("Q?", "a mug", "a plate")
    assert (judgement.score, judgement.value) == (DEFAULT_SCORE, score_value(DEFAULT_SCORE))
    assert judgement.problems[0] == "retried after: no score in reply"
    assert "out of range" in judgement.problems[1] and "unreadable" in judgement.problems[-1]
    assert len(model.requests) == 2


def test_the_cache_answers_repeats_across_judge_objects_without_a_model_call(tmp_path):
    path = tmp_path / "sub" / "j.sqlite"
    model = StubChatModel(["Score: 3", "Score: 1"], name="m", capabilities=PLAIN)
    first = LLMMatchJudge(model, path).judge("What is on the desk?", "a lamp and a book", "a lamp.")
    # A new judge on the same file; the tail cut by trimming does not make a new response.
    again = LLMMatchJudge(model, path).judge("What is on the desk?", "a lamp and a book",
                                             "a lamp. And a")
    assert again == Judgement(3, 50.0, "m", "Score: 3", cached=True) and not first.cached
    assert len(model.requests) == 1
    changed = LLMMatchJudge(model, path).judge("What is on the desk?", "a lamp and a book", "a book")
    assert (changed.score, changed.cached, len(model.requests)) == (1, False, 2)


def test_the_cache_key_holds_the_judge_the_extras_and_the_prompt_version(tmp_path, monkeypatch):
    from efficienteqa.eval import judge as judge_module

    path = tmp_path / "j.sqlite"
    model = StubChatModel(lambda messages: "5", name="m", capabilities=PLAIN)
    LLMMatchJudge(model, path).judge("Q?", "red", "crimson")
    assert LLMMatchJudge(model, path).judge("Q?", "red", "crimson").cached
    assert not LLMMatchJudge(model, path).judge("Q?", "red", "crimson", ["scarlet"]).cached
    other = StubChatModel(lambda messages: "5", name="other", capabilities=PLAIN)
    assert not LLMMatchJudge(other, path).judge("Q?", "red", "crimson").cached
    monkeypatch.setattr(judge_module, "prompt_version", lambda mode="grade": "a-new-prompt")
    assert not LLMMatchJudge(model, path).judge("Q?", "red", "crimson").cached
    assert len(model.requests) == 3 and len(other.requests) == 1


def test_a_corrupt_cache_file_names_the_fix(tmp_path):
    from efficienteqa.errors import EfficientEQAError

    path = tmp_path / "j.sqlite"
    path.write_bytes(b"not a database" * 100)
    with pytest.raises(EfficientEQAError, match="delete"):
        LLMMatchJudge(StubChatModel(["5"]), path).judge("Q?", "red", "crimson")


@pytest.mark.slow
@needs_small_model
def test_smoke_judge_with_the_real_small_model(tmp_path, small_model_cache):
    """SmolLM2-135M through the local server: a 135M model's grade is not trustworthy, so only
    the contract is checked: a whole score 1-5, recorded problems when it defaulted, its name."""
    from efficienteqa.models import local
    from efficienteqa.models.backends import ChatBackend, build_chat_model

    try:
        model = build_chat_model(ChatBackend(kind="local", model="smollm2-135m", cache=False))
        judgement = LLMMatchJudge(model, tmp_path / "j.sqlite").judge(
            "What colour is the sofa?", "grey", "The sofa is grey.")
    finally:
        local.stop("smollm2-135m")
    assert judgement.judge == "smollm2-135m" and isinstance(judgement.raw, str)
    assert isinstance(judgement.score, int) and 1 <= judgement.score <= 5
    assert judgement.value == score_value(judgement.score)
    assert all(isinstance(p, str) for p in judgement.problems)


@pytest.mark.parametrize("question,reference,response,extra,expected", [
    ("Which lamp is on?", "a desk lamp", "Desk lamp.", (), 5),
    ("What colour is the rug?", "grey", "gray", ("gray",), 5),
    ("Is the lamp on?", "Yes, it is on", "yes", (), 5),
    ("Is the door open?", "No", "no, it is closed", (), 5),
    ("Is the door open?", "yes", "No.", (), 1),
    ("Is the lamp next to the bed on?", "Yes, it is on", "lamp", (), 1),  # only the question's words
    ("What is on the table?", "2", "two", (), None),  # not a count question: the model's call
    ("What is on the table?", "a rug", "", (), None),
])
def test_rules_grade_what_every_judge_must_agree_on(question, reference, response, extra, expected):
    ruled = rule_score(question, reference, response, extra)
    assert (ruled.score if ruled else None) == expected


def test_the_polarity_rule_decides_only_bare_yes_and_no(tmp_path):
    """"yes, in the bedroom" is not "yes, in the kitchen": the model decides, not the yes."""
    model = StubChatModel(["1"], capabilities=PLAIN)
    judgement = LLMMatchJudge(model, tmp_path / "j.sqlite").judge(
        "Is there a lamp?", "yes, in the kitchen", "yes, in the bedroom")
    assert judgement.score == 1 and len(model.requests) == 1
    assert rule_score("Is there a lamp?", "yes, in the kitchen", "yes, in the bedroom") is None
    assert rule_score("Is there a lamp?", "yes", "yes, in the bedroom") is None
    assert rule_score("Is there a lamp?", "yes, there is", "Yes, there is a lamp.").score == 5


def test_a_ruled_grade_makes_no_model_call(tmp_path):
    model = StubChatModel([])
    judgement = LLMMatchJudge(model, cache_path=tmp_path / "j.sqlite").judge(
        "Is the door open?", "No", "no")
    assert judgement.score == 5 and "by rule" in judgement.raw and not model.requests


def test_yes_prob_mode_grades_from_the_probability_of_yes(tmp_path):
    from efficienteqa.models.base import TokenLogprob

    def logprobs(text, top):  # P(yes) = 0.8 at the one token
        return [TokenLogprob("yes", math.log(0.8), (("yes", math.log(0.8)), ("no", math.log(0.2))))]

    model = StubChatModel(["yes", "yes"], logprob_fn=logprobs)
    judge = LLMMatchJudge(model, cache_path=tmp_path / "j.sqlite", mode="yes-prob")
    judgement = judge.judge("What is on the desk?", "a laptop", "a notebook computer")
    assert judgement.score == 4 and judgement.raw.startswith("P(yes)=0.800 ")
    assert judgement.judge == "stub (yes-prob)"
    same, correct = model.requests  # both questions, one token each
    assert all(r.max_tokens == 1 and r.logprobs for r in model.requests)
    assert "say the same thing" in same.messages[0].text
    assert correct.messages[0].text.endswith("Correct?\n")
    # no yes/no at all among the alternatives: the documented default, with the problem
    silent = StubChatModel(["maybe", "maybe"])
    low = LLMMatchJudge(silent, cache_path=tmp_path / "k.sqlite", mode="yes-prob").judge(
        "Q?", "a mug", "a cup")
    assert low.score == DEFAULT_SCORE and len(low.problems) == 3


def test_yes_prob_mode_needs_logprobs():
    from efficienteqa.errors import EfficientEQAError

    with pytest.raises(EfficientEQAError, match="grade"):
        LLMMatchJudge(StubChatModel([], capabilities=Capabilities(logprobs=False)), mode="yes-prob")


def test_an_explicit_score_wins_over_numbers_that_look_like_a_hedge():
    """B6: the judge's own score, not the "2 to 3" it quotes from the answers."""
    assert parse_score("Score 4 (both say 2 to 3 chairs)") == (4, [])
    assert parse_score("Score: 5. Both answers say 1 or 2 cups.") == (5, [])
    score, problems = parse_score("Score: 3 or 4")  # a hedge in the score itself stays one
    assert score is None and "conflicting" in problems[0]


@pytest.mark.parametrize("text", [
    "Dr. Smith's office", "A lamp, e.g. the desk lamp", "On the T.V. stand", "It is on the T.V.",
    "Near the U.S. map", "Mr. Bean's mug. It is",
])
def test_trim_keeps_abbreviations_and_initialisms(text):
    trimmed = trim_response(text)
    if text.endswith("It is"):
        assert trimmed == "Mr. Bean's mug."  # a real sentence end is still cut after
    else:
        assert trimmed == text


DIGITS = "9" * 100_000


@pytest.mark.trial("3.4")
@pytest.mark.parametrize("reply, expected", [
    ("A: " + DIGITS, "out of range"), ("Score: " + DIGITS, "out of range"),
    (DIGITS + "/5", "out of range"), ('{"score": ' + DIGITS + "}", "out of range"),
    ("4." + "0" * 100_000, 4), ("“" * 100_000, "no score"), ("“a " * 30_000 + "4", 4),
])
def test_an_absurdly_long_reply_parses_at_once(reply, expected):
    """Fault trial 3.4: patterns that backtracked into each digit run (or rescanned from each
    unclosed quote) made parsing quadratic: 30,000 digits took 45 s. Runs are cut to
    ``MAX_DIGITS``, still out of range; 100,000 characters take well under a second."""
    import time

    start = time.perf_counter()
    score, problems = parse_score(reply)
    assert time.perf_counter() - start < 0.5
    if isinstance(expected, int):
        assert (score, problems) == (expected, [])
    else:
        assert score is None and expected in problems[0]


@pytest.mark.trial("3.4")
def test_an_absurdly_long_number_is_trimmed_and_ruled_at_once():
    """Fault trial 3.4: ``trim_response`` backtracked into each word (12 s for 30,000 digits),
    and the rule judges converted every digit to an int (a ValueError past Python's 4,300)."""
    import time

    from efficienteqa.eval.synthetic_judge import rule_judgement

    start = time.perf_counter()
    assert trim_response("It is " + DIGITS + ". And") == "It is " + DIGITS + "."
    assert trim_response("a" * 100_000 + ", b") == "a" * 100_000 + ", b"
    ruled = rule_score("How many chairs are there?", "3", DIGITS)
    judged = rule_judgement("How many chairs are there?", "count", ["3"], DIGITS)
    assert time.perf_counter() - start < 1.0
    assert ruled is not None and ruled.score == 1 and judged.score == 1
    assert rule_judgement("How many chairs?", "count", ["3"], "0" * 5000 + "3").score == 5


@pytest.mark.parametrize("yes, no", [
    ("\u2581Yes", "\u2581No"), ("Yes.", "No."), ("\u0120yes", "\u0120no"), (" YES", " NO"),
    ('"Yes', '"No'), ("Yes!", "No!"),
])
def test_yes_prob_reads_yes_and_no_tokens_in_any_spelling(tmp_path, yes, no):
    """B7: SentencePiece/BPE space markers, punctuation and case do not hide the answer."""
    from efficienteqa.models.base import TokenLogprob

    def logprobs(text, top):  # P(yes) = 0.9 over yes and no; other tokens do not count
        return [TokenLogprob(yes, math.log(0.6), ((yes, math.log(0.6)), (yes.upper() + " ", math.log(0.3)),
                                                  (no, math.log(0.1)), ("The", math.log(0.2))))]

    model = StubChatModel(["Yes", "Yes"], logprob_fn=logprobs)
    judgement = LLMMatchJudge(model, cache_path=tmp_path / "j.sqlite", mode="yes-prob").judge(
        "What is on the desk?", "a laptop", "a notebook computer")
    assert judgement.problems == () and judgement.raw.startswith("P(yes)=0.900 ")
    assert judgement.score == 5


@pytest.mark.trial("3.2")
@pytest.mark.parametrize("yes, no, expected", [
    (-800.0, -801.0, 1 / (1 + math.exp(-1.0))),  # both underflow exp(): compared as logprobs
    (-1000.0, -1000.0, 0.5),
    (-900.0, -800.0, 1 / (1 + math.exp(100.0))),
    (-9999.0, -2.0, 0.0),  # vLLM's -9999 marks a masked token: it holds no mass
    (-0.1, -9999.0, 1.0),
])
def test_p_yes_survives_logprobs_that_underflow(yes, no, expected):
    """exp() of both logprobs is 0.0 below about -745; P(yes) must not divide by it."""
    from efficienteqa.eval.judge_parse import p_yes
    from efficienteqa.models.base import TokenLogprob

    token = TokenLogprob("Yes", yes, (("Yes", yes), ("No", no)))
    assert p_yes([token]) == pytest.approx(expected, abs=1e-12)


def test_p_yes_adds_spellings_in_log_space():
    """Two spellings of yes far below exp()'s range still add up: P(yes) = 2/3 here."""
    from efficienteqa.eval.judge_parse import p_yes
    from efficienteqa.models.base import TokenLogprob

    token = TokenLogprob("Yes", -900.0, (("Yes", -900.0), (" yes", -900.0), ("No", -900.0)))
    assert p_yes([token]) == pytest.approx(2 / 3)


def test_p_yes_is_none_when_yes_and_no_are_both_masked():
    """-9999 (vLLM's mask) on both words is no answer, not a 50:50 one."""
    from efficienteqa.eval.judge_parse import p_yes
    from efficienteqa.models.base import TokenLogprob

    token = TokenLogprob("The", -0.01, (("The", -0.01), ("Yes", -9999.0), ("No", -9999.0)))
    assert p_yes([token]) is None
    assert p_yes([token, TokenLogprob("no", -0.5, (("no", -0.5),))]) == 0.0


def test_rule_bounds_hold_the_model_grade_and_the_cache_keeps_the_models_own(tmp_path):
    """A right answer in the reference's words with more besides is at least 4 whatever P(yes)
    says; the cache stores the model's grade, the bound is applied on every read."""
    from efficienteqa.models.base import TokenLogprob

    def logprobs(text, top):  # P(yes) = 0.1: the model would say 1
        return [TokenLogprob("no", math.log(0.9), (("yes", math.log(0.1)), ("no", math.log(0.9))))]

    model = StubChatModel(["no"] * 4, logprob_fn=logprobs)
    judge = LLMMatchJudge(model, cache_path=tmp_path / "j.sqlite", mode="yes-prob")
    first = judge.judge("Where is the radio?", "on the shelf", "On the shelf above the sink")
    assert first.score == 4 and "P(yes)=0.100" in first.raw and "held to 4-5" in first.raw
    again = judge.judge("Where is the radio?", "on the shelf", "On the shelf above the sink")
    assert again.cached and again.score == 4 and len(model.requests) == 2
    # no bound: the model's grade stands
    other = judge.judge("Where is the radio?", "on the shelf", "In the garage")
    assert other.score == 1 and "held" not in other.raw


def test_an_opposite_yes_no_with_more_words_is_wrong_without_a_model_call(tmp_path):
    model = StubChatModel([])
    judgement = LLMMatchJudge(model, cache_path=tmp_path / "j.sqlite", mode="yes-prob").judge(
        "Is there a box in the hall?", "No", "Yes, a cardboard box by the door")
    assert judgement.score == 1 and "by rule" in judgement.raw and not model.requests


def test_yes_prob_grades_the_geometric_mean_of_both_questions(tmp_path):
    """The strict question says 0.25, the lenient one 0.81: P = sqrt(0.25 * 0.81) = 0.45, grade
    1 + round(4 * 0.45) = 3 (either alone would give 2 or 4); one unreadable reply leaves the
    other's P(yes), and says so."""
    from efficienteqa.models.base import TokenLogprob

    def script(messages):  # the reply text tells logprobs which question was asked
        return "yes" if messages[0].text.endswith("Correct?\n") else "Yes"

    def logprobs(text, top):
        p = 0.81 if text == "yes" else 0.25
        return [TokenLogprob(text, math.log(p), ((text, math.log(p)), ("no", math.log(1 - p))))]

    model = StubChatModel(script, logprob_fn=logprobs)
    judgement = LLMMatchJudge(model, cache_path=tmp_path / "j.sqlite", mode="yes-prob").judge(
        "What is on the desk?", "a laptop", "a notebook computer")
    assert judgement.score == 3 and judgement.raw == (
        "P(yes)=0.450 (judge_same 0.250; judge_correct 0.810)")

    def half_silent(messages):
        return "yes" if messages[0].text.endswith("Correct?\n") else "Hmm"

    def some_logprobs(text, top):
        return logprobs(text, top) if text == "yes" else [TokenLogprob(text, -0.1, ((text, -0.1),))]

    model = StubChatModel(half_silent, logprob_fn=some_logprobs)
    judgement = LLMMatchJudge(model, cache_path=tmp_path / "k.sqlite", mode="yes-prob").judge(
        "What is on the desk?", "a laptop", "a notebook computer")
    assert judgement.score == 4 and judgement.raw.startswith("P(yes)=0.810 ")
    assert judgement.problems == ("no yes/no among the judge_same reply's tokens",)


def test_the_yes_prob_version_holds_both_prompts_and_the_mapping(monkeypatch):
    """A changed prompt or mapping must not reuse grades cached under the old one."""
    from efficienteqa.eval import judge_prompts

    before = judge_prompts.prompt_version("yes-prob")
    monkeypatch.setattr(judge_prompts, "YES_COMBINE", "arithmetic mean")
    assert judge_prompts.prompt_version("yes-prob") != before
    monkeypatch.undo()
    real = judge_prompts.load_prompt
    monkeypatch.setattr(judge_prompts, "load_prompt", lambda name, package: real(name, package) + (
        " " if name == "judge_correct" else ""))
    assert judge_prompts.prompt_version("yes-prob") != before


# ------------------------------------------------------------------ OpenEQA's protocol

def test_the_openeqa_mode_runs_the_protocol_as_openeqa_does(tmp_path):
    """No rule grading first (the same answer still goes to the model), the response cut after
    its last ".", temperature 0.2, seed 1234, 32 tokens, the mark after "Your mark:"."""
    from efficienteqa.eval.judge_parse import openeqa_cut, openeqa_mark

    model = StubChatModel(["Your mark: 4", "5", "I think it is a good answer."])
    judge = LLMMatchJudge(model, cache_path=tmp_path / "j.sqlite", mode="openeqa")
    first = judge.judge("What is on the desk?", "a lamp", "A lamp. It is on the desk, I")
    assert (first.score, first.judge) == (4, "stub (openeqa)")
    request = model.requests[0]
    assert (request.temperature, request.seed, request.max_tokens) == (0.2, 1234, 32)
    sent = request.messages[-1].text
    assert sent.rstrip().endswith("Response: A lamp.") and "Your mark: 5" in sent
    assert judge.judge("Is the door open?", "yes", "yes").score == 5  # asked, not ruled
    broken = judge.judge("What colour is the sofa?", "red", "blue")
    assert broken.score == 1 and broken.problems and "no mark" in broken.problems[0]
    assert len(model.requests) == 3
    assert openeqa_cut("yes") == "yes" and openeqa_cut("It is red.") == "It is red."
    assert [openeqa_mark(r) for r in ("3", "Your mark: **2**", "Your mark: 9", "mark 3")] == \
        [3, 2, None, None]
