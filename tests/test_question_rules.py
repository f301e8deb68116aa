"""The rules' reading of questions as people ask them (HM-EQA's wording, the issue's examples):
typos, conversational openings and closings, several sentences, room words used as modifiers,
relations. The generator's own forms are in tests/test_seek.py."""

from __future__ import annotations

import pytest

from efficienteqa.question import Target, parse_question


@pytest.mark.parametrize("question,kind,obj,support,rooms", [
    # a typo that hides the question word
    ("Where id the small wooden stool?", "location", "small wooden stool", None, ()),
    ("Is there a towel on the bathrub already? I wanna shower now.", "existence", "towel",
     "bathtub", ()),
    # the object named in one sentence, asked about with a pronoun in the next
    ("I'm trying to remember where I placed the decorative bowl. It is on the kitchen island?",
     "location", "decorative bowl", "kitchen island", ()),
    ("I'm looking for my colorful handbag. Do you see it somewhere?", "existence",
     "colorful handbag", None, ()),
    ("I need to retrieve my pool cues. How many are on the pool table?", "count", "pool cue",
     "pool table", ()),
    # "which room has the X": a location question about X
    ("Which room has the large bookshelf?", "location", "large bookshelf", None, ()),
    ("How many stools are available at the kitchen island?", "count", "stool",
     "kitchen island", ()),
    # a room word before a thing says where it is
    ("Is the living room TV on?", "state", "tv", None, ("living room",)),
    ("I want to make sure I left the red kitchen mat in place.", "other", "red mat", None,
     ("kitchen",)),
    ("How many pieces of mat I put at the entrance door?", "count", "mat", "entrance door", ()),
    # an existence question with a support and a relation: the first place word's thing
    ("Is there a toy car on the table next to the sofa in the living room?", "existence",
     "toy car", "table", ("living room",)),
    ("Does the kitchen island have any fruit bowl on it?", "existence", "fruit bowl",
     "kitchen island", ()),
    # people doing things are no things
    ("Where did my husband leave the coffee machine in the kitchen?", "location",
     "coffee machine", None, ("kitchen",)),
    ("What did I leave on the bench at the foot of the bed?", "identification", None, "bench",
     ()),
    ("Is the walk-in closet door in the bedroom closed?", "state", "walk-in closet door", None,
     ("bedroom",)),
    ("I'm looking for my red and white checkered blanket.", "location",
     "red and white checkered blanket", None, ()),
    ("Where is the silver trash can?", "location", "silver trash can", None, ()),
    ("Is the air conditioning in the dining space still on?", "state", "air conditioning",
     None, ("dining room",)),
    ("How many bedside tables are there in the bedroom with the white bedding?", "count",
     "bedside table", None, ("bedroom",)),
    ("Which rug is at the shower next to the walk-in closet?", "state", "rug", "shower", ()),
])
def test_peoples_questions_parse_into_their_target(question, kind, obj, support, rooms):
    assert parse_question(question) == Target(kind, obj, support, rooms)


def test_words_that_only_look_like_verbs_stay_in_a_things_name():
    assert parse_question("Is the lamp next to the bed on?").support == "bed"  # not "-ed"
    assert parse_question("Where is the painting?").object == "painting"  # not "-ing"
    assert parse_question("Is the standing fan in the office?").object == "standing fan"


def test_a_question_that_names_nothing_has_an_empty_target():
    t = parse_question("What time is it now?")
    assert t.things == () and t.room is None


@pytest.mark.parametrize("question,kind,obj,support,rooms", [
    # chat-speak stays out of a thing's name
    ("How many chairs r around the dining table?", "count", "chair", "dining table", ()),
    ("Where did u leave ur keys?", "location", "keys", None, ()),
    # an opening before the question is no thing ("hey" was read as the object)
    ("Hey, what colour is the couch in the living room?", "colour", "couch", None,
     ("living room",)),
    ("Quick question before I go shopping: what colour is the refrigerator in the kitchen?",
     "colour", "refrigerator", None, ("kitchen",)),
    ("I'm setting up for dinner, how many chairs do we have around the table in the dining "
     "room?", "count", "chair", "table", ("dining room",)),
    ("I need somewhere to put the plates, is there a cabinet in the dining room?", "existence",
     "cabinet", None, ("dining room",)),
    ("I can't remember, do we have a ceiling lamp in the living room?", "existence",
     "ceiling lamp", None, ("living room",)),
    # a request around the question ("could you tell me ...", "do you know ...")
    ("Hey, could you count how many chairs are around the table in the dining room for me?",
     "count", "chair", "table", ("dining room",)),
    ("Hey, do you know which room the piano is in?", "location", "piano", None, ()),
    ("Could you go and see whether the door between the bedroom and the hallway is open?",
     "state", "door", None, ("bedroom", "hallway")),
    # the opening holds the thing the question points at with a pronoun
    ("The lamp by the bed, is it on?", "state", "lamp", "bed", ()),
    # a noun that ends in -ly is no adverb
    ("Is the telly in the spare bedroom switched on?", "state", "telly", None,
     ("guest bedroom",)),
])
def test_conversational_words_are_no_things(question, kind, obj, support, rooms):
    assert parse_question(question) == Target(kind, obj, support, rooms)


@pytest.mark.parametrize("question,kind,obj,support,rooms", [
    ("wat is on the desk in the ofice?", "identification", None, "desk", ("office",)),
    ("What colur is the bed in the bedrom?", "colour", "bed", None, ("bedroom",)),
    ("Is ther a table in the dinning room?", "existence", "table", None, ("dining room",)),
    ("Wher is the stool in the kitchn?", "location", "stool", None, ("kitchen",)),
    ("Is the door betwen the bathroom and the hallway opne?", "state", "door", None,
     ("bathroom", "hallway")),
    ("Whats on the shelf arund the corner of the halway?", "identification", None, "shelf",
     ("hallway",)),
])
def test_a_slip_in_a_question_word_or_a_room_word_is_read(question, kind, obj, support, rooms):
    assert parse_question(question) == Target(kind, obj, support, rooms)


def test_real_words_near_a_known_word_are_not_corrected():
    # one letter from "around", "closet", "garage", "hall", "open", "study", "spare", "lounge"
    assert parse_question("Is there a round table in the ofice?") == \
        Target("existence", "round table", None, ("office",))
    assert parse_question("Is there a garbage bag by the sturdy wall lamp?") == \
        Target("existence", "garbage bag", "sturdy wall lamp", ())
    assert parse_question("Is the oven open?") == Target("state", "oven", None, ())
    assert parse_question("Is the pen close to the spar?").rooms == ()
    assert parse_question("Where is the lunge mat?").object == "lunge mat"
