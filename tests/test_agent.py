"""End-to-end episodes of the agent in synthetic houses, with scripted models (deterministic)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from agent_stubs import MentionScorer, averse_model, seeking_model, token_seeking_model
from conftest import needs_egl
from efficienteqa.agent import Agent, AgentConfig
from efficienteqa.ask import ask
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec
from efficienteqa.models.base import Capabilities
from efficienteqa.models.stub import StubChatModel
from efficienteqa.perception.image import CIRCLE_FILL
from efficienteqa.relevancy.text import WordOverlapScorer
from efficienteqa.scenes import Scene, synthetic_questions
from efficienteqa.stack import Stack, answer_name, build_agent, parse_vlm
from efficienteqa.stop import StopConfig
from test_relevancy import blip2, torch  # noqa: F401 - fixtures: a tiny random BLIP-2 ITM

pytestmark = needs_egl
CAMERA = CameraSpec().scaled(320, 240)


@pytest.fixture(scope="module")
def house4(catalog):
    """Builtin house 4; its question syn-4-10 asks for the colour of the desk in the office."""
    env = SyntheticEnv(generate_house(4, catalog, "builtin"), catalog, CAMERA)
    questions = synthetic_questions(env)
    yield Scene(env, "synthetic:4 (builtin)", questions), next(q for q in questions if q.id == "syn-4-10")
    env.close()


def _episode(scene, question, model, tmp_path, max_steps, **kw):
    desk = scene.env.house.object(question.evidence[0])
    room = scene.env.house.room(desk.room_id).name
    return ask(question.question, scene, tmp_path, stack=Stack(grouping="rules", explore_scorer="vlm"),
               model=model(desk.category, room), relevancy=MentionScorer(desk.category, room),
               config=AgentConfig.of(max_steps=max_steps, **kw))


def test_a_model_that_points_at_the_evidence_stops_early_and_answers_right(house4, tmp_path):
    scene, q = house4
    assert q.answer == "black"
    # The explorer samples frontiers: with seed 1 its path reaches the office within the budget
    # (seeds 0-3: 2 of 4 episodes stop at the desk, for the default and the paper prompts alike).
    done = _episode(scene, q, seeking_model, tmp_path, max_steps=30, seed=1)
    r = done.result
    assert r.stop_reason == "relevancy" and AgentConfig().stop.min_step <= r.steps < 30
    assert r.answer == "black"
    stop = r.records[-1].check
    assert stop.stop and stop.z > 3 and stop.sim == 1.0
    assert r.retrieved[0] == (r.steps, 1.0)  # the outlier frame is the best evidence
    record = json.loads(done.episode_json.read_text())
    assert record["stop_reason"] == "relevancy" and record["oracle_steps"] == q.oracle_steps
    assert record["reference"]["answer"] == "black" and record["answer"] == "black"
    assert len(record["per_step"]) == r.steps and record["model"]["calls"] >= 2
    assert record["backends"]["relevancy"] == "mention-stub"
    assert record["backends"]["answer"].startswith("direct")  # the stub gives logprobs
    assert record["backends"]["perception"] == "semantic-sensor"
    assert record["backends"]["environment"] == "synthetic (builtin)"  # the back-end, not the scene
    assert record["scene"] == "synthetic:4 (builtin)"


def test_a_model_that_never_points_at_it_runs_to_the_budget(house4, tmp_path):
    scene, q = house4
    # Steered away, the robot still passes the office by chance: at step 11 a frame names the
    # desk there (since frontiers along slanted edges are kept). 10 steps stay clear of it under
    # DESIGN 3.4's rule, without the gate and the target steering (which walks to the office).
    r = _episode(scene, q, averse_model, tmp_path, max_steps=10,
                 stop=StopConfig(rule="paper"), gate="none", steering="none").result
    assert r.stop_reason == "budget" and r.steps == 10
    assert r.answer == "unknown"
    assert all(not rec.check.stop for rec in r.records if rec.check)


@pytest.mark.parametrize("confidence,model", [("verbalized", seeking_model),
                                              ("token", token_seeking_model)])
def test_explore_eqa_answers_at_the_step_of_highest_relevancy_times_confidence(
        house4, tmp_path, confidence, model):
    scene, q = house4
    runs = {every: _episode(scene, q, model, tmp_path / str(every), max_steps=12,
                            answer_at="best-step", confidence=confidence,
                            stop=StopConfig(enabled=False), seed=1, answer_every_step=every)
            for every in (True, False)}
    online, lazy = runs[True].result, runs[False].result
    for r in (online, lazy):
        assert r.stop_reason == "budget" and r.steps == 12  # no early stop: the full budget
    answered = [rec for rec in online.records if rec.step_answer is not None]
    assert len(answered) == sum(rec.valid for rec in online.records)  # one answer per valid frame
    best = max(answered, key=lambda rec: rec.step_answer["value"])
    assert online.retrieved == [(best.step, best.check.sim)]
    assert online.answer == best.step_answer["answer"]
    assert online.confidence == best.step_answer["confidence"]
    for rec in answered:
        assert rec.step_answer["value"] == pytest.approx(rec.check.sim * rec.step_answer["confidence"])
    # Asking only the frames that can still win gives the same answer from the same step.
    assert (lazy.answer, lazy.confidence, lazy.retrieved) == (online.answer, online.confidence,
                                                              online.retrieved)
    lazily = [rec for rec in lazy.records if rec.step_answer is not None]
    assert 1 <= len(lazily) < len(answered)
    assert all(rec.step_answer == online.records[rec.step - 1].step_answer for rec in lazily)
    if confidence == "verbalized":  # this trajectory frames the desk (Sim 1) within the budget
        assert best.check.sim == 1.0 and online.answer == "black"
    exchanges = runs[True].record["model"]["exchanges"]
    assert not any(e["phase"] == "answer" for e in exchanges)  # no final RAG call
    if confidence == "token":  # the stub makes each word 90% likely: p("I cannot tell") = 0.9^3
        assert {round(rec.step_answer["confidence"], 3) for rec in answered} <= {0.9, 0.729}
        assert all("two lines" in e["prompt"] for e in exchanges if e["prompt"].startswith("You guide"))


def test_the_white_box_baseline_needs_logprobs(house4, tmp_path):
    scene, q = house4
    blind = StubChatModel(["x"], capabilities=Capabilities(logprobs=False))
    with pytest.raises(EfficientEQAError, match="log-probabilities"):
        ask(q.question, scene, tmp_path, stack=Stack(grouping="rules", explore_scorer="vlm"), model=blind,
            relevancy=MentionScorer("desk"), config=AgentConfig.of(confidence="token"))


def test_the_answer_is_direct_when_the_model_gives_logprobs_and_the_papers_otherwise():
    with_logprobs = StubChatModel(["x"])
    without = StubChatModel(["x"], capabilities=Capabilities(logprobs=False))
    assert answer_name(AgentConfig(), with_logprobs) == "direct"
    assert answer_name(AgentConfig(), without) == "paper"
    assert answer_name(AgentConfig.of(answer="paper"), with_logprobs) == "paper"
    assert answer_name(AgentConfig.of(answer_at="best-step"), with_logprobs) == "paper"
    with pytest.raises(EfficientEQAError, match="answers at every step"):
        answer_name(AgentConfig.of(answer="direct", answer_at="best-step"), with_logprobs)


def test_the_direct_answer_needs_logprobs(house4, tmp_path):
    scene, q = house4
    blind = StubChatModel(["x"], capabilities=Capabilities(logprobs=False))
    with pytest.raises(EfficientEQAError, match="log-probabilities"):
        ask(q.question, scene, tmp_path, stack=Stack(grouping="rules", explore_scorer="vlm"),
            model=blind, relevancy=MentionScorer("desk"), config=AgentConfig.of(answer="direct"))


def test_the_explore_calls_carry_the_question_and_the_directions(house4, tmp_path):
    scene, q = house4
    model = seeking_model("desk", "office")
    built = build_agent(scene.env, Stack(grouping="rules", explore_scorer="vlm"), AgentConfig.of(max_steps=4),
                        "test", model=model, relevancy=WordOverlapScorer())
    r = built.agent.run(scene.env, q.question)
    explore = [e for e in built.model.exchanges if e.phase.startswith("step")]
    assert explore and all(q.question in e.prompt and "Directions:" in e.prompt for e in explore)
    assert sum(len(rec.calls) for rec in r.records) == len(explore)
    assert [e.phase for e in built.model.exchanges][-1] == "answer"
    assert [rec.step for rec in r.records] == [1, 2, 3, 4]


class SequenceScorer:
    """Relevancy stand-in: the given Sims, one per valid frame, in order."""

    name = "sequence-stub"
    modality = "text"

    def __init__(self, sims):
        self.sims = iter(sims)

    def score(self, question, *, image=None, text=None):  # noqa: ANN001, ANN201
        return next(self.sims)


def test_the_agent_may_stop_at_the_minimum_step_itself(house4):
    """An outlier at step 10 (the paper's minimum) stops the episode there: steps count from 1
    and "never before step 10" lets step 10 stop."""
    scene, q = house4
    model = StubChatModel(lambda msgs: "A: 50\nworth exploring: no 50"
                          if msgs[-1].text.startswith("You guide") else "black; 90")
    sims = [0.1, 0.2] * 4 + [0.15, 5.0] + [0.1] * 10
    built = build_agent(scene.env, Stack(grouping="rules", explore_scorer="vlm"),
                        AgentConfig.of(max_steps=14, gate="none", stop=StopConfig()), "test",
                        model=model, relevancy=SequenceScorer(sims))
    r = built.agent.run(scene.env, q.question)
    assert all(rec.valid for rec in r.records)
    assert (r.stop_reason, r.steps) == ("relevancy", 10) and r.records[-1].check.sim == 5.0


def test_invalid_frames_never_reach_a_model(house4, tmp_path):
    scene, q = house4

    class BlindAtOddSteps:
        """The house, but frames of odd steps have no depth at all (outside the mesh)."""

        def __init__(self, env):
            self.env, self.n = env, 0

        def __getattr__(self, name):
            return getattr(self.env, name)

        def _blank(self, obs):
            self.n += 1
            return replace(obs, depth_m=np.zeros_like(obs.depth_m)) if self.n % 2 else obs

        def reset(self, **kw):
            obs, info = self.env.reset(**kw)
            return self._blank(obs), info

        def step(self, action):
            obs, *rest = self.env.step(action)
            return (self._blank(obs), *rest)

    env = BlindAtOddSteps(scene.env)
    seen = []
    model = StubChatModel(lambda msgs: seen.append(msgs[-1].text) or "A: 50\nworth exploring: no 0"
                          if msgs[-1].text.startswith("You guide") else "unknown; 100")
    built = build_agent(env, Stack(grouping="rules", explore_scorer="vlm"),
                        AgentConfig.of(max_steps=6), "test",
                        model=model, relevancy=WordOverlapScorer())
    r = built.agent.run(env, q.question)
    assert [rec.valid for rec in r.records] == [False, True, False, True, False, True]
    assert all(rec.check is None and not rec.calls for rec in r.records if not rec.valid)
    assert {s for s, _ in r.retrieved} <= {2, 4, 6}


def test_frontier_only_makes_no_explore_calls(house4, tmp_path):
    scene, q = house4
    model = StubChatModel(["unknown; 100"])
    done = ask(q.question, scene, tmp_path, stack=Stack(grouping="rules", explore_scorer="vlm"), model=model,
               relevancy=WordOverlapScorer(), config=AgentConfig.of(explorer="frontier-only", max_steps=5))
    assert len(model.requests) == 1 and done.result.steps == 5


def test_text_relevancy_needs_text_perception(house4):
    scene, _ = house4
    with pytest.raises(EfficientEQAError, match="cannot read images"):
        build_agent(scene.env, Stack(perception="rgb"), AgentConfig(), "test",
                    model=StubChatModel([], capabilities=replace(
                        StubChatModel([]).capabilities, images=False)),
                    relevancy=WordOverlapScorer())
    with pytest.raises(ValueError, match="reads text"):
        from efficienteqa.perception.image import ImagePerception

        Agent(ImagePerception(), None, WordOverlapScorer(), None)  # type: ignore[arg-type]


def test_vlm_specs():
    b = parse_vlm("openai:gpt-4o@http://localhost:8000/v1", images=True)
    assert (b.kind, b.model, b.base_url, b.images) == ("openai", "gpt-4o", "http://localhost:8000/v1", True)
    assert parse_vlm("local:smollm2-135m", images=False).base_url is None
    for bad in ("gpt-4o", "ollama:llava", "local:"):
        with pytest.raises(EfficientEQAError, match="cannot read --backends.vlm"):
            parse_vlm(bad, images=False)


class BrightnessScorer:
    """An image relevancy stand-in: the mean brightness of the frame."""

    name = "brightness-stub"
    modality = "image"

    def score(self, question, *, image=None, text=None):  # noqa: ANN001, ANN201
        return float(np.asarray(image, float).mean() / 255)

    def score_many(self, question, items):  # noqa: ANN001, ANN201
        return np.array([self.score(question, image=i) for i in items])


def _brightness_answer(msgs):
    """Says how bright the evidence images are, first (best) image first: the answer shows which
    frames were retrieved and in which order."""
    if msgs[-1].text.startswith("You guide"):
        return "A: 70\nB: 30\nworth exploring: yes 80"
    shares = (60, 30, 10)
    return "\n".join(f"{np.asarray(im, float).mean() / 255:.4f}; {c}"
                     for im, c in zip(msgs[-1].images, shares))


def test_an_image_vlm_gets_marked_frames_and_the_top_k_images(house4, tmp_path):
    scene, q = house4
    model = StubChatModel(_brightness_answer)
    done = ask(q.question, scene, tmp_path, stack=Stack(perception="rgb", grouping="rules"),
               model=model, relevancy=BrightnessScorer(),
               config=AgentConfig.of(max_steps=6, top_k=3, answer="paper"))  # M guesses
    explore = [r for r in model.requests if r.messages[-1].text.startswith("You guide")]
    assert explore, "no exploration call"
    for request in explore:
        (image,) = request.messages[-1].images
        assert image.shape == (240, 320, 3) and "the image" in request.messages[-1].text
        circles = (image == np.array(CIRCLE_FILL)).all(axis=2).sum()
        assert circles > 500  # at least one lettered disk of radius 18 px is drawn
        assert "(the lettered circles in the image)" in request.messages[-1].text
    answer = model.requests[-1].messages[-1]
    assert len(answer.images) == 3 and "the 3 attached images" in answer.text
    # the brightest frame of the episode (Sim = brightness) went first, unmarked
    sims = sorted((rec.check.sim for rec in done.result.records if rec.check), reverse=True)
    assert [s for _, s in done.result.retrieved] == pytest.approx(sims[:3])
    assert float(done.result.answer) == pytest.approx(sims[0], abs=1e-4)
    assert done.result.confidence == pytest.approx(0.6)
    assert done.record["backends"]["perception"] == "rgb"
    assert "Semantic-sensor perception" not in done.report_html.read_text()


def test_vlm_match_relevancy_is_a_recorded_model_call_per_frame(house4, tmp_path):
    scene, q = house4

    def reply(msgs):
        text = msgs[-1].text
        if text.startswith("Does this view"):
            return "yes 90" if "desk" in text.split("View:")[1] else "no 80"
        return "A: 50\nworth exploring: yes 50" if text.startswith("You guide") else "black; 90"

    built = build_agent(scene.env, Stack(relevancy="vlm-match", grouping="rules"),
                        AgentConfig.of(max_steps=5), "test", model=StubChatModel(reply))
    r = built.agent.run(scene.env, q.question)
    match = [e for e in built.model.exchanges if e.prompt.startswith("Does this view")]
    assert len(match) == sum(rec.valid for rec in r.records)
    assert all(any(built.model.exchanges[i].prompt.startswith("Does this view") for i in rec.calls)
               for rec in r.records if rec.valid)
    assert {round(rec.check.sim, 6) for rec in r.records if rec.check} <= {0.9, 0.2}
    assert built.backends["relevancy"] == "vlm-match:stub"


def test_the_papers_stack_rgb_frames_and_blip2_itm(house4, tmp_path, request):
    """A VLM reading frames and BLIP-2 ITM relevancy (a tiny random one, no download): the
    whole episode runs on images and records which back-ends produced it."""
    pytest.importorskip("transformers", reason="needs the 'vision' extra")
    itm = request.getfixturevalue("blip2")
    scene, q = house4
    # the first guess is brown, but the two spellings of black together weigh more
    model = StubChatModel(lambda msgs: "A: 60\nB: 40\nworth exploring: yes 70"
                          if msgs[-1].text.startswith("You guide") else "brown; 40\nblack; 35\nBlack.; 25")
    done = ask(q.question, scene, tmp_path, stack=Stack(perception="rgb", grouping="rules"),
               model=model, relevancy=itm,
               config=AgentConfig.of(max_steps=4, top_k=2, answer="paper"))
    sims = [rec.check.sim for rec in done.result.records if rec.check]
    assert len(sims) == 4 and all(0.0 <= s <= 1.0 for s in sims)
    assert done.record["backends"]["relevancy"] == itm.name
    assert len(model.requests[-1].messages[-1].images) == 2
    assert [st for st, _ in done.result.retrieved] == [
        rec.step for rec in sorted((r for r in done.result.records if r.check),
                                   key=lambda r: (-r.check.sim, r.step))][:2]
    assert (done.result.answer, done.result.confidence) == ("black", pytest.approx(0.6))


@pytest.mark.parametrize("given, read", [({}, ("product", "short")),
                                         ({"answer_probability": "per-token",
                                           "token_answer": "verbalized"}, ("per-token", "verbalized"))])
def test_the_token_answer_settings_reach_the_answerer(house4, given, read):
    scene, _ = house4
    config = AgentConfig.of(confidence="token", **given)
    built = build_agent(scene.env, Stack(grouping="rules"), config, "test",
                        model=StubChatModel([]), relevancy=WordOverlapScorer())
    assert (built.agent.answerer.probability, built.agent.answerer.token_prompt) == read


def test_an_unreadable_relevancy_reply_is_missing_and_every_problem_is_counted(house4, tmp_path):
    """The frame whose yes/no reply could not be read has no Sim, so
    it neither stops the robot nor is retrieved; the explore, relevancy and answer problems are
    counted in episode.json."""
    scene, q = house4
    said = {"match": 0}

    def reply(msgs):
        text = msgs[-1].text
        if text.startswith("Does this view"):
            said["match"] += 1
            return "N/A" if said["match"] == 3 else f"no {60 + said['match']}"
        if text.startswith("You guide"):
            return "A: 50\nworth exploring: perhaps"  # no yes/no: an explore problem
        return "black; 90"

    done = ask(q.question, scene, tmp_path, stack=Stack(relevancy="vlm-match", grouping="rules",
                                                        explore_scorer="vlm"),
               model=StubChatModel(reply), config=AgentConfig.of(max_steps=5, gate="none"))
    r, record = done.result, done.record
    missing = r.records[2]
    assert missing.valid and missing.check is None and missing.relevancy_problems
    assert 3 not in [step for step, _ in r.retrieved]
    assert all(rec.check is not None for rec in r.records if rec.valid and rec.step != 3)
    assert record["problems"]["relevancy"] == 1
    assert record["problems"]["explore"] >= 1  # the explore replies lacked their yes/no
    assert record["explore_problems"][0].startswith("step 1: ")
    assert record["relevancy_problems"][0].startswith("step 3: unreadable reply 'N/A'")
    assert json.loads((tmp_path / "episode.json").read_text())["per_step"][2]["relevancy_problems"]


def test_an_episode_that_fails_at_its_answer_keeps_what_it_explored(house4, tmp_path):
    """``ask`` writes episode.json with the steps taken and every model
    call made before the failure, and the error carries that record for eval's row."""
    scene, q = house4

    def reply(msgs):
        if msgs[-1].text.startswith("A robot explored"):
            raise EfficientEQAError("model server at http://x/v1 rejected the request: HTTP 400")
        return "A: 50\nworth exploring: yes 50"

    with pytest.raises(EfficientEQAError, match="HTTP 400") as failure:
        ask(q.question, scene, tmp_path, stack=Stack(grouping="rules", explore_scorer="vlm"),
            model=StubChatModel(reply), relevancy=WordOverlapScorer(),
            config=AgentConfig.of(max_steps=3, gate="none"))
    record = json.loads((tmp_path / "episode.json").read_text())
    assert record["status"] == "failed" and "HTTP 400" in record["error"]
    assert record["steps"] == 3 and len(record["per_step"]) == 3
    assert record["model"]["calls"] >= 2  # explore calls, and the failed answer call
    assert "<error:" in record["model"]["exchanges"][-1]["reply"]
    assert failure.value.partial_episode == record


def test_the_records_back_ends_say_the_servers_capabilities_and_the_answers_fallback(house4):
    """A server without token probabilities gets the paper's verbalized
    answer, and every record says so, with the capabilities it was run with."""
    scene, _ = house4
    without = StubChatModel(["x"], capabilities=Capabilities(images=True, logprobs=False,
                                                             source="probed"))
    built = build_agent(scene.env, Stack(grouping="rules", explore_scorer="vlm"), AgentConfig(),
                        "test", model=without, relevancy=MentionScorer("desk"))
    assert built.backends["answer"].startswith("paper") and "fallback" in built.backends["answer"]
    caps = built.backends["capabilities"]
    assert caps["logprobs"] is False and caps["source"] == "probed"
    chosen = build_agent(scene.env, Stack(grouping="rules", explore_scorer="vlm"),
                         AgentConfig.of(answer="paper"), "test", model=without,
                         relevancy=MentionScorer("desk"))
    assert "fallback" not in chosen.backends["answer"]  # asked for, not fallen back to


def test_the_relevancy_scores_frames_against_the_question_in_the_perceptions_words(house4):
    """``StopConfig.question_words``: "perceived" (the default) names the lounge the living
    room for the relevancy; "asked" (the paper's) passes the question as typed."""
    scene, _ = house4

    class Heard(MentionScorer):
        def __init__(self) -> None:
            super().__init__("sofa")
            self.questions: list[str] = []

        def score(self, question: str, *, image=None, text: str | None = None) -> float:  # noqa: ANN001
            self.questions.append(question)
            return super().score(question, image=image, text=text)

    asked = "Is the tv in the lounge on?"
    for words, heard in (("perceived", "is the tv in the living room on?"), ("asked", asked)):
        scorer = Heard()
        built = build_agent(scene.env, Stack(grouping="rules", explore_scorer="vlm"),
                            AgentConfig.of(max_steps=2, question_words=words), "test",
                            model=seeking_model("tv", "living room"), relevancy=scorer)
        built.agent.run(scene.env, asked)
        assert scorer.questions and set(scorer.questions) == {heard}, words
