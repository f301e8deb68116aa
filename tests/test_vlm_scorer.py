"""The exploration call of verbalized confidence (DESIGN 3.3) and its white-box reading."""

from __future__ import annotations

import math

import numpy as np
import pytest

from efficienteqa.explore.vlm_scorer import explore_scores, explore_token_scores
from efficienteqa.models.base import Message, TokenLogprob
from efficienteqa.models.stub import StubChatModel
from efficienteqa.vc.yes_no import DEFAULT_P_YES

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


def _tok(token, **probs):
    """A generated token with its alternatives given as probabilities."""
    top = tuple((t, math.log(p)) for t, p in probs.items())
    return TokenLogprob(token, dict(top).get(token, math.log(0.5)), top)


# The letter's alternatives hold "Yes"/"No" too (a model may start its reply with them): P(yes)
# must come from the yes/no answer, 0.9, not from those alternatives (0.5).
LETTER = _tok("B", B=0.8, A=0.1, Yes=0.05, No=0.05)


@pytest.mark.parametrize("tokens", [
    [LETTER, _tok("\n"), _tok("yes", yes=0.9, no=0.1)],
    [LETTER, _tok("\n"), _tok("\n"), _tok("Yes", Yes=0.9, No=0.1)],  # a blank line between
    [LETTER, _tok(" yes", **{" yes": 0.9, " no": 0.1})],  # both on one line
])
def test_token_p_yes_is_read_on_the_yes_no_line(tokens):
    """B1: white-box P(yes) comes from the yes/no line, never from the letter token."""
    stub = StubChatModel(["B\nyes"], logprob_fn=lambda text, top: tokens)
    score = explore_token_scores(stub, "Where is the cat?", VIEW, DIRECTIONS)
    assert score.letters == pytest.approx({"A": 1 / 9, "B": 8 / 9, "C": 0.0})
    assert score.p_yes == pytest.approx(0.9)


def test_token_letters_are_read_on_the_first_line_only():
    """A reply with no letter on line 1 is uniform: a letter among line 2's alternatives is not
    the model's choice of direction."""
    tokens = [_tok("none", none=0.9), _tok("\n"), _tok("no", no=0.7, A=0.2, yes=0.1)]
    stub = StubChatModel(["none\nno"], logprob_fn=lambda text, top: tokens)
    score = explore_token_scores(stub, "Where is the cat?", VIEW, DIRECTIONS)
    assert score.letters == pytest.approx({"A": 1 / 3, "B": 1 / 3, "C": 1 / 3})
    assert score.p_yes == pytest.approx(0.1 / 0.8)
    # the uniform scores are a problem the episode counts, not a silent reading
    assert score.info["problems"] == ["no direction letter among the reply's top logprobs: uniform"]


def test_a_read_letter_is_no_problem():
    stub = StubChatModel(["B\nyes"], logprob_fn=lambda text, top: [LETTER, _tok("\n"),
                                                                    _tok("yes", yes=0.9, no=0.1)])
    assert explore_token_scores(stub, "Where is the cat?", VIEW, DIRECTIONS).info["problems"] == []


def _image_obs():
    from efficienteqa.geometry import Pose2D
    from efficienteqa.observation import Observation

    rgb = np.full((120, 160, 3), 90, np.uint8)
    return Observation(rgb, np.ones((120, 160), np.float32), np.eye(4), np.eye(3),
                       Pose2D(0.0, 0.0, 0.0))


def _worth_or_letters(msgs):
    if "worth exploring" in msgs[-1].text and "Directions:" not in msgs[-1].text:
        return "worth exploring: no 80"
    return "A: 70\nB: 30"


@pytest.mark.parametrize("confidence", ["verbalized", "token"])
def test_an_image_vlm_judges_worth_exploring_on_the_unmarked_frame(confidence):
    """DESIGN 3.3 asks "is this direction worth exploring" on the plain RGB frame
    and the lettered points on the frame with circles: two calls, the second's only image the
    frame as captured, with no circle on it."""
    from efficienteqa.explore.vlm_scorer import VLMScorer
    from efficienteqa.observation import PromptPoint
    from efficienteqa.perception.image import CIRCLE_FILL, ImagePerception

    obs = _image_obs()
    prompts = [PromptPoint("A", (1.0, 0.0), (40.5, 60.5)), PromptPoint("B", (2.0, 0.0), (120.5, 60.5))]
    tokens = {"verbalized": None,
              "token": lambda text, top: [_tok(text, **({"A": 0.9, "B": 0.1} if text == "A"
                                                        else {"yes": 0.8, "no": 0.2}))]}
    script = (_worth_or_letters if confidence == "verbalized"
              else lambda msgs: "yes" if "yes or no only" in msgs[-1].text else "A")
    stub = StubChatModel(script, logprob_fn=tokens[confidence])
    score = VLMScorer(stub, ImagePerception(), confidence=confidence).score(obs, prompts, "Where is the cat?")
    assert len(stub.requests) == 2
    letters_call, worth_call = (r.messages[-1] for r in stub.requests)
    (marked,) = letters_call.images
    assert (marked == np.array(CIRCLE_FILL)).all(axis=2).sum() > 300  # the circles are drawn
    assert "Directions:" in letters_call.text and "yes or no" not in letters_call.text.lower()
    (plain,) = worth_call.images
    assert np.array_equal(plain, obs.rgb)  # the frame as captured: no circle
    assert "Directions" not in worth_call.text and "Where is the cat?" in worth_call.text
    if confidence == "verbalized":
        assert score.letters == pytest.approx({"A": 0.7, "B": 0.3})
        assert score.p_yes == pytest.approx(0.2)
        assert score.info["worth_raw"] == "worth exploring: no 80"
    else:
        assert score.letters == pytest.approx({"A": 0.9, "B": 0.1})
        assert score.p_yes == pytest.approx(0.8)
        assert worth_call.text.rstrip().endswith("Where is the cat?")


def test_a_text_model_still_gets_one_exploration_call():
    from efficienteqa.explore.vlm_scorer import VLMScorer
    from efficienteqa.perception.base import ExploreRequest

    class Text:
        name, modality = "text", "text"

        def explore_request(self, obs, prompts):
            return ExploreRequest(VIEW, DIRECTIONS)

    stub = StubChatModel(["B: 60\nA: 40\nworth exploring: yes 80"])
    score = VLMScorer(stub, Text()).score(_image_obs(), [], "Is the oven on?")  # type: ignore[arg-type]
    assert len(stub.requests) == 1 and score.p_yes == pytest.approx(0.8)
