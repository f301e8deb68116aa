"""Direction scorers (DESIGN 8): the model-free text scorers, the black-box elicitations
with a stub model, the explore scorer a stack picks, and the direction experiment's baselines
(experiments/direction_scorers.py) and labelling."""

from __future__ import annotations

import math

import pytest

from efficienteqa.agent import AgentConfig
from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.text_scorers import (
    FEATURES,
    LOGIT_WEIGHTS,
    DirectionFrame,
    DirectionScorer,
    LogitDirections,
    direction_features,
    direction_rooms,
)
from efficienteqa.geometry import Pose2D
from efficienteqa.models.base import Message
from efficienteqa.models.stub import StubChatModel
from efficienteqa.observation import PromptPoint
from efficienteqa.perception.base import ExploreRequest
from efficienteqa.stack import Stack, explore_scorer_name
from experiments.direction_scorers import (
    DebiasedDirections,
    KeywordDirections,
    NearestDirections,
    SampledDirections,
    YesNoDirections,
    first_letter,
    relabelled,
)

QUESTION = "What is on the desk in the office?"
TEXTS = {
    "A": "in the hallway, 1.2 m away; a green plant.",
    "B": "towards the office, floor of the hallway in view, 3.4 m away; a brown desk; "
         "an open door to the hallway.",
    "C": "in the hallway, 2.0 m away; no objects seen there.",
}
RANGES = {"A": 1.2, "B": 3.4, "C": 2.0}


def frame(texts=TEXTS, ranges=RANGES, question=QUESTION) -> DirectionFrame:
    return DirectionFrame(question, "You are in the hallway.", dict(texts), dict(ranges))


def best(scores: dict[str, float]) -> str:
    return max(scores, key=scores.__getitem__)


# -- model-free scorers ---------------------------------------------------------------------
def test_nearest_prefers_the_nearest_point():
    scores, _ = NearestDirections().letter_scores(frame())
    assert best(scores) == "A" and scores["A"] > scores["C"] > scores["B"]
    assert math.isclose(sum(scores.values()), 1.0)


def test_keyword_finds_the_question_words_and_is_uniform_without_any():
    scores, _ = KeywordDirections().letter_scores(frame())
    assert best(scores) == "B" and scores["A"] == scores["C"] == 0
    none, _ = KeywordDirections().letter_scores(frame(question="Where is the piano?"))
    assert len(set(none.values())) == 1


def test_direction_rooms_reads_the_perception_text():
    rooms = direction_rooms(TEXTS["B"])
    assert rooms.at == "office" and rooms.towards
    assert rooms.floor == ("hallway",) and rooms.doors == ("hallway",)
    assert rooms.all == ("office", "hallway")
    two = direction_rooms("in the kitchen, floor of the hallway and the dining room in view, "
                          "2.0 m away; a stove.")
    assert two.at == "kitchen" and not two.towards and two.floor == ("hallway", "dining room")
    assert direction_rooms("1.0 m away; no objects seen there.").at is None


def test_features_name_the_question_room_and_the_nearest_point():
    x = direction_features(frame())
    col = {name: i for i, name in enumerate(FEATURES)}
    assert x.shape == (3, len(FEATURES))
    assert x[:, col["question_room"]].tolist() == [0.0, 1.0, 0.0]  # "office" only in B
    assert x[:, col["towards"]].tolist() == [0.0, 1.0, 0.0]
    assert x[:, col["nearest"]].tolist() == [1.0, 0.0, 0.0]
    assert x[:, col["no_objects"]].tolist() == [0.0, 0.0, 1.0]
    assert x[:, col["hallway"]].tolist() == [1.0, 1.0, 1.0]


def test_logit_follows_its_weights():
    only_room = [1.0 if f == "question_room" else 0.0 for f in FEATURES]
    only_near = [1.0 if f == "nearest" else 0.0 for f in FEATURES]
    assert best(LogitDirections(only_room).letter_scores(frame())[0]) == "B"
    assert best(LogitDirections(only_near).letter_scores(frame())[0]) == "A"
    # the fitted default: the direction towards the office the question names wins here
    assert best(LogitDirections(LOGIT_WEIGHTS).letter_scores(frame())[0]) == "B"
    with pytest.raises(ValueError):
        LogitDirections([1.0, 2.0])


class TextPerception:
    name, modality = "stub-text", "text"

    def explore_request(self, obs, prompts):
        return ExploreRequest("You are in the hallway.", {p.letter: TEXTS[p.letter] for p in prompts})


class Obs:
    pose = Pose2D(0.0, 0.0, 0.0)


def test_direction_scorer_is_a_semantic_scorer():
    prompts = [PromptPoint("A", (1.2, 0.0), (10, 10)), PromptPoint("B", (0.0, 3.4), (20, 10)),
               PromptPoint("C", (2.0, 0.0), (30, 10))]
    s = DirectionScorer(NearestDirections(), TextPerception()).score(Obs(), prompts, QUESTION)
    assert best(s.letters) == "A" and s.p_yes == 0.5 and s.info["scorer"] == "nearest"


# -- black-box elicitations with a stub model -----------------------------------------------
def directions_of(messages: list[Message]) -> dict[str, str]:
    """The lettered lines of a choice prompt."""
    lines = messages[-1].text.split("Directions:\n", 1)[1].splitlines()
    return {ln[0]: ln[3:] for ln in lines if len(ln) > 2 and ln[1] == ":"}


def test_relabelled_turns_the_order():
    assert relabelled(TEXTS, 0) == {"A": "A", "B": "B", "C": "C"}
    assert relabelled(TEXTS, 1) == {"A": "B", "B": "C", "C": "A"}
    assert first_letter("(C) because", ["A", "B", "C"]) == "C"
    assert first_letter("none", ["A", "B"]) is None


def test_debiasing_cancels_a_model_that_always_says_a():
    model = StubChatModel(lambda _: "A")
    scores, info = DebiasedDirections(model).letter_scores(frame())
    assert all(math.isclose(v, 1 / 3) for v in scores.values()) and not info["problems"]
    assert len(model.requests) == 3 and all(r.logprobs for r in model.requests)


def test_a_choice_reply_without_any_letter_is_counted_as_a_problem():
    """A one-token reply whose top logprobs hold no letter gives uniform scores, said so."""
    model = StubChatModel(lambda _: "The")
    scores, info = DebiasedDirections(model).letter_scores(frame())
    assert all(math.isclose(v, 1 / 3) for v in scores.values())
    assert len(info["problems"]) == 3 and "no letter among the top logprobs" in info["problems"][0]


def test_debiased_choice_follows_the_office_wherever_it_is_shown():
    def office(messages):
        return next(x for x, t in directions_of(messages).items() if "office" in t)

    model = StubChatModel(office)
    scores, _ = DebiasedDirections(model).letter_scores(frame())
    assert scores["B"] > 0.85
    shown = [directions_of(r.messages) for r in model.requests]
    assert len({d["A"] for d in shown}) == 3  # each direction lettered A once


def test_sampled_choices_count_votes_and_degrade_to_uniform():
    model = StubChatModel(lambda m: next(x for x, t in directions_of(m).items() if "desk" in t))
    scores, _ = SampledDirections(model, n=3).letter_scores(frame())
    assert scores == {"A": 0.0, "B": 1.0, "C": 0.0}
    assert [r.temperature for r in model.requests] == [1.0] * 3
    scores, info = SampledDirections(StubChatModel(lambda _: "hmm"), n=3).letter_scores(frame())
    assert len(set(scores.values())) == 1 and info["problems"]


def test_yes_no_reads_p_yes_per_direction_and_records_unreadable_replies():
    model = StubChatModel(lambda m: "yes" if "office" in m[-1].text.split("walk to:")[1] else "no")
    scores, info = YesNoDirections(model).letter_scores(frame())
    assert best(scores) == "B" and scores["A"] < 0.5 and not info["problems"]
    scores, info = YesNoDirections(StubChatModel(lambda _: "perhaps")).letter_scores(frame())
    assert set(scores.values()) == {0.5} and len(info["problems"]) == 3


# -- the explore scorer a stack uses --------------------------------------------------------
class ImagePerception:
    name, modality = "rgb", "image"


def test_the_offline_stack_takes_the_direction_logit_and_vlms_keep_their_confidence():
    text, image = TextPerception(), ImagePerception()
    assert explore_scorer_name(Stack(), text, AgentConfig()) == "direction-logit"
    assert explore_scorer_name(Stack(), image, AgentConfig()) == "vlm"
    assert explore_scorer_name(Stack(), text, AgentConfig.of(confidence="token")) == "vlm"
    assert explore_scorer_name(Stack(explore_scorer="vlm"), text, AgentConfig()) == "vlm"
    with pytest.raises(EfficientEQAError):
        explore_scorer_name(Stack(explore_scorer="direction-logit"), image, AgentConfig())
    with pytest.raises(EfficientEQAError):
        explore_scorer_name(Stack(explore_scorer="bogus"), text, AgentConfig())


def test_the_paper_preset_keeps_the_vlm():
    from efficienteqa.config.presets import PRESETS

    assert PRESETS["paper"]["backends.explore_scorer"] == "vlm"


# -- the benchmark's labelling --------------------------------------------------------------
@pytest.fixture(scope="module")
def bench():
    from experiments import direction_bench

    return direction_bench


def test_best_letters_are_the_closest_and_unlabelled_frames_are_dropped(bench):
    assert bench.best_letters({"A": 5.0, "B": 3.0, "C": 4.0}) == ["B"]
    assert bench.best_letters({"A": 3.0, "B": 3.02, "C": None}) == ["A", "B"]  # tied within 5 cm
    assert bench.best_letters({"A": None, "B": 2.0}) == ["B"]
    assert bench.best_letters({"A": None, "B": None}) is None  # nothing finite
    assert bench.best_letters({"A": 2.0, "B": 2.0}) is None  # all tied


def test_top1_credit_is_fractional_over_the_scorers_ties(bench):
    assert bench.top1_credit({"A": 0.2, "B": 0.7, "C": 0.1}, ["B"]) == 1.0
    assert bench.top1_credit({"A": 0.7, "B": 0.2, "C": 0.1}, ["B"]) == 0.0
    assert bench.top1_credit({"A": 0.4, "B": 0.4, "C": 0.2}, ["B"]) == 0.5
    assert bench.top1_credit({"A": 1.0, "B": 1.0, "C": 1.0}, ["C"]) == pytest.approx(1 / 3)


def test_spearman_against_negative_distances(bench):
    d = {"A": 5.0, "B": 3.0, "C": None}
    assert bench.spearman({"A": 0.5, "B": 0.9, "C": 0.1}, d) == pytest.approx(1.0)
    assert bench.spearman({"A": 0.5, "B": 0.1, "C": 0.9}, d) == pytest.approx(-1.0)
    assert bench.spearman({"A": 0.3, "B": 0.3, "C": 0.3}, d) == 0.0


def test_a_colder_logit_keeps_the_ranking_and_sharpens_the_confidences():
    from efficienteqa.explore.text_scorers import LOGIT_WEIGHTS, LogitDirections

    warm, _ = LogitDirections(LOGIT_WEIGHTS).letter_scores(frame())
    cold, _ = LogitDirections(LOGIT_WEIGHTS, temperature=0.25).letter_scores(frame())
    assert sorted(warm, key=warm.get) == sorted(cold, key=cold.get)
    assert max(cold.values()) > max(warm.values())
