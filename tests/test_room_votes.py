"""The pixel perception's room votes: a room named from what it holds, per region of the map,
afresh in every episode."""

from __future__ import annotations

import numpy as np
import pytest

from efficienteqa.perception.pixels import rooms
from efficienteqa.perception.pixels.backend import PixelPerception
from efficienteqa.perception.pixels.rooms import RoomPrior, RoomVotes, Seen, count_prior
from efficienteqa.perception.pixels.segment import PixelClasses

ROOMS = ("living room", "kitchen", "bedroom", "bathroom", "dining room", "office", "hallway")


def _square(x0: float, x1: float, y0: float, y1: float, step: float = 0.05) -> np.ndarray:
    xs, ys = np.meshgrid(np.arange(x0, x1, step), np.arange(y0, y1, step))
    return np.stack([xs.ravel(), ys.ravel()], 1)


def _seen(floor: np.ndarray, room: str, objects=(), walls=None) -> Seen:  # noqa: ANN001
    return Seen(floor, np.full(len(floor), ROOMS.index(room)),
                np.zeros((0, 2)) if walls is None else walls, np.zeros((0, 2)), list(objects))


@pytest.fixture(scope="module")
def prior() -> RoomPrior:
    return RoomPrior.load()  # the committed prior, counted over training houses' labels


def _counts() -> dict[str, list[int]]:
    """The committed prior's object counts (training houses' labels)."""
    import json

    return json.loads(rooms.PRIOR.read_text())["counts"]


def _blind_prior(a: str, b: str) -> RoomPrior:
    """The committed object counts, with a network that cannot tell room ``a``'s floor from
    ``b``'s (it calls each of them either, half the time) and tells every other floor right:
    the situation of wood floors (living room, dining room, office) and tiles (kitchen,
    bathroom) the room votes are for. The committed confusions are counted for the committed
    weights and change with them."""
    confusion = np.eye(len(ROOMS)) * 1000.0
    for row in (a, b):
        confusion[ROOMS.index(row), [ROOMS.index(a), ROOMS.index(b)]] = 500.0
    return RoomPrior.from_counts(ROOMS, _counts(), confusion)


def test_a_toilet_and_a_sink_name_a_living_room_floor_a_bathroom():
    """The frame's floor says "living room", but a toilet and a sink stand on its region."""
    votes = RoomVotes(ROOMS, _blind_prior("living room", "bathroom"))
    floor = _square(0.0, 2.0, 0.0, 2.0)
    bare = votes.add((0,), _seen(floor, "living room", [("sofa", (1.0, 1.0))]))
    assert bare.room_at(1.0, 1.0) == "living room"
    seen = votes.add((1,), _seen(floor, "living room", [("toilet", (0.3, 0.3)),
                                                        ("sink", (1.7, 0.3))]))
    assert seen.room_at(1.0, 1.0) == seen.room_at(0.1, 1.9) == "bathroom"
    assert bare.room_at(1.0, 1.0) == "living room"  # a frame's labels keep their answer


def test_a_floor_the_network_tells_apart_holds_against_objects():
    """The same toilet and sink on a floor the network never confuses with a bathroom's: the
    floor wins (FLOOR_WEIGHT readings against two objects)."""
    prior = _blind_prior("kitchen", "bathroom")
    objects = [("toilet", (0.3, 0.3)), ("sink", (1.7, 0.3))]
    room_map = RoomVotes(ROOMS, prior).add((0,), _seen(_square(0, 2, 0, 2), "hallway", objects))
    assert room_map.room_at(1.0, 1.0) == "hallway"


def test_a_wall_keeps_the_objects_vote_in_its_own_room():
    """Two tiled floors joined but for a wall line with a doorway-wide gap: the toilet names the
    left room, the stove the right one. Without the wall they are one region, one name."""
    prior = _blind_prior("kitchen", "bathroom")
    left, right = _square(0.0, 2.0, 0.0, 3.0), _square(2.2, 4.0, 0.0, 3.0)
    join = _square(2.0, 2.2, 1.0, 1.9)  # the doorway's floor
    wall = np.concatenate([_square(2.05, 2.15, 0.0, 1.0), _square(2.05, 2.15, 1.9, 3.0)])
    objects = [("toilet", (0.3, 0.3)), ("stove", (3.7, 0.3))]
    floor = np.concatenate([left, right, join])
    walled = RoomVotes(ROOMS, prior).add((0,), _seen(floor, "kitchen", objects, wall))
    assert (walled.room_at(1.0, 1.5), walled.room_at(3.0, 1.5)) == ("bathroom", "kitchen")
    open_plan = RoomVotes(ROOMS, prior).add((0,), _seen(floor, "kitchen", objects))
    assert open_plan.room_at(1.0, 1.5) == open_plan.room_at(3.0, 1.5)


def test_a_table_on_wall_cells_still_votes_for_the_room_around_it():
    """Pixels of a dining table taken for wall mark its own cells as bounds (seen on the
    agent's walks): the table still votes for the region around it (OBJECT_NEAR_M)."""
    prior = _blind_prior("living room", "dining room")
    floor = _square(0.0, 3.0, 0.0, 3.0)
    on_table = _square(1.3, 1.7, 1.3, 1.7)  # "wall" pixels where the table stands
    floor = floor[~((np.abs(floor - 1.5) < 0.35).all(1))]  # the table hides its floor
    seen = _seen(floor, "living room", [("table", (1.5, 1.5))], on_table)
    assert RoomVotes(ROOMS, prior).add((0,), seen).room_at(0.3, 0.3) == "dining room"
    saved = rooms.OBJECT_NEAR_M
    try:
        rooms.OBJECT_NEAR_M = 0.0  # the vote of its own cell only: none
        assert RoomVotes(ROOMS, prior).add((0,), seen).room_at(0.3, 0.3) == "living room"
    finally:
        rooms.OBJECT_NEAR_M = saved


def test_the_floor_outweighs_one_ambiguous_object():
    """A chair seen on a kitchen floor leaves it a kitchen: one object is weak evidence."""
    votes = RoomVotes(ROOMS, _blind_prior("kitchen", "bathroom"))
    room_map = votes.add((0,), _seen(_square(0, 2, 0, 2), "kitchen", [("chair", (1.0, 1.0))]))
    assert room_map.room_at(1.0, 1.0) == "kitchen"


def test_a_frame_read_twice_and_one_object_seen_twice_count_once(prior):
    votes = RoomVotes(ROOMS, prior)
    floor = _square(0.0, 2.0, 0.0, 2.0)
    votes.add((0,), _seen(floor, "living room", [("toilet", (1.0, 1.0))]))
    for key in ((0,), (1,)):  # the same frame again; the same toilet from another pose
        votes.add(key, _seen(floor, "living room", [("toilet", (1.1, 1.0))]))
    assert len(votes._objects) == 1
    assert float(votes._floor.sum()) == 2 * len(floor)


def test_the_prior_counts_labels_and_smooths_them():
    counts = count_prior([("toilet", "bathroom"), ("toilet", "bathroom"), ("sofa", "living room"),
                          ("door", "kitchen"), ("sofa", "garage")], ROOMS)
    assert counts == {"sofa": [1, 0, 0, 0, 0, 0, 0], "toilet": [0, 0, 0, 2, 0, 0, 0]}
    prior = RoomPrior.from_counts(ROOMS, counts, mix=0.1)
    p = np.exp(prior.log_given["toilet"])
    assert p.sum() == pytest.approx(1.0) and p.argmax() == ROOMS.index("bathroom")
    assert np.all(p > 0)  # smoothed: no room is ruled out by one category


def _frame_classes(floor_class: int, categories: tuple[str, ...]) -> PixelClasses:
    category = np.full((24, 32), floor_class, np.uint8)
    zeros = np.zeros_like(category)
    return PixelClasses(category, zeros, zeros, categories, ("grey",), ("on",),
                        np.ones(category.shape, np.float32))


def test_the_votes_start_afresh_each_episode(env_seed3):
    """What an episode saw names no floor in the next: ``reset`` (called by the agent as each
    episode starts) empties the votes, and the agent calls it."""
    from efficienteqa.agent import AgentConfig
    from efficienteqa.models.stub import StubChatModel
    from efficienteqa.stack import Stack, build_agent

    categories = ("void", "wall", "floor:kitchen", "floor:bedroom", "door")
    says = {"floor": 2}
    perception = PixelPerception(lambda rgb, depth: _frame_classes(says["floor"], categories),
                                 room_votes=True)
    obs = env_seed3.observe()
    pose = (obs.pose.x, obs.pose.y)
    assert perception.read(obs)[1].room_at(*pose) == "kitchen"
    says["floor"] = 3
    behind = env_seed3.observe(type(obs.pose)(obs.pose.x, obs.pose.y, obs.pose.yaw + 0.5))
    perception.read(behind)  # the same floor, now said to be a bedroom: the votes are mixed
    perception.reset()
    assert perception.read(obs)[1].room_at(*pose) == "bedroom"

    built = build_agent(env_seed3, Stack(grouping="rules", perception="semantic"),
                        AgentConfig.of(max_steps=1, gate="none"), "test",
                        model=StubChatModel(lambda m: "unknown"))
    calls = []
    perception.reset = lambda: calls.append(1)  # type: ignore[method-assign]
    built.agent.perception = perception
    for _ in range(2):
        built.agent.run(env_seed3, "What is in the kitchen?")
    assert len(calls) == 2


def test_the_stack_builds_the_pixel_perception_with_votes_and_others_without():
    """The agent's perception votes (and is reset each episode); one perception reading frames
    of many houses (``evaluate``) does not, unless asked."""
    from efficienteqa.stack import build_perception

    assert build_perception("pixels", None).room_votes  # type: ignore[attr-defined]
    assert not PixelPerception.load().room_votes


def test_the_constants_have_the_documented_sense():
    assert rooms.OBJECT_REACH_M >= rooms.OBJECT_MERGE_M > 0
    assert rooms.WALL_BAND_M[0] > 0  # floor pixels never bound a room


def test_with_perfect_classes_the_votes_name_the_rooms_the_sensor_does(env_seed3):
    """A walk's frames read with every pixel's class right: the voted map names the robot's
    room and the rooms in view as the label-reading sensor does (walls and doors split the
    rooms where the house does)."""
    from efficienteqa.geometry import Pose2D
    from efficienteqa.perception.pixels.frames import build_vocabulary, frame_labels
    from efficienteqa.perception.pixels.net import IGNORE
    from efficienteqa.perception.semantic import SemanticPerception

    vocab = build_vocabulary()
    start = env_seed3.house.start
    poses = [Pose2D(start.x, start.y, start.yaw + turn) for turn in (0.0, 2.0, -2.0, 1.0)]
    frames = [env_seed3.observe(pose) for pose in poses]
    perfect = []
    for obs in frames:
        labels = frame_labels(obs, env_seed3.house, vocab)
        keep = {k: np.where(labels[k] == IGNORE, 0, labels[k]) for k in ("category", "colour",
                                                                          "state")}
        perfect.append(PixelClasses(keep["category"], keep["colour"], keep["state"],
                                    vocab.categories, vocab.colours, vocab.states,
                                    np.ones(keep["category"].shape, np.float32)))
    said = iter(perfect)
    pixels = PixelPerception(lambda rgb, depth: next(said), room_votes=True)
    sensor = SemanticPerception(env_seed3.scene_labels())
    for obs in frames:
        a, b = pixels.describe(obs), sensor.describe(obs)
        assert a.room == b.room and a.rooms_in_view == b.rooms_in_view
