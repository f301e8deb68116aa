"""Which rooms a question names (experiments.reference_policies.named_rooms): the room the
yardstick "knows the named room" is told, read from the question's words."""

from __future__ import annotations

from efficienteqa.envs.synthetic.layout import Room
from experiments.reference_policies import named_rooms

ROOMS = [Room(i, name.split()[-1], name, 0, 0, 1, 1) for i, name in enumerate(
    ("living room", "bedroom", "guest bedroom", "hallway", "dining room"))]


def test_names_in_the_question_as_whole_words_the_longer_name_first():
    assert named_rooms("Is the door between the guest bedroom and the hallway open?",
                       ROOMS) == {2, 3}
    assert named_rooms("Is there a bed in the bedroom?", ROOMS) == {1}
    assert named_rooms("What colour is the sofa in the Living Room?", ROOMS) == {0}


def test_a_question_naming_no_room_names_none():
    assert named_rooms("Where is the sofa?", ROOMS) == set()
    assert named_rooms("Is the bedroomlamp on?", ROOMS) == set()  # not inside a word
