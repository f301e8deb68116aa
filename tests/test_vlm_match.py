"""The model-as-matcher relevancy: P(yes) from a verbalized yes/no confidence."""

import numpy as np
import pytest

from efficienteqa.models.stub import StubChatModel
from efficienteqa.relevancy.vlm_match import VLMMatchScorer
from efficienteqa.vc.parse import DEFAULT_P_YES


@pytest.mark.parametrize("reply, p_yes", [("yes 80", 0.8), ("no 90", pytest.approx(0.1)),
                                          ("Yes, 100%", 1.0)])
def test_yes_no_confidence_is_the_match_probability(reply, p_yes):
    model = StubChatModel([reply])
    sim = VLMMatchScorer(model).score("Where is the sofa?", text="You are in the hallway.")
    assert sim == p_yes
    prompt = model.requests[0].messages[0].text
    assert prompt.index("Question: Where is the sofa?") < prompt.index("View: You are in the hallway.")


def test_unreadable_reply_is_neutral_and_recorded():
    scorer = VLMMatchScorer(StubChatModel(["maybe"]))
    assert scorer.score("Where is the sofa?", text="x") == DEFAULT_P_YES and scorer.problems


def test_image_modality_sends_the_frame():
    model = StubChatModel(["yes 60", "no 60"])
    scorer = VLMMatchScorer(model, "image")
    frames = [np.zeros((4, 4, 3), np.uint8), np.ones((4, 4, 3), np.uint8)]
    assert scorer.score_many("Is the TV on?", frames).tolist() == pytest.approx([0.6, 0.4])
    assert all(len(r.messages[0].images) == 1 for r in model.requests)
    with pytest.raises(ValueError, match="pass image"):
        scorer.score("Is the TV on?", text="a TV")
