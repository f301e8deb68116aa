"""The model's reading of the question (reading.reader), the match of its words by meaning
(reading.aliases) and how the agent gets both (AgentConfig.reading / matching): with stub
models and a stub embedder, so every verdict is deterministic."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import needs_egl
from efficienteqa.agent import PAPER_CONFIG, Agent, AgentConfig
from efficienteqa.models.base import Capabilities, Message
from efficienteqa.models.stub import StubChatModel
from efficienteqa.question import Target, parse_question
from efficienteqa.reading.aliases import AliasResolver
from efficienteqa.reading.reader import ModelReader, words_of
from efficienteqa.reading.target import TargetReading


def _reader(**said) -> tuple[ModelReader, StubChatModel]:
    reply = {"kind": "other", "object": None, "support": None, "rooms": [], "usual_rooms": [],
             **said}
    model = StubChatModel([f"Sure:\n```json\n{json.dumps(reply)}\n```"])
    return ModelReader(model), model


def test_the_models_fields_are_kept_when_they_are_words_of_the_question():
    reader, model = _reader(kind="existence", object="Towel", support="bathtub",
                            usual_rooms=["bathroom", "washroom", "attic", "guest bathroom"])
    t = reader.read("Is there a towel on the bathrub already? I wanna shower now.")
    # a typo-tolerant match ("bathtub" for "bathrub"); "washroom" is the bathroom, "attic" no room
    assert (t.kind, t.object, t.support) == ("existence", "towel", "bathtub")
    assert t.likely_rooms == ("bathroom", "guest bathroom") and t.rooms == ()
    assert len(model.requests) == 1 and reader.problems == []


def test_a_field_that_is_not_in_the_question_falls_back_to_the_rules():
    question = "Where id the small wooden stool?"
    reader, _ = _reader(kind="location", object="chair", support="kitchen")
    t = reader.read(question)
    assert t.object == parse_question(question).object == "small wooden stool"
    assert t.support is None  # "kitchen" is not in the question
    assert len(reader.problems) == 2


def test_a_room_is_no_support_and_named_rooms_stay_the_questions():
    reader, _ = _reader(kind="state", object="tv", support="guest bedroom",
                        rooms=["kitchen"], usual_rooms=["living room"])
    t = reader.read("Is the tv in the guest bedroom on?")
    assert (t.kind, t.object, t.support, t.rooms) == ("state", "tv", None, ("guest bedroom",))
    assert t.likely_rooms == ()  # a room is named: no prior


def test_a_things_name_is_cut_from_the_relations_the_model_keeps_with_it():
    reader, _ = _reader(kind="count", object="pillows", support="bed with green floral bedding")
    t = reader.read("How many pillows did I leave on the bed with green floral bedding?")
    assert (t.object, t.support) == ("pillow", "bed")  # "bed with ..." would name no bed


def test_an_unreadable_reply_is_the_rules_target():
    model = StubChatModel(["I think it is a stool."])
    reader = ModelReader(model)
    question = "How many stools are available at the kitchen island?"
    assert reader.read(question) == parse_question(question)
    assert reader.problems and "no JSON" in reader.problems[0]


def test_the_count_object_is_singular_and_identification_looks_at_its_support():
    reader, _ = _reader(kind="count", object="chairs", support="table")
    assert reader.read("How many chairs are around the table?").object == "chair"
    reader, _ = _reader(kind="identification", object="nightstand")
    t = reader.read("What is on the nightstand?")
    assert (t.object, t.support) == (None, "nightstand")


def test_the_schema_is_sent_where_the_server_takes_one():
    reader, model = _reader(kind="location", object="stool")
    reader.read("Where is the stool?")
    assert model.requests[0].json_schema is not None
    plain = StubChatModel(['{"kind": "location"}'], capabilities=Capabilities())
    ModelReader(plain).read("Where is the stool?")
    assert plain.requests[0].json_schema is None


def test_words_of_the_question():
    assert words_of("The Coffee Machines", "Where is the coffee machine?") == "coffee machines"
    assert words_of("bathtub", "a towel on the bathrub") == "bathtub"
    assert words_of("bath", "a towel on the bathrub") is None  # short words must match exactly
    assert words_of("sofa", "Where is the couch?") is None


# ----- matching by meaning ----------------------------------------------------------------
_VECTORS = {"couch": [1, 0, 0], "sofa": [0.9, 0.1, 0], "bedside table": [0, 1, 0.3],
            "nightstand": [0, 1, 0.8], "table": [0, 0.2, 1], "chair": [0.2, 0.2, 0.2],
            "dining table": [0.3, 0.3, 1]}


def _embed(texts):
    rows = np.array([_VECTORS.get(t, [0.1, 0.1, 0.1]) for t in texts], dtype=float)
    return rows / np.linalg.norm(rows, axis=1, keepdims=True)


def test_clear_pairs_are_aliases_and_unsure_ones_are_asked_in_one_call():
    model = StubChatModel(['1. "bedside table" and "nightstand": yes\n2 no\n3 no'])
    resolver = AliasResolver(_embed, model, clear=0.95, unsure=0.2)
    target = Target("location", "couch", "bedside table")
    aliases = resolver.aliases(target, ["Sofa", "nightstand", "table", "chair"])
    assert ("couch", "sofa") in aliases and ("bedside table", "nightstand") in aliases
    assert ("bedside table", "table") not in aliases  # asked, and the model said no
    assert len(model.requests) == 1
    with_aliases = Target("location", "couch", "bedside table", aliases=aliases)
    assert with_aliases.is_a("couch", "sofa") and not with_aliases.is_a("couch", "table")


def test_words_that_already_name_a_category_are_not_resolved():
    model = StubChatModel([])  # any call would fail the test
    resolver = AliasResolver(_embed, model)
    assert resolver.aliases(Target("count", "chair", "table"), ["chair", "table"]) == ()


def test_a_category_the_words_already_name_is_not_asked():
    model = StubChatModel(["1 yes"])
    resolver = AliasResolver(_embed, model, clear=0.99, unsure=0.2)
    aliases = resolver.aliases(Target("location", "bedside table"), ["table", "nightstand"])
    assert aliases == (("bedside table", "nightstand"),)
    assert '"table"' not in model.requests[0].messages[0].text  # a table by its words already


def test_words_that_name_a_category_take_no_alias_further_from_them_than_it():
    # "dining table" names a "table"; MiniLM put "chair" among its closest other
    # categories (0.50, "table" 0.68), the model said yes, and the support became a chair.
    model = StubChatModel(["1 yes\n2 yes\n3 yes"])
    resolver = AliasResolver(_embed, model, clear=0.9, unsure=0.2)
    assert resolver.aliases(Target("count", "chair", "dining table"),
                            ["table", "chair", "nightstand"]) == ()
    assert model.requests == []  # nothing closer than "table" to ask about
    # a category closer to the words than the one they name is still asked: "bedside table"
    # is nearer "nightstand" than "table"
    assert resolver.aliases(Target("location", "bedside table"), ["table", "nightstand"]) == \
        (("bedside table", "nightstand"),)


def test_without_a_model_only_the_clear_pairs_are_kept():
    resolver = AliasResolver(_embed, None, clear=0.95, unsure=0.2)
    aliases = resolver.aliases(Target("location", "couch", "bedside table"),
                               ["sofa", "nightstand"])
    assert aliases == (("couch", "sofa"),)


def test_an_unanswered_pair_is_no_alias():
    model = StubChatModel(["maybe"])
    resolver = AliasResolver(_embed, model, clear=0.99, unsure=0.2)
    assert resolver.aliases(Target("location", "bedside table"), ["nightstand"]) == ()
    assert resolver.problems


def test_a_slip_in_an_objects_name_is_read_against_the_vocabulary():
    from efficienteqa.reading.aliases import slip_aliases

    vocabulary = ["table", "foosball table", "table lamp", "lamp", "chair", "tv stand", "stool",
                  "clock", "cup"]
    got = slip_aliases(["tabel", "chiars", "tv stnad", "stoool", "dining tabel", "tabel lamp",
                        "couch", "chair", "pcu", "cloc"], vocabulary)
    assert got == {"tabel": "table", "chiars": "chair", "tv stnad": "tv stand",
                   "stoool": "stool", "dining tabel": "table", "tabel lamp": "table lamp",
                   "cloc": "clock"}  # none in three letters ("pcu"); a drop in five
    # a slip that fits two words of the vocabulary is read as neither
    assert slip_aliases(["stoo"], ["stool"]) == {"stoo": "stool"}
    assert slip_aliases(["stoo"], ["stool", "stoop"]) == {}


def test_the_resolver_mends_slips_without_embedding_them():
    embedded: list[str] = []

    def embed(texts):
        embedded.extend(texts)
        return _embed(texts)

    resolver = AliasResolver(embed, StubChatModel([]))  # any call would fail the test
    aliases = resolver.aliases(Target("count", "chiar", "tabel"), ["chair", "table"])
    assert aliases == (("chiar", "chair"), ("tabel", "table")) and embedded == []
    target = Target("count", "chiar", "tabel", aliases=aliases)
    assert target.is_a("chiar", "chair") and target.is_a("tabel", "table")


# ----- the agent's options ----------------------------------------------------------------
def test_the_reading_options_are_checked_and_the_paper_reads_by_rules():
    with pytest.raises(ValueError, match="reading"):
        AgentConfig.of(reading="guess")
    with pytest.raises(ValueError, match="matching"):
        AgentConfig.of(matching="sound")
    assert (PAPER_CONFIG.explore.reading, PAPER_CONFIG.explore.matching) == ("rules", "words")
    # the default: the rules' target, the model's likely rooms, words matched by meaning
    assert (AgentConfig().explore.reading, AgentConfig().explore.matching) == ("rules+rooms", "meaning")


def test_the_paper_configuration_builds_no_reading(monkeypatch):
    from efficienteqa.stack import build_reading

    assert build_reading(PAPER_CONFIG, None, None, None) is None  # type: ignore[arg-type]


def test_an_agent_asked_to_read_by_model_needs_the_reading():
    from agent_stubs import MentionScorer

    class Text:
        modality = "text"

    with pytest.raises(ValueError, match="reading"):
        Agent(Text(), None, MentionScorer("x"), None,  # type: ignore[arg-type]
              AgentConfig.of(reading="model"))


def test_rules_plus_rooms_keeps_the_rules_target_and_adds_the_models_rooms():
    reader, model = _reader(kind="existence", object="chair", usual_rooms=["bedroom"])
    reading = TargetReading("rules+rooms", "words", reader)
    question = "Where id the small wooden stool?"
    t = reading.target(question)
    assert t.object == "small wooden stool" and t.likely_rooms == ("bedroom",)
    calls = len(model.requests)
    named = reading.target("Is there a stool in the kitchen?")  # a named room: no prior needed
    assert named.likely_rooms == () and len(model.requests) == calls


@needs_egl
def test_an_episode_reads_its_question_once_and_records_the_target(env_seed3):
    from agent_stubs import averse_model
    from efficienteqa.stack import Stack, build_agent

    averse = averse_model("none", "none")
    reads: list[str] = []

    def reply(messages: list[Message]) -> str:
        if "Say what the robot must look for" in messages[-1].text:
            reads.append(messages[-1].text)
            return json.dumps({"kind": "location", "object": "stool", "support": None,
                               "rooms": [], "usual_rooms": ["kitchen", "dining room"]})
        return averse._reply(messages)

    model = StubChatModel(reply, name="reader-stub")
    config = AgentConfig.of(max_steps=2, reading="model")
    built = build_agent(env_seed3, Stack(grouping="rules", explore_scorer="direction-logit"),
                        config, "synthetic", model=model)
    result = built.agent.run(env_seed3, "Where id the stool?")
    assert len(reads) == 1
    assert result.target.object == "stool"
    assert result.target.likely_rooms == ("kitchen", "dining room")


def test_the_relevancy_can_read_the_question_in_the_perceptions_words():
    """``StopConfig.question_words`` "perceived": rooms by their canonical names, slips mended
    and the target's resolved phrases in the perception's words; the generator's own words
    (and a question with nothing to mend) stay as asked."""
    from dataclasses import replace

    from efficienteqa.question import parse_question, perceived_words

    q = "Is there a couch in the lounge?"
    target = replace(parse_question(q), aliases=(("couch", "sofa"),))
    assert perceived_words(q, target) == "is there a sofa in the living room?"
    assert perceived_words("Wher are the couches?", target) == "where are the sofas?"
    q = "Is there a sofa in the living room?"
    assert perceived_words(q, parse_question(q)) == q
    q = "What colour is the bed in the bedroom?"
    assert perceived_words(q, parse_question(q)) == q  # no spelling "mended"


def test_the_agent_scores_frames_against_the_question_in_the_words_it_is_told():
    from efficienteqa.agent import PAPER_CONFIG
    from efficienteqa.stop.rules import StopConfig

    assert StopConfig().question_words == "perceived"  # measured on the paraphrase split
    assert PAPER_CONFIG.stop.question_words == "asked"  # the paper's: the question as typed
    with pytest.raises(ValueError, match="question_words"):
        StopConfig(question_words="typed")
