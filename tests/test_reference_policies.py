"""The steering benchmark's reference policies (experiments/reference_policies.py, DESIGN 9
items 5-6) on one small built-in house: they reach the evidence, a random walk does not."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from conftest import needs_egl
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M, generate_house
from efficienteqa.envs.synthetic.oracle import STEP_M, annotate
from efficienteqa.envs.synthetic.questions import Question, evidence_visible
from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.scenes import synthetic_questions

pytestmark = needs_egl

# House 3 (built-in boxes, 9 rooms): the robot starts in the living room at one end of the
# hallway; the dining room is at the other end, 6 oracle steps away.
HOUSE = 3
FAR = "What is on the bookshelf in the dining room?"


@pytest.fixture(scope="module")
def ref():
    from experiments import reference_policies

    return reference_policies


@pytest.fixture(scope="module")
def house(catalog):
    """House 3 at 320 x 240 (the pixel thresholds scale with the image), its far question."""
    env = SyntheticEnv(generate_house(HOUSE, catalog, "builtin"), catalog,
                       CameraSpec().scaled(320, 240))
    question = next(q for q in synthetic_questions(env, oracle=False) if q.question == FAR)
    (question,) = annotate(env, [question])
    yield env, question, int(math.sqrt(env.floor_area_m2) * 3)
    env.close()


def random_walk(env: SyntheticEnv, q: Question, budget: int, seed: int) -> int | None:
    """The step rule with no policy: each step to a random floor point within one move (3 m of
    path), facing a random direction. The step of first sight, None if never."""
    rng = np.random.default_rng(seed)
    obs, _ = env.reset()
    for step in range(1, budget + 1):
        if evidence_visible(obs.instance, q.evidence):
            return step
        field_m = env.grid.distance_field((obs.pose.x, obs.pose.y), ROBOT_RADIUS_M)
        cells = np.argwhere(field_m <= STEP_M)
        x, y = env.grid.spec.cell_to_world(cells[rng.integers(len(cells))])
        obs, *_ = env.step(Pose2D(float(x), float(y), float(rng.uniform(-math.pi, math.pi))))
    return None


def test_target_room_policy_reaches_the_far_evidence_where_a_random_walk_does_not(ref, house):
    env, q, budget = house
    assert q.oracle_steps == 6
    bound = 2 * q.oracle_steps  # "knows the target room": within twice the oracle's steps
    ep = ref.run_policy(env, q, "target-room", budget)
    assert ep.stop == "seen" and ep.first_seen is not None and ep.first_seen <= bound
    # It went there by doors it saw, not through walls: every step is at most one move.
    xy = np.array([t[:2] for t in ep.trace])
    assert np.all(np.linalg.norm(np.diff(xy, axis=0), axis=1) <= STEP_M + 0.01)  # poses rounded to cm
    walks = [random_walk(env, q, budget, seed) for seed in range(3)]
    assert all(w is None or w > bound for w in walks), walks


def test_room_by_room_searches_rooms_and_is_slower_than_knowing_the_target(ref, house):
    env, q, budget = house
    target = ref.run_policy(env, q, "target-room", budget)
    rooms = ref.run_policy(env, q, "room-by-room", budget)
    assert rooms.first_seen is not None and target.first_seen < rooms.first_seen <= budget
    assert rooms.rooms_entered >= 5 and rooms.turns >= 2 * 4  # a look-around in each room
    # The dining room's bookshelf is first glimpsed, then walked up to: going closer is what
    # shows it, and without it the evidence is seen later or not at all.
    assert rooms.approaches >= 1 and rooms.trace[rooms.first_seen - 1][3] == "approach"
    far = ref.run_policy(env, q, "room-by-room-no-closer", budget)
    assert far.approaches == 0 and (far.first_seen is None or far.first_seen > rooms.first_seen)


def test_named_room_knows_only_the_room_the_question_names(ref, house):
    """The yardstick "knows the named room": where the question names the evidence's room it
    walks as target-room; a location question names no room, so it is not told where the
    evidence is (target-room is) and searches room by room."""
    env, q, budget = house
    named = ref.run_policy(env, q, "named-room", budget)
    assert named.trace == ref.run_policy(env, q, "target-room", budget).trace
    where = replace(q, question="Where is the bookshelf?", category="location")
    told = ref.run_policy(env, where, "target-room", budget)
    named = ref.run_policy(env, where, "named-room", budget)
    rooms = ref.run_policy(env, where, "room-by-room", budget)
    assert named.first_seen is not None and named.first_seen > 2 * told.first_seen
    assert named.trace == rooms.trace


def test_named_room_searches_on_room_by_room_when_the_named_room_is_empty(ref, house):
    """A question naming another room than the evidence's: the named room first (its
    viewpoints looked around at), then on to the other rooms, never back and forth."""
    env, q, budget = house
    bedroom = next(r.id for r in env.house.layout.rooms if r.name == "bedroom")
    wrong = replace(q, question="What is on the bookshelf in the bedroom?")
    ep = ref.run_policy(env, wrong, "named-room", budget)
    rooms = [env.house.layout.room_at(x, y) for x, y, *_ in ep.trace]
    ids = [r.id if r is not None else None for r in rooms]
    first = ids.index(bedroom)
    assert ids[:first].count(bedroom) == 0
    left = max(k for k, i in enumerate(ids) if i == bedroom)
    assert left > first + 4  # looked around at more than one viewpoint in the bedroom
    assert bedroom not in ids[left + 1:]  # never back into it
    assert ep.rooms_entered >= 5  # went on to other rooms
