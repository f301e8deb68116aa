"""The model-as-matcher relevancy: P(yes) from a verbalized yes/no confidence."""

import math

import numpy as np
import pytest

from efficienteqa.models.stub import StubChatModel
from efficienteqa.relevancy.vlm_match import VLMMatchScorer


@pytest.mark.parametrize("reply, p_yes", [("yes 80", 0.8), ("no 90", pytest.approx(0.1)),
                                          ("Yes, 100%", 1.0)])
def test_yes_no_confidence_is_the_match_probability(reply, p_yes):
    model = StubChatModel([reply])
    sim = VLMMatchScorer(model).score("Where is the sofa?", text="You are in the hallway.")
    assert sim == p_yes
    prompt = model.requests[0].messages[0].text
    assert prompt.index("Question: Where is the sofa?") < prompt.index("View: You are in the hallway.")


@pytest.mark.parametrize("reply", ["maybe", "N/A", "I'm sorry, I can't help with that.",
                                   "The image shows a living room with a grey",  # cut prose
                                   ""])
def test_an_unreadable_reply_is_missing_and_recorded(reply):
    """Not 0.5 (``DEFAULT_P_YES``), which stands far above a confident "no" (0.1) and became the
    outlier that stopped the robot."""
    scorer = VLMMatchScorer(StubChatModel([reply]))
    assert math.isnan(scorer.score("Where is the sofa?", text="x"))
    assert scorer.problems and "relevancy missing" in scorer.problems[0]


def test_a_reply_cut_at_max_tokens_is_read_as_far_as_it_goes_and_noted():
    model = StubChatModel(["Sure! My answer: yes 80"], finish_reason="length")
    scorer = VLMMatchScorer(model)
    assert scorer.score("Where is the sofa?", text="x") == pytest.approx(0.8)
    assert any("cut at" in p for p in scorer.problems)
    assert model.requests[0].max_tokens >= 16  # room for a short preamble


def test_image_modality_sends_the_frame():
    model = StubChatModel(["yes 60", "no 60"])
    scorer = VLMMatchScorer(model, "image")
    frames = [np.zeros((4, 4, 3), np.uint8), np.ones((4, 4, 3), np.uint8)]
    assert scorer.score_many("Is the TV on?", frames).tolist() == pytest.approx([0.6, 0.4])
    assert all(len(r.messages[0].images) == 1 for r in model.requests)
    with pytest.raises(ValueError, match="pass image"):
        scorer.score("Is the TV on?", text="a TV")
