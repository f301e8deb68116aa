"""Retrieval of the top-K frames and the RAG answer (DESIGN 3.5)."""

import math

import pytest

from efficienteqa.answer import RagAnswerer, TopK
from efficienteqa.answer.rag import View, same_view
from efficienteqa.models.base import TokenLogprob
from efficienteqa.models.stub import StubChatModel
from efficienteqa.vc.grouping import RuleGrouper


def test_top_k_keeps_the_most_relevant_best_first():
    top = TopK(3)
    for step, sim in enumerate([0.2, 0.9, 0.1, 0.5, 0.7, 0.3], start=1):
        top.push(sim, step, f"frame {step}")
    assert [(r.step, r.sim) for r in top.best()] == [(2, 0.9), (5, 0.7), (4, 0.5)]
    assert len(top) == 3


def test_ties_keep_the_earlier_frame():
    top = TopK(2)
    for step in range(1, 6):
        top.push(0.5, step, step)
    assert [r.step for r in top.best()] == [1, 2]


def test_top_k_holds_distinct_views():
    """Three frames from one spot (the robot did not move) and one elsewhere: K = 3 retrieves
    the best of the three copies and the other view, not the copies."""
    top = TopK(3)
    here = View(1.0, 2.0, 0.0, "You are in the kitchen. Visible: a red chair ahead, 0.9 m.")
    top.push(0.5, 1, "copy 1", here)
    top.push(0.8, 2, "copy 2", View(1.1, 2.05, math.radians(10), "a slightly different text"))
    top.push(0.8, 3, "copy 3", View(1.0, 2.0, 0.0, here.text))  # a tie: the earlier stays
    top.push(0.3, 4, "elsewhere", View(5.0, 2.0, 0.0, "You are in the hallway."))
    assert [(r.step, r.item) for r in top.best()] == [(2, "copy 2"), (4, "elsewhere")]


def test_same_description_is_the_same_view_wherever_it_was_taken():
    text = "You are in the hallway. Visible: a brown door (open), 2.0 m."
    assert same_view(View(0.0, 0.0, 0.0, text), View(3.0, 0.0, math.pi, text))
    assert not same_view(View(0.0, 0.0, 0.0, "a"), View(0.0, 0.0, math.radians(20), "b"))
    assert same_view(View(0.0, 0.0, math.radians(179), None), View(0.2, 0.0, math.radians(-179)))
    assert not same_view(View(0.0, 0.0, 0.0), View(0.3, 0.0, 0.0))


def test_a_duplicate_view_evicted_and_seen_again_competes_afresh():
    top = TopK(1)
    top.push(0.4, 1, "a", View(0.0, 0.0, 0.0))
    top.push(0.6, 2, "b", View(4.0, 0.0, 0.0))
    top.push(0.9, 3, "a again", View(0.0, 0.0, 0.0))
    assert [r.item for r in top.best()] == ["a again"]
    top.push(0.95, 4, "a once more", View(0.0, 0.0, 0.0))
    assert [r.item for r in top.best()] == ["a once more"]


def test_fewer_frames_than_k():
    top = TopK(5)
    top.push(0.1, 1, "a")
    assert [r.item for r in top.best()] == ["a"]
    with pytest.raises(ValueError):
        TopK(0)


def test_answer_from_retrieved_descriptions():
    model = StubChatModel(["blue; 60\nnavy; 30\nred; 10"])
    result = RagAnswerer(model, RuleGrouper()).answer(
        "What colour is the sofa?", ["You are in the living room. Visible: a blue sofa ahead."])
    assert result.answer == "blue" and result.confidence == pytest.approx(0.6)
    prompt = model.requests[0].messages[0].text
    assert "view 1: You are in the living room" in prompt and "What colour is the sofa?" in prompt


def test_an_empty_reply_gives_no_answer_not_a_crash():
    result = RagAnswerer(StubChatModel([""]), RuleGrouper()).answer("Q?", ["x"])
    assert (result.answer, result.confidence, result.classes) == ("", 0.0, [])
    assert "no answers found" in result.problems


def test_a_reply_without_confidences_is_the_answer_with_the_repair_recorded():
    """No number at all: each line is a guess with the default share; alone, it is C* = 1."""
    result = RagAnswerer(StubChatModel(["I cannot tell."]), RuleGrouper()).answer("Q?", ["x"])
    assert (result.answer, result.confidence) == ("I cannot tell", 1.0)
    assert any(p.startswith("missing confidence for 'I cannot tell'") for p in result.problems)


def test_m_guesses_are_asked_for_and_kept():
    model = StubChatModel(["red; 50\nblue; 30\ngreen; 20"])
    result = RagAnswerer(model, RuleGrouper(), m=2).answer("What colour is the sofa?", ["x"])
    assert "Give your 2 best guesses" in model.requests[0].messages[0].text
    assert [c.text for c in result.candidates] == ["red", "blue"]  # at most m
    assert result.confidence == pytest.approx(50 / 80)


def test_the_white_box_answer_reads_token_probabilities():
    tokens = [TokenLogprob("blue", math.log(0.8)), TokenLogprob(" sofa", math.log(0.5))]
    model = StubChatModel(["blue sofa"], logprob_fn=lambda text, top: tokens)
    result = RagAnswerer(model, RuleGrouper(), confidence="token").answer("What is blue?", ["x"])
    assert (result.answer, result.confidence) == ("blue sofa", pytest.approx(0.4))
    assert model.requests[0].logprobs == 1 and "one line" in model.requests[0].messages[0].text
