import math

import numpy as np
import pytest

from conftest import needs_egl
from efficienteqa.envs.synthetic.questions import (
    CATEGORIES,
    evidence_visible,
    generate_questions,
    load_questions,
    save_questions,
)
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D
from efficienteqa.scenes import synthetic_questions


@pytest.fixture(scope="module")
def questions(env_seed3):
    return synthetic_questions(env_seed3)


@needs_egl
def test_every_category_is_asked(questions):
    assert {q.category for q in questions} >= set(CATEGORIES) - {"identification"}
    assert all(q.answer and q.question.endswith("?") for q in questions)


@needs_egl
def test_evidence_is_visible_from_the_oracle_pose(env_seed3, questions):
    for q in questions:
        if not q.evidence:
            assert q.category == "existence" and q.answer == "no"
            continue
        obs = env_seed3.observe(Pose2D(*q.oracle_pose))
        assert evidence_visible(obs.instance, q.evidence), q.question
        budget = int(math.sqrt(env_seed3.floor_area_m2) * 3)
        assert 1 <= q.oracle_steps <= budget


@needs_egl
def test_answers_match_the_house(env_seed3, questions):
    house = env_seed3.house
    for q in questions:
        objs = [house.object(e) for e in q.evidence]
        if q.category == "count":
            assert int(q.answer) == sum(o.category == "chair" for o in objs)
        elif q.category == "colour":
            assert objs[0].colour == q.answer and objs[0].colour_rgb is not None
        elif q.category == "location":
            assert house.room(objs[0].room_id).name in q.answer
        elif q.category == "state":
            assert (objs[0].state in ("on", "open")) == (q.answer == "yes")
        elif q.category == "existence" and q.answer == "yes":
            assert objs[0].category in q.question


def test_evidence_visibility_threshold():
    inst = np.full((120, 160), -1, np.int32)
    inst[:10, :10] = 5  # 100 px at 160x120 = 1600 px at 640x480
    assert evidence_visible(inst, [5])
    assert not evidence_visible(inst, [5, 6])
    assert not evidence_visible(inst, [])
    assert not evidence_visible(inst, [5], min_pixels=101)


def test_questions_are_deterministic_and_round_trip(catalog, tmp_path):
    from efficienteqa.envs.synthetic.generate import generate_house

    house = generate_house(6, catalog, "builtin")
    a = generate_questions(house, np.random.default_rng(1))
    b = generate_questions(house, np.random.default_rng(1))
    assert [q.to_json() for q in a] == [q.to_json() for q in b]
    path = tmp_path / "q.jsonl"
    save_questions(a, path)
    assert [q.to_json() for q in load_questions(path)] == [q.to_json() for q in a]
    path.write_text('{"id": 1}\n')
    with pytest.raises(EfficientEQAError, match="q.jsonl:1"):
        load_questions(path)
