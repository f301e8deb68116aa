"""The rule judge on real generated questions: right answers in several surface forms pass,
wrong ones (another value, a right one beside a wrong one, a negation, a hedge) fail; synthetic
runs are graded by it by default."""

from __future__ import annotations

import numpy as np
import pytest

from efficienteqa.datasets.synthetic import load_split
from efficienteqa.envs.synthetic.answers import NUMBER_WORDS, lexicon
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.envs.synthetic.primitives import builtin_catalog
from efficienteqa.envs.synthetic.questions import generate_questions
from efficienteqa.eval.synthetic_judge import RULE_JUDGE, rule_judgement

SEEDS = (0, 1, 2, 5, 8, 13)


def _live(seed: int) -> list[tuple[str, str, str, tuple[str, ...]]]:
    house = generate_house(seed, builtin_catalog(), "builtin")
    return [(q.question, q.category, q.answer, tuple(q.accepted))
            for q in generate_questions(house, np.random.default_rng([seed, 7]))]


@pytest.fixture(scope="module")
def questions() -> list[tuple[str, str, str, tuple[str, ...]]]:
    """Generated questions of several houses (built-in boxes) and the committed split (real
    furniture): (question, category, answer, accepted)."""
    live = [q for seed in SEEDS for q in _live(seed)]
    split = [(q.question, q.category, q.answer, q.accepted) for q in load_split()]
    assert all(q[3] for q in split), "the split's rows carry their accepted answers"
    return live + split


def _other(kind: str, accepted: tuple[str, ...], question: str) -> str:
    """A value of the same kind that is not accepted and not named by the question."""
    taken = {a.lower() for a in accepted}
    asked = question.lower()
    return next(v for v in lexicon(kind) if v not in taken and v not in asked and " " not in v)


def right_and_wrong(question: str, category: str, answer: str, accepted: tuple[str, ...]
                    ) -> tuple[list[str], list[str]]:
    """Answers a strict grader accepts, and answers it rejects, in several surface forms."""
    if category == "count":
        n = int(answer)
        word, other = NUMBER_WORDS[n], n + 2
        return ([answer, f"{word} chairs", f"There are {word.capitalize()} chairs around it.", f"{n}."],
                [str(other), NUMBER_WORDS[other], f"{word} or {NUMBER_WORDS[n + 1]}", f"{n}-{n + 1}",
                 "none", "I can't tell how many"])
    if category in ("existence", "state"):
        yes = answer == "yes"
        if "open?" in question:
            says, denies = ("The door is open.", "It's closed") if yes else ("It is closed.", "it's open")
        elif category == "state":
            says, denies = ("It's on.", "It is switched off.") if yes else ("It is off", "it is on")
        else:
            says, denies = ("Yes, there is one.", "There isn't one.") if yes else \
                ("No, there isn't one.", "Yes, there is one.")
        plain, opposite = ("yes", "no") if yes else ("no", "yes")
        return ([plain, plain.capitalize() + ".", says],
                [opposite, opposite.capitalize() + ".", denies, "yes and no", "Maybe."])
    if category == "colour":
        other = _other("colour", accepted, question)
        return ([answer, f"It is {answer}.", f"The colour is {accepted[-1]}", f"dark {answer}"],
                [other, f"{answer} and {other}", f"not {answer}", f"It is {other}, not {answer}.",
                 "I am not sure"])
    if category == "identification":
        name = answer.removeprefix("a ")
        other = _other("object", accepted, question)
        return ([answer, f"It's a {accepted[-1]}.", f"A {name} is on it", name.upper()],
                [f"a {other}", f"a {name} or a {other}", f"not a {name}", "nothing"])
    if category == "location":
        room = accepted[0]
        other = _other("room", accepted, question)
        right = [answer, f"It is in the {room}.", f"in the {room.upper()}", accepted[1]
                 if len(accepted) > 1 else f"the {room}"]
        wrong = [f"in the {other}", f"in the {room} or the {other}", "I cannot see it"]
        if " on the " in answer:
            surface = answer.split(" on the ")[-1].split(" in the ")[0]
            right.append(f"on the {surface}")
        return right, wrong
    raise AssertionError(category)


def test_right_answers_pass_and_wrong_ones_fail_on_generated_questions(questions):
    categories = set()
    for question, category, answer, accepted in questions:
        right, wrong = right_and_wrong(question, category, answer, accepted)
        for response in right:
            verdict = rule_judgement(question, category, accepted, response)
            assert verdict.score == 5, (question, answer, response, verdict.raw)
        for response in wrong:
            verdict = rule_judgement(question, category, accepted, response)
            assert verdict.score == 1, (question, answer, response, verdict.raw)
        categories.add(category)
    assert categories == {"identification", "count", "existence", "state", "location", "colour"}


@pytest.mark.parametrize("category, accepted, response, score", [
    ("colour", ("grey", "gray"), "gray", 5),
    ("colour", ("grey", "gray"), "navy blue", 1),  # "navy" modifies blue: it says blue
    ("colour", ("blue",), "navy blue", 5),
    ("identification", ("tv", "television"), "a flat-screen television", 5),
    ("identification", ("vase",), "a glass vase", 5),  # "glass" modifies vase
    ("identification", ("vase",), "a vase and a glass", 1),
    ("location", ("kitchen", "table"), "on the table", 5),
    ("location", ("kitchen", "table"), "on the desk in the kitchen", 1),
    ("location", ("kitchen", "table"), "in the kitchen, next to the sofa", 5),  # a landmark
    ("location", ("kitchen",), "in the bedroom", 1),
])
def test_mentions_modifiers_and_landmarks(category, accepted, response, score):
    assert rule_judgement("Where is the mug?" if category == "location" else "What is it?",
                          category, accepted, response).score == score


def test_a_missing_answer_scores_zero_and_a_grade_names_the_rule_judge():
    missing = rule_judgement("Is the lamp on?", "state", ("yes", "on"), "  ")
    assert (missing.score, missing.value, missing.judge) == (None, 0.0, RULE_JUDGE)
    right = rule_judgement("Is the lamp on?", "state", ("yes", "on"), "It is not off.")
    assert (right.score, right.value, right.judge) == (5, 100.0, RULE_JUDGE) and "yes" in right.raw


def test_synthetic_datasets_default_to_the_rule_judge_and_hm_eqa_to_llm_match(tmp_path, monkeypatch,
                                                                              hm_eqa_dir):
    """``efficienteqa eval`` without --judge: a synthetic run calls no judge model (the rule
    judge grades it), an HM-EQA run keeps the local LLM-Match judge; --judge adds LLM-Match
    beside the rule."""
    from typer.testing import CliRunner

    from efficienteqa import cli
    from efficienteqa.eval import runner
    from efficienteqa.eval.methods import default_judge

    specs = []

    def fake_run_eval(spec, questions, out, **kwargs):
        specs.append((spec, questions))
        return runner.RunResult(out, 0, 0, 0, 1.0)

    monkeypatch.setattr(runner, "run_eval", fake_run_eval)
    for args in (["--dataset", "synthetic"], ["--dataset", "synthetic", "--judge", "rule"],
                 ["--dataset", "hm-eqa", "--hm-eqa-path", str(hm_eqa_dir)],
                 ["--dataset", "synthetic", "--judge", "local:qwen2.5-coder-1.5b"]):
        result = CliRunner().invoke(cli.app, ["eval", "--method", "blind", "--limit", "2",
                                              "--out", str(tmp_path / "run"), *args])
        assert result.exit_code == 0, result.output
    judges = [spec.judge for spec, _ in specs]
    assert judges == [None, None, "local:qwen2.5-coder-1.5b", "local:qwen2.5-coder-1.5b"]
    assert all(q.accepted for q in specs[0][1])  # the rule judge's key travels with the questions
    assert default_judge("synthetic:0-3") is None and default_judge("hm-eqa") is not None
    refused = CliRunner().invoke(cli.app, ["eval", "--method", "blind", "--dataset", "hm-eqa",
                                           "--hm-eqa-path", str(hm_eqa_dir), "--judge", "rule",
                                           "--out", str(tmp_path / "x")])
    assert refused.exit_code == 1 and "synthetic questions only" in str(refused.exception)


def test_an_episode_line_carries_the_rule_grade_beside_llm_match(tmp_path, monkeypatch):
    from efficienteqa.datasets.base import EvalQuestion
    from efficienteqa.eval.methods import RunSpec
    from efficienteqa.eval.runner import run_episode

    q = EvalQuestion(id="toy/0", dataset="synthetic-v1", scene="synthetic:0",
                     question="Is the lamp on?", answer="yes", category="state", accepted=("yes", "on"))
    spec = RunSpec.of(method="eval_stubs:echo", dataset="synthetic-v1", judge=None)
    monkeypatch.setenv("EQA_STUB_ANSWER", "It is switched off.")
    row = run_episode(spec, q, tmp_path)
    assert row["status"] == "done" and row["rule"]["score"] == 1 and row["judge"] is None
    assert row["accepted"] == ["yes", "on"]
    monkeypatch.setenv("EQA_STUB_ANSWER", "Yes, the lamp is on.")
    assert run_episode(spec, q, tmp_path)["rule"]["value"] == 100.0
