"""The exploration call of verbalized confidence (SPEC 3.3) and its white-box reading."""

from __future__ import annotations

import numpy as np
import pytest

from efficienteqa.explore.vlm_scorer import explore_scores
from efficienteqa.models.base import Message
from efficienteqa.models.stub import StubChatModel
from efficienteqa.vc.parse import DEFAULT_P_YES

VIEW = "a grey sofa ahead, 2.1 m; a wooden coffee table at 1.5 m; an open door on the right"
DIRECTIONS = {"A": "through the open door, 4 m", "B": "past the sofa, 3 m", "C": "back left, 5 m"}


def test_explore_scores_prompt_and_normalisation():
    stub = StubChatModel(["B: 60\nA: 30\nC: 30\nworth exploring: yes 80"])
    score = explore_scores(stub, "Is the oven on?", VIEW, DIRECTIONS)
    prompt = stub.requests[0].messages[0].text
    assert "Is the oven on?" in prompt and VIEW in prompt and DIRECTIONS["A"] in prompt
    assert score.letters == pytest.approx({"A": 0.25, "B": 0.5, "C": 0.25})
    assert score.p_yes == pytest.approx(0.8)
    assert score.info["problems"] == [] and score.info["raw"].startswith("B: 60")
    assert score.info["usage"]["prompt_tokens"] > 0


def test_explore_scores_two_letters_and_images():
    stub = StubChatModel(["A: 90\nB: 10\nworth exploring: no 70"])
    frame = np.zeros((4, 4, 3), np.uint8)
    score = explore_scores(stub, "Where is the cat?", "", ["A", "B"], images=[frame])
    msg: Message = stub.requests[0].messages[0]
    assert len(msg.images) == 1 and "View: the image" in msg.text
    assert msg.text.split("Directions:")[1].strip() == "A, B (the lettered circles in the image)"
    assert score.letters == pytest.approx({"A": 0.9, "B": 0.1})
    assert score.p_yes == pytest.approx(0.3)


@pytest.mark.parametrize("reply, letters", [
    ("", (1 / 3, 1 / 3, 1 / 3)), ("I cannot tell.", (1 / 3, 1 / 3, 1 / 3)),
    ("D: 100", (1 / 3, 1 / 3, 1 / 3)), ("{{{", (1 / 3, 1 / 3, 1 / 3)), ("nan nan", (1 / 3, 1 / 3, 1 / 3)),
    ("A: -3\nB: 0", (0.5, 0.5, 0.0)),  # all-zero confidences: uniform over the listed answers
])
def test_explore_scores_malformed_replies_give_defaults(reply, letters):
    score = explore_scores(StubChatModel([reply]), "Where is the cat?", VIEW, DIRECTIONS)
    assert score.letters == pytest.approx(dict(zip("ABC", letters)))
    assert score.p_yes == DEFAULT_P_YES and score.info["problems"]
