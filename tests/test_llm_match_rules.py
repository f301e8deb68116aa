"""The clear cases an LLM-Match judge decides without its model (eval.llm_match_rules), and the
bounds on the grade it gives (eval.llm_match_bounds)."""

from __future__ import annotations

import pytest

from efficienteqa.eval.answer_words import question_state, stance, stem, words
from efficienteqa.eval.llm_match_rules import rule_score


def grade(question: str, reference: str, response: str) -> int | None:
    ruled = rule_score(question, reference, response)
    return None if ruled is None else ruled.score


def test_words_spell_out_contractions_and_stems_make_plurals_singular():
    assert words("It isn't on; there's none. I can't tell") == [
        "it", "is", "not", "on", "there", "is", "none", "i", "can", "not", "tell"]
    assert [stem(w) for w in ("towels", "boxes", "glasses", "glass", "yes", "batteries")] == [
        "towel", "box", "glass", "glass", "yes", "battery"]


@pytest.mark.parametrize("question, state", [
    ("Is the lamp on?", "on"), ("Is the TV in the bedroom left on?", "on"),
    ("Is the door to the garage closed?", "closed"), ("Is the fan turned off right now?", "off"),
    ("Is the kettle on the counter?", None),  # "on" the preposition
    ("Is the lamp on or off?", None), ("Is the door open or closed?", None),  # a choice
    ("Where is the lamp that is on?", None),  # not a yes/no question
])
def test_the_state_a_yes_no_question_asks_about(question, state):
    assert question_state(question) == state


@pytest.mark.parametrize("text, value, bare", [
    ("Yes, it is on", "yes", True), ("It's switched off.", "no", True), ("It is not on", "no", True),
    ("It isn't off", "yes", True), ("No, the lamp is off", "no", True), ("yes and no", None, True),
    ("Yes, in the kitchen", "yes", False), ("Nope", "no", True),
])
def test_stance_reads_state_words_against_the_question(text, value, bare):
    said = stance(text, "Is the lamp on?")
    assert (said.value, said.bare) == (value, bare)


@pytest.mark.parametrize("question, reference, response, expected", [
    # counts: same 5, one off 2, further off or none-against-some 1, two guesses 2 or 1
    ("How many chairs are at the table?", "Four", "4 chairs", 5),
    ("How many chairs are at the table?", "Four", "There are four chairs.", 5),
    ("How many chairs are at the table?", "Four", "three", 2),
    ("How many chairs are at the table?", "Four", "7", 1),
    ("How many chairs are at the table?", "None", "one", 1),
    ("How many chairs are at the table?", "None", "Zero, there are no chairs", 5),
    ("How many chairs are at the table?", "Four", "four or five", 2),
    ("How many chairs are at the table?", "Four", "two or three", 1),
    ("How many chairs are at the table?", "Four", "four, two on each side", None),  # more to it
    ("How many chairs are at the table?", "Four", "a few", None),
    # bare yes/no, with state words read against the question
    ("Is the fan turned off?", "It is off", "Yes, it's off", 5),
    ("Is the fan on or off?", "On", "off", 1),
    ("Is the window open or closed?", "Closed", "It is open", 1),
    ("Is the mug on the shelf?", "No", "Yes, it is on the shelf.", 1),  # the question's words
    ("Is the mug on the shelf?", "No", "Yes, on the table", None),  # a claim the model checks
    ("Is there a rug in the hall?", "None", "No, there is no rug in the hall", 5),
    # non-answers, guesses, no yes/no, echoes
    ("Is the oven on?", "Yes", "I can't tell from this view.", 1),
    ("Where is the mop?", "In the laundry room", "I am not sure, I cannot see it.", 1),
    ("Where is the mop?", "In the laundry room", "Maybe in the laundry room", None),
    ("Is the oven on?", "Yes", "Probably yes, but I am not certain.", None),
    ("Where is the mop?", "In the laundry room", "Either in the garage or the laundry room", 2),
    ("Where is the mop?", "In the laundry room", "Either in the garage or the attic", 1),
    ("Is the bike in the garage?", "No", "A blue bike", 1),
    ("Is the bike in the garage?", "Yes", "It is in the garage", None),  # restates: a yes
    ("Is the bike in the garage?", "Yes", "There is one next to the car", None),
    ("Where is the mop?", "In the laundry room", "A green plastic mop", 1),  # no place
    ("Where is the mop?", "In the laundry room", "laundry room", None),  # a place, said short
    ("Where is the mop?", "In the laundry room", "It is a mop for the floor", None),
    ("Where is the blue vase?", "On the shelf", "the blue vase", 1),
    ("Where is the blue vase?", "On the shelf", "a vase on the shelf", None),
    ("Which rug is in the hall?", "The red one", "a rug", 1),
])
def test_clear_cases(question, reference, response, expected):
    assert grade(question, reference, response) == expected


def test_every_ruled_grade_says_which_rule_decided():
    ruled = rule_score("How many cups?", "2", "three")
    assert ruled is not None and ruled.score == 2 and "count" in ruled.rule


def bounds(question: str, reference: str, response: str) -> tuple[int, int] | None:
    from efficienteqa.eval.llm_match_bounds import rule_bounds

    held = rule_bounds(question, reference, response)
    return None if held is None else (held.low, held.high)


@pytest.mark.parametrize("question, reference, response, expected", [
    # opposite yes/no with more to it than a bare word: wrong, whatever the model thinks
    ("Is there a box in the hall?", "No", "Yes, a cardboard box by the door", (1, 1)),
    ("Is the heater on?", "Yes, it is on", "It is switched off, the dial is at zero", (1, 1)),
    ("Is the lid open or closed?", "closed", "It's open, you can see inside", (1, 1)),
    # the same yes/no, said at length: at least 4
    ("Are the curtains drawn?", "No", "No, they're pulled back to the sides.", (4, 5)),
    ("Is the tap running?", "No", "No, it is off and dry.", (4, 5)),
    ("Is there a lamp?", "yes, in the kitchen", "Yes", (3, 5)),  # right, less specific
    ("Is there a lamp?", "yes, in the kitchen", "yes, in the bedroom", None),
    ("Is the tap running?", "No", "Maybe no, hard to tell", None),  # a hedge commits to nothing
    # the reference's words in the response
    ("What colour is the kettle?", "grey", "It's gray.", (5, 5)),
    ("What is on the sofa?", "a couch cushion", "A sofa cushion", (5, 5)),
    ("Which mat is at the door?", "The green one", "Dark green, with a pattern", (4, 5)),
    ("Where is the radio?", "on the shelf", "On the shelf above the sink", (4, 5)),
    ("How many mugs are on the tray?", "three", "There are 3 mugs on the tray, all white", (4, 5)),
    ("How many mugs are on the tray?", "three", "3 mugs, and 2 more on the shelf", None),
    ("Where is the radio?", "on the shelf", "Under the shelf", None),  # another place word
    ("Where is the radio?", "on the shelf", "Not on the shelf", None),  # negated
    ("What colour is the kettle?", "grey", "grey or black", None),  # alternatives
    ("What is the radio on?", "the radio shelf", "radio", None),  # only the question's words
    # another colour where the colour is the answer; a close shade is the model's to judge
    ("What colour is the kettle?", "grey", "Black", (1, 1)),
    ("Which cushion is on the chair?", "The yellow one", "The purple one", (1, 1)),
    ("Which room has the desk?", "the room with the red rug", "The room with the green rug", (1, 2)),
    ("Which room has the desk?", "the room with the red rug", "the room with the green plant",
     None),  # something else differs too: the model judges
    ("What colour is the kettle?", "blue", "Navy", None),
    ("Which cushion is on the chair?", "The red one", "A burgundy one", None),
    ("What colour is the kettle?", "grey", "A metal kettle", None),  # no colour word of its own
    ("Where is the lamp?", "on the green table", "on the table next to the red vase", None),
])
def test_rule_bounds_hold_the_model_to_what_the_words_make_certain(question, reference, response,
                                                                    expected):
    assert bounds(question, reference, response) == expected


def test_an_opposite_yes_no_is_not_wrong_when_an_accepted_answer_says_it():
    from efficienteqa.eval.llm_match_bounds import rule_bounds

    held = rule_bounds("Is the door open?", "no", "Yes, a little, by the hinge")
    assert held is not None and (held.low, held.high) == (1, 1) and "yes against no" in held.rule
    held = rule_bounds("Is the door open?", "no", "Yes, a little, by the hinge", ["yes"])
    assert held is not None and (held.low, held.high) == (4, 5)  # as the accepted bare yes
