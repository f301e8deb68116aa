"""When the evidence was first in view, recorded after the episode from the ground truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agent_stubs import MentionScorer, seeking_model
from conftest import needs_egl
from efficienteqa.agent import AgentConfig
from efficienteqa.ask import ask
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.envs.synthetic.questions import MIN_EVIDENCE_PIXELS, evidence_visible
from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.observation import Observation
from efficienteqa.report.evidence import FIELDS, EvidenceWatch, evidence_pixels
from efficienteqa.scenes import Scene, synthetic_questions
from efficienteqa.stack import Stack
from efficienteqa.trace import StepRecord


def _frame(pixels: dict[int, int], size: int = 64) -> Observation:
    """A frame whose instance buffer holds ``pixels[id]`` pixels of each object."""
    inst = np.zeros(size * size, np.int32)
    at = 0
    for obj, n in pixels.items():
        inst[at:at + n] = obj
        at += n
    return Observation(np.zeros((size, size, 3), np.uint8), np.ones((size, size), np.float32),
                       np.eye(4), np.eye(3), Pose2D(0, 0, 0), inst.reshape(size, size))


def _watch(evidence, frames) -> EvidenceWatch:
    watch = EvidenceWatch(evidence)
    for step, frame in enumerate(frames, start=1):
        watch(StepRecord(step, (0.0, 0.0, 0.0), True), frame, None)
    return watch


def test_first_seen_needs_every_evidence_object_at_the_oracles_pixel_threshold():
    # 64 x 64 frames: the oracle's threshold scales with the frame to this many pixels.
    need = max(4, round(MIN_EVIDENCE_PIXELS * 64 * 64 / (640 * 480)))
    frames = [_frame({}), _frame({7: need, 9: need - 1}), _frame({7: need, 9: need}),
              _frame({9: 500}), _frame({7: need + 3, 9: need})]
    watch = _watch([7, 9], frames)
    assert watch.fields([(4, 0.9), (1, 0.5)]) == {
        "evidence_first_seen_step": 3, "evidence_in_top_k": False, "evidence_seen_steps": [3, 5],
        "evidence_stop_pixels": None}
    assert watch.fields([(5, 0.9), (1, 0.5)])["evidence_in_top_k"] is True


def test_a_relevancy_stops_frame_records_its_fewest_evidence_pixels_at_640x480():
    """The stop's tested frame, audited at 250 px and at any other rule."""
    need = max(4, round(MIN_EVIDENCE_PIXELS * 64 * 64 / (640 * 480)))
    frames = [_frame({7: need, 9: need}), _frame({7: 30, 9: 2}), _frame({9: 40})]
    watch = _watch([7, 9], frames)
    scale = 640 * 480 / (64 * 64)
    assert watch.fields([(1, 0.9)], stop_step=2)["evidence_stop_pixels"] == 2 * scale
    assert watch.fields([(1, 0.9)], stop_step=1)["evidence_stop_pixels"] == need * scale >= 250
    assert watch.fields([(1, 0.9)], stop_step=3)["evidence_stop_pixels"] == 0.0  # 7 not in view
    assert watch.fields([(1, 0.9)])["evidence_stop_pixels"] is None  # no relevancy stop


def test_never_seen_is_not_unknown():
    never = _watch([7], [_frame({}), _frame({3: 900})]).fields([(2, 0.4)])
    assert never == {"evidence_first_seen_step": None, "evidence_in_top_k": False,
                     "evidence_seen_steps": [], "evidence_stop_pixels": None}
    # No ground truth (a free question, HM-EQA, an existence question answered "no"): None.
    assert _watch([], [_frame({7: 900})]).fields([(1, 0.9)]) == dict.fromkeys(FIELDS)
    assert _watch(None, [_frame({7: 900})]).fields([(1, 0.9)]) == dict.fromkeys(FIELDS)
    # Frames without an instance buffer cannot tell.
    blind = _watch([7], [_frame({7: 900})])
    blind(StepRecord(2, (0.0, 0.0, 0.0), True), Observation(
        np.zeros((4, 4, 3), np.uint8), np.ones((4, 4), np.float32), np.eye(4), np.eye(3),
        Pose2D(0, 0, 0)), None)
    assert blind.fields([(1, 0.9)]) == dict.fromkeys(FIELDS)


@pytest.fixture(scope="module")
def house4(catalog):
    env = SyntheticEnv(generate_house(4, catalog, "builtin"), catalog, CameraSpec().scaled(320, 240))
    questions = synthetic_questions(env)
    yield Scene(env, "synthetic:4 (builtin)", questions), next(q for q in questions if q.id == "syn-4-10")
    env.close()


@needs_egl
def test_episode_json_records_when_the_evidence_was_in_view(house4, tmp_path):
    scene, q = house4
    desk = scene.env.house.object(q.evidence[0])
    room = scene.env.house.room(desk.room_id).name
    done = ask(q.question, scene, tmp_path, stack=Stack(grouping="rules", explore_scorer="vlm"),
               model=seeking_model(desk.category, room), relevancy=MentionScorer(desk.category, room),
               config=AgentConfig.of(max_steps=30, seed=1), report=False)  # seed 1 frames the desk
    record = json.loads(done.episode_json.read_text())
    # Rendered again from the recorded poses, after the episode: the same steps show the desk.
    shown = [s["step"] for s in record["per_step"]
             if evidence_visible(scene.env.observe(Pose2D(*s["pose"])).instance, q.evidence)]
    assert shown and record["evidence_seen_steps"] == shown
    assert record["evidence_first_seen_step"] == shown[0]
    retrieved = {r["step"] for r in record["retrieved"]}
    assert record["evidence_in_top_k"] == bool(retrieved & set(shown))
    assert record["oracle_steps"] == q.oracle_steps
    if record["stop_reason"] == "relevancy":  # the tested frame's pixels, rendered again
        last = record["per_step"][-1]
        tested = record["per_step"][(last["tested_step"] or last["step"]) - 1]
        frame = scene.env.observe(Pose2D(*tested["pose"])).instance
        assert record["evidence_stop_pixels"] == round(evidence_pixels(frame, q.evidence), 1)
    else:
        assert record["evidence_stop_pixels"] is None


@needs_egl
def test_a_question_of_ones_own_has_no_evidence_record(house4, tmp_path):
    scene, _ = house4
    done = ask("Is there a piano anywhere?", scene, tmp_path,
               stack=Stack(grouping="rules", explore_scorer="vlm"),
               model=seeking_model("piano", "hall"), relevancy=MentionScorer("piano"),
               config=AgentConfig.of(max_steps=3), report=False)
    record = json.loads(done.episode_json.read_text())
    assert all(k in record and record[k] is None for k in FIELDS)


@needs_egl
def test_eval_rows_carry_the_evidence_record_refused_moves_and_oracle_steps(tmp_path, monkeypatch):
    from efficienteqa import stack as stack_module
    from efficienteqa.datasets.synthetic import to_eval_question
    from efficienteqa.eval.methods import RunSpec
    from efficienteqa.eval.runner import run_eval

    with SyntheticEnv.from_seed(4, "builtin") as env:
        q = next(x for x in synthetic_questions(env) if x.id == "syn-4-10")
        desk = env.house.object(q.evidence[0])
        room = env.house.room(desk.room_id).name
    monkeypatch.setattr(stack_module, "build_chat_model",
                        lambda backend: seeking_model(desk.category, room))
    spec = RunSpec.of(method="frontier-only", dataset="synthetic-test", judge=None, assets="builtin",
                   stack=Stack(relevancy="overlap", grouping="rules"),
                   config=AgentConfig.of(max_steps=4))
    question = to_eval_question(q, "synthetic-test", "builtin")
    run_eval(spec, [question], tmp_path, prepare=False)
    row = json.loads((tmp_path / "episodes.jsonl").read_text().splitlines()[-1])
    assert row["status"] == "done", row.get("error")
    record = json.loads(next((tmp_path / "episodes").rglob("episode.json")).read_text())
    assert row["oracle_steps"] == q.oracle_steps
    for key in ("evidence_first_seen_step", "evidence_in_top_k", "evidence_stop_pixels",
                "refused_moves"):
        assert row[key] == record[key]
    assert isinstance(row["evidence_in_top_k"], bool) and isinstance(row["refused_moves"], int)
