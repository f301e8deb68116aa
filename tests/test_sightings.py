"""Sightings read by the chat model (perception/sightings.py): the reply's parser, the projection
of boxes with depth, the call over the test server with images (readable, chatty, refused and
truncated replies), and the labels-backed test VLM against the semantic sensor's own sightings."""

from __future__ import annotations

import json

import numpy as np
import pytest

from efficienteqa.models.base import Capabilities
from efficienteqa.models.stub import StubChatModel
from efficienteqa.perception.base import Sightings
from efficienteqa.perception.image import ImagePerception
from efficienteqa.perception.semantic import SemanticPerception
from efficienteqa.perception.sightings import (
    ModelSightings,
    Region,
    SightingReply,
    box_mask,
    project,
    prompt,
    read_reply,
    schema,
)
from efficienteqa.question import Target, parse_question
from efficienteqa.stack import build_chat_model, build_gate, parse_vlm
from efficienteqa.stop.gate import SightingsGate
from labels_vlm import Errors, LabelsSightings
from test_semantic_perception import FakeLabels, make_frame
from vlm_server import Options, servers

COUNT = Target(kind="count", object="chair", support="table", rooms=("kitchen",))
SOFA = Target(kind="colour", object="sofa")


def test_a_readable_reply_gives_rooms_doorways_and_the_targets_things():
    reply = json.dumps({"room": "Kitchen", "doorways": [{"room": "hall", "box": [700, 0, 1000, 900]}],
                        "things": [{"name": "chairs", "box": [100, 400, 300, 800]},
                                   {"name": "the table", "box": [0.3, 0.4, 0.7, 0.9]}]})
    said, problems = read_reply(reply, COUNT)
    assert problems == []
    assert said == SightingReply("kitchen", (("hallway", Region((700, 0, 1000, 900))),),
                                 (("chair", Region((100, 400, 300, 800))),
                                  ("table", Region((300, 400, 700, 900)))))


@pytest.mark.parametrize("wrap", ["Sure! Here is what I see:\n```json\n{}\n```\nHope this helps.",
                                  "The view shows a kitchen. {}"])
def test_a_chatty_reply_is_read_as_far_as_its_json_goes(wrap):
    body = json.dumps({"room": "kitchen", "doorways": [], "things": [
        {"name": "chair", "box": [100, 400, 300, 800]}]})
    said, problems = read_reply(wrap.replace("{}", body), COUNT)
    assert said is not None and said.room == "kitchen" and [n for n, _ in said.things] == ["chair"]
    assert problems == []


@pytest.mark.parametrize("reply", ["I'm sorry, but I can't help with that.", "",
                                   '{"room": "kitchen", "things": [{"name": "chair", "box": [1'])
def test_a_refused_or_truncated_reply_is_a_problem_and_no_sighting(reply):
    said, problems = read_reply(reply, COUNT)
    assert said is None
    assert len(problems) == 1 and problems[0].startswith("no JSON object")


def test_what_cannot_be_used_is_dropped_and_said():
    reply = json.dumps({"room": "spaceship", "doorways": "hallway", "things": [
        {"name": "lamp", "box": [0, 0, 10, 10]}, {"name": "chair", "box": [1, 2, 3]},
        {"name": "chair", "box": [500, 500, 500, 900]}, {"name": "table", "box": ["a", 1, 2, 3]},
        "chair", {"name": "chair", "box": [-50, 100, 400, 2000]}]})
    said, problems = read_reply(reply, COUNT)
    assert said is not None and said.room is None and said.doorways == ()
    assert said.things == (("chair", Region((0, 100, 400, 1000))),)  # clamped to the frame
    assert problems == ["room 'spaceship' unknown", "doorways is no list",
                        "1 of the things are no objects", "thing 'lamp' is not the target's",
                        "box [1, 2, 3] is not four numbers", "box [500, 500, 500, 900] is empty",
                        "box ['a', 1, 2, 3] is not four numbers"]


def test_a_text_view_names_listed_items_only():
    reply = json.dumps({"room": "kitchen", "doorways": [{"room": "hallway"}], "things": [
        {"name": "chair", "item": 2}, {"name": "chair", "item": 9}, {"name": "table", "item": True}]})
    said, problems = read_reply(reply, COUNT, items=3)
    assert said is not None and said.things == (("chair", Region(items=(2,))),)
    assert said.doorways == (("hallway", Region()),)
    assert problems == ["item 9 is not listed", "item True is not listed"]


def test_the_prompt_and_schema_say_what_the_reply_needs():
    text = prompt("How many chairs are around the table in the kitchen?", COUNT,
                  "The view is the attached image.", images=True)
    assert 'Things to look for: "chair", "table"' in text and "thousandths" in text
    assert text.index("Example:") < text.index("Question:") < text.index("The view is")
    other = prompt("Is there a lamp?", SOFA, "The view is the attached image.", images=True)
    fixed = text[:text.index("Question:")]
    assert other.startswith(fixed)  # the instructions are the same for every call
    assert "(living room, kitchen, dining room" in text and "Question: How many chairs" in text
    assert schema(True)["properties"]["things"]["items"]["required"] == ["name", "box"]
    assert schema(False)["properties"]["things"]["items"]["required"] == ["name", "item"]


def test_a_box_is_projected_onto_the_thing_not_the_wall_behind_it():
    obs = make_frame()  # a sofa at depth 3 in rows 10-20, cols 5-14; a wall at 4 m behind
    truth = SemanticPerception(FakeLabels()).sightings(obs, SOFA)
    [sofa] = truth.things
    h, w = obs.depth_m.shape
    box = (2 * 1000 / w, 8 * 1000 / h, 17 * 1000 / w, 23 * 1000 / h)  # a loose box, wall inside
    seen = project(SightingReply("kitchen", (), (("sofa", Region(box)),)), obs)
    [thing] = seen.things
    assert np.hypot(thing.xy[0] - sofa.xy[0], thing.xy[1] - sofa.xy[1]) < 0.3
    assert thing.category == "sofa" and thing.room == "kitchen" and not thing.cut
    assert set(seen.floor) == {"kitchen"} and len(seen.floor["kitchen"]) > 0
    assert np.all(seen.floor["kitchen"][:, 0] > obs.pose.x)  # the floor ahead of the camera


def test_a_doorway_box_takes_its_floor_and_an_edge_box_is_cut():
    obs = make_frame()
    h, w = obs.depth_m.shape
    far = (0, 30 * 1000 / h, 1000, 35 * 1000 / h)  # floor rows 30-34: beyond x = 4
    seen = project(SightingReply("kitchen", (("hallway", Region(far)),),
                                 (("sofa", Region((0, 200, 300, 450))),)), obs)
    assert np.all(seen.floor["hallway"][:, 0] > 4.0 - 0.2)
    assert np.all(seen.floor["kitchen"][:, 0] < 4.0 + 0.2)
    assert seen.things[0].cut
    assert box_mask((0, 0, 1000, 1000), (h, w)).all()


class _Server:
    def __init__(self, start, options):
        self.server = start(options)
        self.model = build_chat_model(parse_vlm(f"openai:test-vlm@{self.server.base_url}",
                                                images=True, cache=False))


@pytest.fixture
def vlm(tmp_path, monkeypatch):
    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    with servers() as start:
        yield lambda **fields: _Server(start, Options(**fields))


QUESTION = "How many chairs are around the table in the kitchen?"


@pytest.mark.parametrize("style", ["exact", "json", "preamble", "reasoning", "markdown"])
def test_the_call_over_a_server_with_images_gives_sightings(vlm, style):
    s = vlm(style=style, json_schema="reject")
    perception = ModelSightings(ImagePerception(), s.model)
    perception.ask_about(QUESTION)
    obs = make_frame()
    seen = perception.sightings(obs, COUNT)
    assert perception.sightings(obs, COUNT) is seen  # one call per frame, read by two users
    [request] = [r for r in s.server.requests if r.kind == "sightings"]
    assert request.images == 1 and not s.server.image_errors
    assert QUESTION in json.dumps(request.body)
    assert perception.problems == []
    assert seen.floor and all(len(xy) for xy in seen.floor.values())


def test_a_server_with_json_schema_gets_the_schema(vlm):
    s = vlm()
    perception = ModelSightings(ImagePerception(), s.model)
    seen = perception.sightings(make_frame(), COUNT)
    [request] = [r for r in s.server.requests if r.kind == "sightings"]
    assert request.body["response_format"]["type"] == "json_schema"
    assert seen.floor and perception.problems == []


def test_a_refusal_over_a_server_is_a_problem_not_a_crash(vlm):
    s = vlm(style="refuse", json_schema="reject")
    perception = ModelSightings(ImagePerception(), s.model)
    assert perception.sightings(make_frame(), COUNT) == Sightings({})
    assert perception.problems == ["no JSON object in the sighting reply \"I'm sorry, but I "
                                   "can't help with that.\": no sighting"]


def test_a_reply_cut_at_max_tokens_says_so(vlm):
    s = vlm(cut=True, json_schema="reject")
    perception = ModelSightings(ImagePerception(), s.model, max_tokens=5)
    assert perception.sightings(make_frame(), COUNT) == Sightings({})
    [problem] = perception.problems
    assert problem.startswith("no JSON object") and problem.endswith("(cut at 5 tokens)")


def test_a_question_without_a_target_costs_no_call():
    model = StubChatModel([], capabilities=Capabilities(images=True))
    perception = ModelSightings(ImagePerception(), model)
    assert perception.sightings(make_frame(), parse_question("What is going on?")) == Sightings({})
    assert model.usage.calls == 0


def test_the_text_view_numbers_the_description_and_keeps_the_named_rooms():
    base = SemanticPerception(FakeLabels())
    obs = make_frame()
    d = base.describe(obs)
    chair = next(n for n, o in enumerate(d.objects, 1) if o.label.category == "chair")

    reply = json.dumps({"room": "kitchen", "doorways": [],
                        "things": [{"name": "chair", "item": chair}]})
    model = StubChatModel([reply])
    perception = ModelSightings(base, model)
    seen = perception.sightings(obs, COUNT)
    said = model.requests[-1].messages[-1].text
    assert f"{chair}. " in said and "You are in the kitchen." in said
    own = base.sightings(obs, COUNT)
    assert set(seen.floor) == {"kitchen"} and set(own.floor) == {"kitchen", "hallway"}
    [thing] = seen.things
    assert thing.category == "chair"
    assert min(np.hypot(thing.xy[0] - t.xy[0], thing.xy[1] - t.xy[1]) for t in own.things) < 1e-6


def test_the_labels_vlm_without_errors_places_things_as_the_semantic_sensor():
    base = SemanticPerception(FakeLabels())
    obs = make_frame()
    exact = LabelsSightings(base, FakeLabels())
    own = base.sightings(obs, COUNT)
    seen = exact.sightings(obs, COUNT)
    assert sorted(t.category for t in seen.things) == sorted(t.category for t in own.things)
    for t in seen.things:
        assert min(np.hypot(t.xy[0] - o.xy[0], t.xy[1] - o.xy[1]) for o in own.things
                   if o.category == t.category) < 0.35
    missing = LabelsSightings(base, FakeLabels(), Errors(miss=1.0, wrong_room=1.0))
    spoiled = missing.sightings(obs, COUNT)
    assert spoiled.things == () and "kitchen" not in spoiled.floor


def test_the_sightings_gate_reads_the_models_sightings():
    obs = make_frame()
    perception = LabelsSightings(SemanticPerception(FakeLabels()), FakeLabels())
    stub = StubChatModel([], capabilities=Capabilities(images=True))
    gate = build_gate("auto", ModelSightings(ImagePerception(), stub), stub)
    assert isinstance(gate, SightingsGate)
    gate = SightingsGate(perception)
    assert gate.check("What colour is the sofa?", SOFA, obs, obs.rgb).ok
    bicycle = Target(kind="colour", object="bicycle")
    assert not gate.check("What colour is the bicycle?", bicycle, obs, obs.rgb).ok
    blind = SightingsGate(LabelsSightings(SemanticPerception(FakeLabels()), FakeLabels(),
                                          Errors(miss=1.0)))
    assert not blind.check("What colour is the sofa?", SOFA, obs, obs.rgb).ok


def test_a_sightings_source_that_cannot_act_is_refused_in_one_line():
    from efficienteqa.errors import EfficientEQAError
    from efficienteqa.stack import Stack, check_stack

    with pytest.raises(EfficientEQAError, match="unknown sightings source 'labels'"):
        check_stack(Stack(sightings="labels"))
    with pytest.raises(EfficientEQAError, match="rgb perception gives no sightings of its own") \
            as raised:
        check_stack(Stack(perception="rgb", relevancy="vlm-match", sightings="perception"))
    assert "--backends.sightings model" in str(raised.value)


def test_the_cli_takes_sightings_from_the_command_line_and_a_config_file(tmp_path):
    from efficienteqa.config.presets import build_stack, load_config

    config = tmp_path / "c.toml"
    config.write_text('sightings = "model"\n')
    assert build_stack({"sightings": "model"}).sightings == "model"
    assert load_config(config)["backends.sightings"] == "model"


def test_a_run_recorded_before_the_sightings_source_reads_as_what_it_ran_with():
    from efficienteqa.eval.records import upgrade

    semantic = upgrade({"format": 2, "stack": {"perception": "semantic"}})
    assert semantic["stack"]["sightings"] == "auto"  # the perception's own, as "auto" is now
    rgb = upgrade({"format": 2, "stack": {"perception": "rgb"}})
    assert "sightings" not in rgb["stack"]  # it had none: no run of today resumes it


def test_a_vlms_boxes_fill_the_instance_map_and_the_count_gate_reads_it():
    """The things the model boxes become points with the frame's depth (``project``) and go to
    the episode's instance map: two views of the same two chairs are two chairs, and the
    sightings gate counts the group around the table from the map."""
    obs = make_frame()  # two chairs side by side in cols 40-45 at 2.5 m; "a table": the lamp's
    h, w = obs.depth_m.shape

    def box(c0, c1):
        return [c0 * 1000 / w, 10 * 1000 / h, c1 * 1000 / w, 21 * 1000 / h]

    reply = json.dumps({"room": "kitchen", "doorways": [], "things": [
        {"name": "table", "box": box(30, 36)}, {"name": "chair", "box": box(40, 43)},
        {"name": "chair", "box": box(43, 46)}]})
    stub = StubChatModel([reply, reply], capabilities=Capabilities(images=True))
    perception = ModelSightings(ImagePerception(), stub)
    gate = SightingsGate(perception)
    q = "How many chairs are around the table in the kitchen?"
    verdicts = [gate.check(q, COUNT, obs, obs.rgb) for obs in (make_frame(), make_frame())]
    assert [v.why for v in verdicts] == ["2 chair around the whole table"] * 2
    assert all(v.final for v in verdicts) and len(stub.requests) == 2
    chairs = [i for i in perception.instances.instances() if i.category == "chair"]
    assert len(chairs) == 2 and all(i.views == 2 for i in chairs)
    assert len(perception.instances) == 3
    perception.reset()
    assert len(perception.instances) == 0


def test_a_door_in_view_is_sighted_where_it_stands_never_with_the_rooms_its_label_joins():
    from dataclasses import replace

    from efficienteqa.envs.base import DoorSides, ObjectLabel
    from test_semantic_perception import LABELS

    class WithDoor(FakeLabels):
        def label(self, instance_id):
            if instance_id == 13:
                return ObjectLabel("door", "white", "open", "kitchen",
                                   DoorSides(("kitchen", "office"), 4.5, 1.0, (-1.0, 0.0)))
            return LABELS.get(instance_id)

    obs = make_frame()
    instance, depth = obs.instance.copy(), obs.depth_m.copy()
    instance[10:30, 20:28], depth[10:30, 20:28] = 13, 3.5
    obs = replace(obs, instance=instance, depth_m=depth)
    for target in (SOFA, Target()):  # whatever the question, doors are sighted
        seen = SemanticPerception(WithDoor()).sightings(obs, target)
        [door] = seen.doors
        assert door.category == "door" and door.room is None  # the label's sides unread
        assert abs(door.xy[0] - (obs.pose.x + 3.5)) < 0.3
        assert [t.category for t in seen.things] == (["sofa"] if target == SOFA else [])


def test_a_doorway_box_is_a_door_with_the_room_seen_through_it():
    obs = make_frame()  # the wall at 4 m, rows 10-29
    h, w = obs.depth_m.shape
    box = (20 * 1000 / w, 10 * 1000 / h, 28 * 1000 / w, 34 * 1000 / h)
    seen = project(SightingReply("kitchen", (("hallway", Region(box)),), ()), obs)
    [door] = seen.doors
    assert door.room == "hallway" and abs(door.xy[0] - (obs.pose.x + 4.0)) < 0.3
    assert not project(SightingReply("kitchen", (("hallway", Region()),), ()), obs).doors
