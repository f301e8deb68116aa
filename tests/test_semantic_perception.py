"""Semantic-sensor perception: a hand-made frame with known objects, then a rendered house.

The hand-made camera: 64x48, 90 deg HFOV (fx = fy = 32, principal point (32, 24)), 1 m high,
level, at (1, 1) looking along +x. A level camera sees floor at depth 32/(v + 0.5 - 24) on row v,
so floor rows 30-34 lie beyond x = 4 (the fake "hallway") and rows 35-47 before it ("kitchen").
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import needs_egl
from efficienteqa.envs.base import DoorSides, ObjectLabel
from efficienteqa.envs.synthetic.colours import PALETTE
from efficienteqa.envs.synthetic.labels import HouseLabels
from efficienteqa.explore.prompting import project_floor_points
from efficienteqa.geometry import CameraSpec, Pose2D, camera_to_world
from efficienteqa.observation import Observation, PromptPoint
from efficienteqa.perception.semantic import (
    MAX_OBJECTS,
    SemanticPerception,
    describe_directions,
    describe_frame,
)
from efficienteqa.perception.visible import NoiseConfig, bearing_words, scaled_min_pixels

CAMERA = CameraSpec(width=64, height=48, hfov_deg=90.0, height_m=1.0, pitch_deg=0.0)
POSE = Pose2D(1.0, 1.0, 0.0)
LABELS = {
    5: ObjectLabel("sofa", "red", None, "hallway"),
    7: ObjectLabel("lamp", "white", "on", "kitchen"),
    9: ObjectLabel("cup", "blue", None, "kitchen"),
    11: ObjectLabel("chair", "brown", None, "kitchen"),
    12: ObjectLabel("chair", "brown", None, "kitchen"),
}


class FakeLabels:
    def label(self, instance_id: int) -> ObjectLabel | None:
        return LABELS.get(instance_id)

    def room_at(self, x: float, y: float) -> str | None:
        return "kitchen" if x < 4.0 else "hallway"


def make_frame() -> Observation:
    h, w = CAMERA.height, CAMERA.width
    instance = np.full((h, w), -1, np.int32)  # rows 0-9: nothing (depth 0)
    depth = np.zeros((h, w), np.float32)
    instance[10:30], depth[10:30] = 0, 4.0  # a wall, never floor (z > 0.3 m)
    rows = np.arange(30, h)
    instance[30:], depth[30:] = 0, (32.0 / (rows + 0.5 - 24.0))[:, None]  # floor
    instance[10:21, 5:15], depth[10:21, 5:15] = 5, 3.0  # sofa, left
    depth[10:12, 5:15] = 9.0  # a few far pixels: the median ignores them
    instance[10:21, 30:36], depth[10:21, 30:36] = 7, 2.0  # lamp, ahead
    instance[10:21, 40:43], depth[10:21, 40:43] = 11, 2.5  # two chairs, slightly right
    instance[10:21, 43:46], depth[10:21, 43:46] = 12, 2.5
    instance[25:27, 50:52], depth[25:27, 50:52] = 9, 1.2  # a cup of 4 pixels
    return Observation(rgb=np.zeros((h, w, 3), np.uint8), depth_m=depth,
                       cam_to_world=camera_to_world(POSE, CAMERA), intrinsics=CAMERA.intrinsics,
                       pose=POSE, instance=instance)


def test_frame_text_is_exact():
    d = describe_frame(make_frame(), FakeLabels(), min_pixels=10)
    assert d.text == (
        "You are in the kitchen. Visible: a white lamp (on) ahead, 2.0 m; "
        "two brown chairs slightly right, 2.5 m; "
        "a red sofa on the left, 3.0 m, in the hallway. Through a doorway: the hallway.")
    assert d.room == "kitchen" and d.rooms_through_doorways == ("hallway",)
    assert [o.instance_id for o in d.objects] == [7, 11, 12, 5]
    sofa = d.objects[-1]
    assert sofa.pixels == 110 and sofa.centroid_px == pytest.approx((10.0, 15.5))
    assert sofa.bearing_deg == pytest.approx(np.degrees(np.arctan(22 / 32)))


def test_small_objects_are_left_out_and_the_threshold_scales():
    assert 9 not in [o.instance_id for o in describe_frame(make_frame(), FakeLabels(), 10).objects]
    d = describe_frame(make_frame(), FakeLabels(), min_pixels=4)
    assert d.objects[0].instance_id == 9 and "a blue cup on the right, 1.2 m" in d.text
    assert scaled_min_pixels(480, 640) == 150 and scaled_min_pixels(120, 160) == 9
    assert scaled_min_pixels(48, 64) == 2


def test_max_objects_keeps_the_nearest_entries_and_never_cuts_a_group():
    d = describe_frame(make_frame(), FakeLabels(), min_pixels=10, max_objects=2)
    assert [o.instance_id for o in d.objects] == [7, 11, 12]  # the lamp, then both chairs
    assert d.text.endswith("two brown chairs slightly right, 2.5 m. Through a doorway: the hallway.")


def test_identical_objects_are_counted_with_their_bearing_span_and_distance_range():
    obs = make_frame()
    obs.instance[10:21, 5:15] = 14  # a third brown chair where the sofa was, on the left, 3.0 m
    obs.instance[22:24, 60:62] = 13  # and one in the hallway, on the right, 4.0 m
    extra = {13: ObjectLabel("chair", "brown", None, "hallway"),
             14: ObjectLabel("chair", "brown", None, "kitchen")}
    LABELS.update(extra)
    try:
        d = describe_frame(obs, FakeLabels(), min_pixels=4)
    finally:
        for i in extra:
            del LABELS[i]
    assert d.text == (
        "You are in the kitchen. Visible: a blue cup on the right, 1.2 m; a white lamp (on) "
        "ahead, 2.0 m; three brown chairs on the left to slightly right, 2.5-3.0 m; a brown chair "
        "on the right, 4.0 m, in the hallway. Through a doorway: the hallway.")
    assert [o.instance_id for o in d.objects] == [9, 7, 11, 12, 14, 13]  # still one by one


def test_a_stack_seen_in_the_frame_is_described_as_standing_on_its_support():
    # a box on the floor 2 m ahead (its front face up to z = 0.41 m on rows 33-39; a level
    # camera 1 m high sees z = 1 - (v + 0.5 - 24) / 16 there) and a cup on top (rows 30-32)
    obs = make_frame()
    obs.instance[33:40, 20:28], obs.depth_m[33:40, 20:28] = 30, 2.0
    obs.instance[30:33, 22:26], obs.depth_m[30:33, 22:26] = 31, 2.0
    extra = {30: ObjectLabel("box", "grey", None, "kitchen"), 31: LABELS[9]}
    LABELS.update(extra)
    try:
        d = describe_frame(obs, FakeLabels(), min_pixels=4)
        obs.instance[33:40, 20:28] = 0  # without the box in the frame the cup stands on nothing
        alone = describe_frame(obs, FakeLabels(), min_pixels=4)
    finally:
        for i in extra:
            del LABELS[i]
    assert ("; a grey box slightly left, 2.0 m, with a blue cup on it; a blue cup on the grey "
            "box, slightly left, 2.0 m;") in d.text  # the relation both ways round
    assert {o.instance_id: o.on for o in d.objects if o.instance_id in extra} == {
        30: None, 31: "the grey box"}  # the box's bottom is at the floor
    assert {o.instance_id: o.carries for o in d.objects if o.instance_id in extra} == {
        30: "a blue cup", 31: None}
    assert all(o.on is None for o in alone.objects)
    assert "two blue cups slightly left to on the right, 1.2-2.0 m" in alone.text


def test_bearing_words():
    assert [bearing_words(a) for a in (0.0, 9.9, -15.0, 25.0, 45.0, -59.0)] == [
        "ahead", "ahead", "slightly right", "slightly left", "on the left", "on the right"]


def test_nothing_visible_and_no_room():
    obs = make_frame()
    obs.instance[obs.instance > 0] = 0
    d = describe_frame(obs, FakeLabels(), min_pixels=10)
    assert "Visible: nothing but walls and floor." in d.text and d.objects == ()


def _prompt(letter: str, xy: tuple[float, float]) -> PromptPoint:
    obs = make_frame()
    pixel, _ = project_floor_points(np.array([xy]), obs.cam_to_world, obs.intrinsics)
    return PromptPoint(letter, xy, (float(pixel[0, 0]), float(pixel[0, 1])))


def test_directions_name_the_objects_near_each_point():
    prompts = [_prompt("A", (2.5, 1.0)), _prompt("B", (4.5, 3.0))]
    out = describe_directions(make_frame(), prompts, FakeLabels(), min_pixels=10)
    assert out == {
        "A": "in the kitchen, 1.5 m away; a white lamp (on), two brown chairs.",
        "B": "towards the hallway, floor of the kitchen in view, 4.0 m away; a red sofa.",
    }


def test_directions_with_nothing_near():
    # (2, -3) lies outside the 90 deg view: no floor of its room (the kitchen) near it is seen
    out = describe_directions(make_frame(), [_prompt("C", (2.0, -3.0))], FakeLabels(),
                              radius_m=0.5, min_pixels=10)
    assert out["C"] == "4.1 m away; no objects seen there."


def test_a_direction_names_its_room_only_where_that_floor_is_seen():
    prompts = [_prompt("A", (2.5, 1.0)), _prompt("B", (4.5, 3.0))]
    obs = make_frame()
    obs.depth_m[30:35], obs.instance[30:35] = 0.0, -1  # the hallway's floor is not seen
    out = describe_directions(obs, prompts, FakeLabels(), min_pixels=10)
    assert out == {"A": "in the kitchen, 1.5 m away; a white lamp (on), two brown chairs.",
                   "B": "floor of the kitchen in view, 4.0 m away; a red sofa."}


def test_noise_drops_everything_at_rate_one():
    d = describe_frame(make_frame(), FakeLabels(), min_pixels=10, noise=NoiseConfig(miss_rate=1.0))
    assert d.objects == () and "nothing but walls and floor" in d.text


def test_noise_recolours_everything_deterministically():
    noise = NoiseConfig(wrong_colour_rate=1.0, seed=4)
    a = describe_frame(make_frame(), FakeLabels(), min_pixels=10, noise=noise)
    b = describe_frame(make_frame(), FakeLabels(), min_pixels=10, noise=noise)
    assert a == b and len(a.objects) == 4
    for o in a.objects:
        assert o.label.colour in PALETTE and o.label.colour != LABELS[o.instance_id].colour
        assert o.label.category == LABELS[o.instance_id].category
    clean = describe_frame(make_frame(), FakeLabels(), min_pixels=10, noise=NoiseConfig())
    assert clean == describe_frame(make_frame(), FakeLabels(), min_pixels=10)
    with pytest.raises(ValueError):
        NoiseConfig(miss_rate=1.5)


def test_frame_without_instance_buffer_is_refused():
    obs = make_frame()
    obs.instance = None
    with pytest.raises(ValueError, match="instance buffer"):
        describe_frame(obs, FakeLabels())


@needs_egl
def test_synthetic_house_descriptions_match_the_instance_buffer():
    from efficienteqa.envs.synthetic.env import SyntheticEnv

    with SyntheticEnv.from_seed(3, assets="builtin", camera=CameraSpec().scaled(160, 120)) as env:
        labels = HouseLabels(env.house)
        obs, _ = env.reset()
        for turn in range(4):
            obs = env.observe(Pose2D(obs.pose.x, obs.pose.y, env.house.start.yaw + turn * 1.6))
            d = describe_frame(obs, labels)
            assert d.room in (None, env.house.layout.room_at(obs.pose.x, obs.pose.y).name)
            ids, counts = np.unique(obs.instance[obs.depth_m > 0], return_counts=True)
            big = {int(i) for i, n in zip(ids, counts) if i > 0 and n >= scaled_min_pixels(120, 160)}
            listed = {o.instance_id for o in d.objects}
            entries = d.text.count(";") + 1 if listed else 0  # a group of objects is one entry
            assert listed <= big and entries <= MAX_OBJECTS
            assert listed == big or entries == MAX_OBJECTS
            depth = {i: float(np.median(obs.depth_m[(obs.instance == i) & (obs.depth_m > 0)]))
                     for i in big}
            if big - listed:  # the ones left out lie no nearer than any listed (0.1 m rounding)
                assert min(depth[i] for i in listed) <= min(depth[i] for i in big - listed) + 0.1
            for o in d.objects:
                truth = env.house.object(o.instance_id)
                assert o.instance_id in ids and o.label.category == truth.category
                assert o.label.colour == truth.colour and o.label.state == truth.state
                noun = {"tv": "TV", "tv stand": "TV stand"}.get(o.label.category, o.label.category)
                assert f"{o.label.colour} {noun[:-1]}" in d.text  # singular or plural
            assert describe_frame(obs, labels) == d  # deterministic


def test_relevancy_text_is_one_object_per_line_with_its_room():
    from efficienteqa.perception.semantic import SemanticPerception

    perception = SemanticPerception(FakeLabels())
    obs = make_frame()
    lines = perception.relevancy_text(obs).splitlines()
    assert "a red sofa in the hallway" in lines and "a white lamp (on) in the kitchen" in lines
    assert not any(w == "m" or "ahead" in w for line in lines for w in line.split())
    assert perception.frame(obs).startswith("You are in the kitchen.")


def test_door_sides_are_the_rooms_either_side_of_the_wall(catalog):
    from efficienteqa.envs.synthetic.generate import generate_house

    house = generate_house(7, catalog, "builtin")  # nine doors, two of them closed
    labels = HouseLabels(house)
    rooms = {r.id: r.name for r in house.layout.rooms}
    for door_id, obj in house.meta["door_objects"].items():
        door = house.layout.doors[int(door_id)]
        sides = labels.label(obj).door
        assert sides.rooms == (rooms[door.room_a], rooms.get(door.room_b))
        for sign, name in ((1, sides.rooms[0]), (-1, sides.rooms[1])):
            x, y = door.x + sign * 0.4 * sides.normal[0], door.y + sign * 0.4 * sides.normal[1]
            assert sides.side(x, y) == name == labels.room_at(x, y)
    assert all(labels.label(o.id).door is None for o in house.objects if o.category != "door")


DOOR = 20  # on the wall line x = 4 between the kitchen (camera side) and the hallway


class DoorLabels(FakeLabels):
    def __init__(self, state: str) -> None:
        sides = DoorSides(("hallway", "kitchen"), 4.0, 0.0, (1.0, 0.0))
        self.door = ObjectLabel("door", "brown", state, "hallway", sides)

    def label(self, instance_id: int) -> ObjectLabel | None:
        return self.door if instance_id == DOOR else super().label(instance_id)


def _frame_with_door(kitchen_floor: bool = True) -> Observation:
    obs = make_frame()
    obs.instance[10:21, 20:26], obs.depth_m[10:21, 20:26] = DOOR, 3.0
    if not kitchen_floor:
        obs.depth_m[35:], obs.instance[35:] = 0.0, -1
    return obs


@pytest.mark.parametrize("state, kitchen_floor, place", [
    ("closed", True, ", in a wall of the kitchen"),  # the hallway's floor is seen, elsewhere
    ("closed", False, ""),
    ("open", True, ", between the hallway and the kitchen"),
    ("open", False, ", in a wall of the hallway"),
])
def test_a_door_names_the_rooms_the_frame_shows(state, kitchen_floor, place):
    obs = _frame_with_door(kitchen_floor)
    d = describe_frame(obs, DoorLabels(state), min_pixels=10)
    assert f"a brown door ({state}) slightly left, 3.0 m{place}. Through" in d.text  # the last
    line = f"a brown door ({state}) {place.removeprefix(', ')}".strip()
    assert line in SemanticPerception(DoorLabels(state)).relevancy_text(obs).splitlines()


def test_the_robots_room_is_named_only_when_its_floor_or_furniture_is_seen():
    obs = _frame_with_door(kitchen_floor=False)  # the lamp, chairs and cup stand in the kitchen
    assert describe_frame(obs, FakeLabels(), min_pixels=10).text.startswith(
        "You are in the kitchen. Visible: a white lamp (on) ahead, 2.0 m;")
    obs.instance[np.isin(obs.instance, [7, 9, 11, 12])] = 0  # now a wall
    d = describe_frame(obs, FakeLabels(), min_pixels=10)
    assert d.room is None and d.rooms_in_view == ("hallway",)
    assert d.text == ("The room you are in is not in view. Visible: a red sofa on the left, "
                      "3.0 m, in the hallway. Through a doorway: the hallway.")
    assert SemanticPerception(FakeLabels()).relevancy_text(obs) == "a red sofa in the hallway"
    obs.instance[obs.instance == 5] = 0
    assert SemanticPerception(FakeLabels()).relevancy_text(obs) == "walls and floor"


def test_an_object_names_its_room_only_when_that_floor_is_seen():
    obs = make_frame()
    obs.depth_m[30:35], obs.instance[30:35] = 0.0, -1  # the hallway's floor is not seen
    d = describe_frame(obs, FakeLabels(), min_pixels=10)
    assert d.text.endswith("a red sofa on the left, 3.0 m.") and d.rooms_through_doorways == ()
    assert "a red sofa" in SemanticPerception(FakeLabels()).relevancy_text(obs).splitlines()


def test_a_direction_names_every_room_whose_floor_its_part_of_the_image_shows():
    # with a 3 m radius the part around A (in the kitchen) also holds the hallway's floor
    out = describe_directions(make_frame(), [_prompt("A", (2.5, 1.0))], FakeLabels(),
                              radius_m=3.0, min_pixels=10)
    assert out["A"].startswith("in the kitchen, floor of the hallway in view, 1.5 m away; ")
    obs = make_frame()
    obs.depth_m[30:35], obs.instance[30:35] = 0.0, -1  # the hallway's floor is not seen
    out = describe_directions(obs, [_prompt("A", (2.5, 1.0))], FakeLabels(), radius_m=3.0,
                              min_pixels=10)
    assert out["A"].startswith("in the kitchen, 1.5 m away; ") and "hallway" not in out["A"]


@pytest.mark.parametrize("state, hallway_floor, lead", [
    ("open", True, "; an open door to the hallway."),
    ("open", False, "."),  # the hallway's floor is not in the frame: where it leads is not seen
    ("closed", True, "."),
])
def test_an_open_door_near_a_point_says_where_it_leads(state, hallway_floor, lead):
    obs = _frame_with_door()
    if not hallway_floor:
        obs.depth_m[30:35], obs.instance[30:35] = 0.0, -1
    out = describe_directions(obs, [_prompt("A", (3.5, 1.8))], DoorLabels(state), radius_m=1.0,
                              min_pixels=10)
    assert f"a brown door ({state})" in out["A"] and out["A"].endswith(f"a red sofa{lead}")
    assert ("door to" in out["A"]) == (lead != ".")


def _sh3d_env(seed: int):
    from pathlib import Path

    from efficienteqa.envs.synthetic.catalog import DEFAULT_SOURCE
    from efficienteqa.envs.synthetic.env import SyntheticEnv

    if not Path(DEFAULT_SOURCE).exists():
        pytest.skip("apt-get install sweethome3d-furniture")
    return SyntheticEnv.from_seed(seed, "sh3d")


@needs_egl
def test_a_lamp_on_a_nightstand_is_said_to_stand_on_it_in_a_rendered_frame():
    # house 1's "What is on the nightstand in the bedroom?" seen from its oracle pose; the relation
    # comes from the frame's depth and instance buffers, not from the house's support_id
    with _sh3d_env(1) as env:
        nightstand, lamp = env.house.object(2), env.house.object(3)
        assert (nightstand.category, lamp.category, lamp.support_id) == ("nightstand", "desk lamp", 2)
        d = describe_frame(env.observe(Pose2D(1.575, 4.025, -2.2502)), env.scene_labels())
    on = {o.instance_id: o.on for o in d.objects}
    assert on[3] == f"the {nightstand.colour} nightstand"
    assert f"a {lamp.colour} desk lamp ({lamp.state}) on the {nightstand.colour} nightstand, " in d.text
    assert on[2] is None and on[1] is None  # the nightstand and the bed stand on the floor


@needs_egl
def test_the_chairs_around_a_table_are_counted_in_a_rendered_frame():
    with _sh3d_env(0) as env:
        chairs = [o for o in env.house.objects if o.id in (37, 38, 39, 40)]
        assert {o.category for o in chairs} == {"chair"} and len({o.colour for o in chairs}) == 1
        d = describe_frame(env.observe(Pose2D(7.875, 4.725, 1.6575)), env.scene_labels())
    assert f"four {chairs[0].colour} chairs slightly left to slightly right, " in d.text
    assert d.text.count(" chair") == 1 and {37, 38, 39, 40} <= {o.instance_id for o in d.objects}
    assert all(o.on is None for o in d.objects if o.instance_id in (36, 37, 38, 39, 40))
