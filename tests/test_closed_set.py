"""HM-EQA closed-set for the Blind LLM: the letter of highest log-probability, graded by letter."""

from __future__ import annotations

import math

import pytest

from conftest import HM_EQA, needs_hm_eqa
from efficienteqa.answer.blind import blind_choice
from efficienteqa.datasets import load_dataset
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.methods import RunSpec
from efficienteqa.eval.runner import run_episode
from efficienteqa.eval.summary import summarise
from efficienteqa.models.base import Capabilities, TokenLogprob
from efficienteqa.models.stub import StubChatModel
from efficienteqa.vc.logprobs import TOP_LOGPROBS

CHOICES = ("Red", "Blue", "Green", "White")


def letter_model(logprobs: dict[str, float], reply: str = "B") -> StubChatModel:
    """A model that writes ``reply`` with ``logprobs`` (token -> logprob) as the top alternatives
    of its first token."""
    def make(text: str, top: int) -> list[TokenLogprob]:
        return [TokenLogprob(text, logprobs.get(text, -5.0), tuple(logprobs.items())[:top])]
    return StubChatModel([reply] * 4, logprob_fn=make)


def test_the_letter_of_highest_logprob_is_the_answer_whatever_the_text():
    model = letter_model({"B": -1.2, " C": -0.4, "(A": -2.0, "D.": -3.0, "Yes": -0.1})
    result = blind_choice(model, "What colour is the sofa?", CHOICES)
    assert result.letter == "C" and result.answer == "Green" and not result.problems
    total = sum(math.exp(v) for v in (-1.2, -0.4, -2.0, -3.0))  # "Yes" is no letter
    assert result.confidence == pytest.approx(math.exp(-0.4) / total)
    assert sum(result.letter_probs.values()) == pytest.approx(1.0)
    request = model.requests[0]
    assert request.logprobs == TOP_LOGPROBS and request.temperature == 0.0
    prompt = request.messages[0].text
    assert "What colour is the sofa?" in prompt and "A) Red\nB) Blue\nC) Green\nD) White" in prompt


def test_no_letter_among_the_alternatives_is_a_problem_not_a_guess_in_silence():
    result = blind_choice(letter_model({"The": -0.1, "It": -0.5}, reply="The"), "Is it on?",
                          ("Yes", "No"))
    assert result.letter_probs == {"A": 0.5, "B": 0.5} and result.letter == "A"
    assert result.problems and "no letter" in result.problems[0]


def test_a_model_without_logprobs_is_refused_before_any_call():
    model = StubChatModel(["B"], capabilities=Capabilities(logprobs=False))
    with pytest.raises(EfficientEQAError, match="log-probabilities"):
        blind_choice(model, "Is it on?", ("Yes", "No"))
    assert not model.requests
    with pytest.raises(EfficientEQAError, match="choices"):
        blind_choice(letter_model({"A": -0.1}), "Is it on?", ())


@needs_hm_eqa
def test_a_closed_set_episode_is_graded_by_its_letter(tmp_path, monkeypatch):
    questions = load_dataset("hm-eqa", path=HM_EQA, closed_set=True)[:2]
    assert all(q.choices and q.source["letter"] for q in questions)
    right, wrong = (q.source["letter"] for q in questions)
    # Every call prefers the first question's letter: right there, and wrong on the second
    # unless both letters are the same (then the first other letter is preferred).
    pick = right if right != wrong else next(x for x in "ABCD" if x != right)
    model = letter_model({pick: -0.2, **{x: -2.0 for x in "ABCD" if x != pick}}, reply=pick)
    monkeypatch.setattr("efficienteqa.models.backends.build_chat_model", lambda backend: model)
    spec = RunSpec.of(method="blind", dataset="hm-eqa", judge=None, closed_set=True)
    rows = [run_episode(spec, q, tmp_path) for q in questions]
    assert [r["status"] for r in rows] == ["done", "done"], rows
    for q, row in zip(questions, rows):
        assert row["extra"]["letter"] == pick and row["answer"] == q.choices["ABCD".index(pick)]
        assert row["choice"] == {"correct": pick == q.source["letter"],
                                 "value": 100.0 * (pick == q.source["letter"]), "letter": pick,
                                 "reference_letter": q.source["letter"]}
        assert row["judge"] is None and row["rule"] is None
    s = summarise({"method": "blind", "dataset": "hm-eqa", "closed_set": True}, rows)
    expected = 50.0 if right != wrong else 0.0
    assert s.accuracy_judge == "choice" and s.n_choice == 2
    assert s.accuracy == s.choice_accuracy == expected and math.isnan(s.llm_match)
    assert s.label == "blind closed-set"


def test_open_ended_rows_have_no_letter_grade(tmp_path):
    from efficienteqa.datasets.base import EvalQuestion

    q = EvalQuestion(id="x/0", dataset="x", scene="synthetic:0", question="Is it on?", answer="yes",
                     category="state")
    row = run_episode(RunSpec.of(method="eval_stubs:echo", dataset="x", judge=None), q, tmp_path)
    assert row["status"] == "done" and row["choice"] is None


@pytest.mark.parametrize("args, message", [
    (["--dataset", "synthetic"], "--eval.closed-set is HM-EQA's multiple-choice mode"),
    (["--dataset", "hm-eqa", "--method", "efficienteqa"], "answers open-ended only"),
])
def test_closed_set_outside_blind_on_hm_eqa_is_one_line(cli, tmp_path, args, message):
    result = cli("eval", "--closed-set", "--out", str(tmp_path / "run"), *args)
    assert result.returncode == 1 and message in result.stdout
    assert "Traceback" not in result.stdout + result.stderr
    assert not (tmp_path / "run").exists()


def test_the_benchmark_reports_accuracy_against_the_majority_letter():
    from experiments import hm_eqa_closed as bench

    assert bench.majority(["C", "B", "C", "B", "A"]) == ("B", 40.0)  # a tie goes to the earlier
    rows = [{"id": f"q/{i}", "status": "done", "category": cat, "answer": "x", "reference": "x",
             "extra": {"letter": chose}, "choice": {"value": 100.0 * (chose == ref),
                                                    "reference_letter": ref}}
            for i, (cat, ref, chose) in enumerate([("count", "B", "B"), ("count", "B", "A"),
                                                   ("state", "C", "C"), ("state", "B", "B")])]
    f = bench.figures(rows)
    assert f["n"] == 4 and f["accuracy"] == 75.0 and f["majority_letter"] == "B"
    assert f["majority_prior"] == 75.0 and f["chosen_letters"] == {"A": 1, "B": 2, "C": 1}
    assert f["by_category"]["count"] == {"n": 2, "accuracy": 50.0, "majority_letter": "B",
                                         "majority_prior": 100.0, "overall_majority_prior": 100.0}
    assert f["by_category"]["state"]["majority_prior"] == 50.0


def test_a_library_caller_gets_the_evals_refusals_and_judge_from_plan_run():
    """The evaluation's policy is the library's (``eval.plan``), not the command line's: the
    same refusals, the same judge chosen."""
    from efficienteqa.config.presets import run_config
    from efficienteqa.errors import EfficientEQAError
    from efficienteqa.eval.judge_prompts import DEFAULT_JUDGE
    from efficienteqa.eval.plan import plan_run

    with pytest.raises(EfficientEQAError, match="HM-EQA's multiple-choice mode"):
        plan_run(run_config(None, {"eval.closed_set": True, "eval.dataset": "synthetic"}))
    with pytest.raises(EfficientEQAError, match="rule judge grades synthetic questions only"):
        plan_run(run_config(None, {"eval.dataset": "hm-eqa", "eval.judge": "rule"}))
    assert plan_run(run_config("default")).judge is None  # the rule judge grades it, for free
    spec = plan_run(run_config(None, {"eval.dataset": "hm-eqa", "eval.method": "blind"}))
    assert spec.judge == DEFAULT_JUDGE and spec.method == "blind"
