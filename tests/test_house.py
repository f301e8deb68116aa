import json
import math

import numpy as np
import pytest

from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M, generate_house, navigation_grid
from efficienteqa.envs.synthetic.house import House
from efficienteqa.errors import EfficientEQAError

SEEDS = range(8)


@pytest.mark.parametrize("seed", SEEDS)
def test_same_seed_same_house(catalog, seed):
    a = generate_house(seed, catalog, "builtin").to_json()
    b = generate_house(seed, catalog, "builtin").to_json()
    assert json.dumps(a) == json.dumps(b)


def test_different_seeds_differ(catalog):
    houses = {json.dumps(generate_house(s, catalog, "builtin").to_json()) for s in SEEDS}
    assert len(houses) == len(SEEDS)


@pytest.mark.parametrize("seed", SEEDS)
def test_every_room_is_reachable_from_the_start(catalog, seed):
    house = generate_house(seed, catalog, "builtin")
    grid = navigation_grid(house)
    start = (house.start.x, house.start.y)
    assert grid.is_navigable(*start, ROBOT_RADIUS_M)
    field = grid.distance_field(start, ROBOT_RADIUS_M)
    xs, ys = grid.spec.centres()
    for room in house.layout.rooms:
        inside = (xs > room.x0) & (xs < room.x1) & (ys > room.y0) & (ys < room.y1)
        assert np.isfinite(field[inside]).any(), f"{room.name} unreachable in house {seed}"


@pytest.mark.parametrize("seed", SEEDS)
def test_furniture_stays_in_its_room_without_collisions(catalog, seed):
    house = generate_house(seed, catalog, "builtin")
    standing = [o for o in house.objects if o.on_floor and o.category != "door"]
    boxes = {}
    for o in standing:
        room = house.room(o.room_id)
        quarter = round(o.yaw / (math.pi / 2)) % 2
        hx, hy = (o.size_m[0], o.size_m[1]) if quarter == 0 else (o.size_m[1], o.size_m[0])
        box = (o.x - hx / 2, o.y - hy / 2, o.x + hx / 2, o.y + hy / 2)
        assert room.x0 < box[0] and box[2] < room.x1 and room.y0 < box[1] and box[3] < room.y1
        boxes[o.id] = box
    chairs_at = {c for chairs in house.meta["chairs_at_table"].values() for c in chairs}
    tables = {int(t) for t in house.meta["chairs_at_table"]}
    for i, a in enumerate(standing):
        for b in standing[i + 1:]:
            if {a.id, b.id} & chairs_at and {a.id, b.id} & tables:
                continue  # chairs slide under their table
            if {a.category, b.category} == {"desk", "office chair"} or (
                    {a.category, b.category} == {"desk", "chair"}):
                continue
            ba, bb = boxes[a.id], boxes[b.id]
            overlap = min(ba[2], bb[2]) - max(ba[0], bb[0]), min(ba[3], bb[3]) - max(ba[1], bb[1])
            assert min(overlap) <= 1e-6, f"{a.category} {a.id} overlaps {b.category} {b.id}"
    for small in (o for o in house.objects if o.support_id is not None):
        support = house.object(small.support_id)
        assert small.z > 0.05 and abs(small.z - support.top_z) < support.size_m[2]
        assert math.hypot(small.x - support.x, small.y - support.y) < max(support.size_m[:2])


def test_dining_chairs_are_counted_and_face_their_table(catalog):
    found = 0
    for seed in range(20):
        house = generate_house(seed, catalog, "builtin")
        for table_id, chairs in house.meta["chairs_at_table"].items():
            table = house.object(int(table_id))
            near = [o.id for o in house.objects if o.category == "chair" and o.room_id == table.room_id
                    and math.hypot(o.x - table.x, o.y - table.y) < max(table.size_m[:2])]
            assert sorted(near) == sorted(chairs)
            for c in chairs:
                chair = house.object(c)
                front = np.array([math.sin(chair.yaw), -math.cos(chair.yaw)])
                to_table = np.array([table.x - chair.x, table.y - chair.y])
                assert front @ to_table > 0, "a chair turns its back to the table"
            found += 1
    assert found >= 5


def test_states_colours_and_doors(catalog):
    house = generate_house(4, catalog, "builtin")
    states = {o.state for o in house.objects if o.category in ("tv", "floor lamp", "desk lamp")}
    assert states <= {"on", "off"}
    doors = [o for o in house.objects if o.category == "door"]
    assert len(doors) == len(house.layout.doors)
    assert {o.state for o in doors} <= {"open", "closed"}
    recoloured = [o for o in house.objects if o.colour_rgb is not None]
    assert 1 <= len(recoloured) <= 3


def test_json_round_trip_and_broken_file(catalog, tmp_path):
    house = generate_house(2, catalog, "builtin")
    path = tmp_path / "house.json"
    house.save(path)
    again = House.load(path)
    assert json.dumps(again.to_json()) == json.dumps(house.to_json())
    path.write_text("{not json")
    with pytest.raises(EfficientEQAError, match="cannot read house file"):
        House.load(path)


REQUIRED = {"bedroom": "bed", "guest bedroom": "bed", "kitchen": "refrigerator",
            "bathroom": "toilet", "guest bathroom": "toilet", "living room": "sofa"}


@pytest.mark.parametrize("assets", ["builtin", "sh3d"])
def test_every_room_gets_its_key_furniture(assets):
    from pathlib import Path

    from efficienteqa.envs.synthetic.catalog import DEFAULT_SOURCE
    from efficienteqa.envs.synthetic.env import catalog_for

    if assets == "sh3d" and not Path(DEFAULT_SOURCE).exists():
        pytest.skip("apt-get install sweethome3d-furniture")
    catalog = catalog_for(assets)
    missing = []
    for seed in range(15):
        house = generate_house(seed, catalog, assets)
        for room in house.layout.rooms:
            want = REQUIRED.get(room.name)
            if want and not any(o.category == want and o.room_id == room.id for o in house.objects):
                missing.append((seed, room.name, want))
    assert not missing


def test_start_is_in_the_open_living_room(catalog):
    for seed in range(10):
        house = generate_house(seed, catalog, "builtin")
        grid = navigation_grid(house)
        room = house.layout.room_at(house.start.x, house.start.y)
        assert room is not None and room.type == "living room"
        i, j = grid.spec.world_to_cell((house.start.x, house.start.y))
        # The most open spot of the furnished room: at least 1 m where the room allows it.
        xs, ys = grid.spec.centres()
        labels, _ = grid.components(ROBOT_RADIUS_M)
        main = labels == grid.label_at((house.start.x, house.start.y), ROBOT_RADIUS_M)
        inside = (xs > room.x0) & (xs < room.x1) & (ys > room.y0) & (ys < room.y1) & main
        best = grid.clearance()[inside].max()
        assert grid.clearance()[i, j] >= min(1.0, best - 0.1) - 1e-9


def test_overhead_mask_marks_parts_above_the_top_surface():
    from efficienteqa.envs.synthetic.furnish import overhead_mask
    from efficienteqa.envs.synthetic.mesh import box_part

    top = box_part((1.0, 0.6, 0.05), (1, 1, 1), centre=(0.0, 0.0, 0.725))
    side = box_part((0.2, 0.6, 1.5), (1, 1, 1), centre=(0.4, 0.0, 0.75))  # a tall side
    shelf = box_part((1.0, 0.6, 0.02), (1, 1, 1), centre=(0.0, 0.0, 1.2))  # 0.45 m higher
    mask = overhead_mask([top, side, shelf], 0.75, (1.0, 0.6, 1.5), clear_m=0.3)
    xs = (np.arange(mask.shape[1]) + 0.5) * 0.05 - 0.5
    assert mask[:, xs > 0.32].all() and not mask[:, xs < 0.28].any()
    assert overhead_mask([top, side, shelf], 0.75, (1.0, 0.6, 1.5), clear_m=0.6).all()


def test_small_objects_do_not_cut_into_their_supports():
    from pathlib import Path

    from efficienteqa.envs.synthetic.catalog import DEFAULT_SOURCE
    from efficienteqa.envs.synthetic.env import catalog_for
    from efficienteqa.envs.synthetic.furnish import overhead_mask

    if not Path(DEFAULT_SOURCE).exists():
        pytest.skip("apt-get install sweethome3d-furniture")
    catalog = catalog_for("sh3d")
    checked = 0
    for seed in range(8):
        house = generate_house(seed, catalog, "sh3d")
        for obj in (o for o in house.objects if o.support_id is not None):
            support = house.object(obj.support_id)
            top = obj.z - support.z
            mask = overhead_mask(catalog.mesh(support.model_key), top, support.size_m,
                                 clear_m=obj.size_m[2])
            c, s = math.cos(-support.yaw), math.sin(-support.yaw)
            dx, dy = obj.x - support.x, obj.y - support.y
            lx, ly = c * dx - s * dy, s * dx + c * dy  # object centre in the support's frame
            j = int((lx + support.size_m[0] / 2) / 0.05)
            i = int((ly + support.size_m[1] / 2) / 0.05)
            assert not mask[min(max(i, 0), mask.shape[0] - 1), min(max(j, 0), mask.shape[1] - 1)]
            checked += 1
    assert checked >= 10


@pytest.mark.parametrize("assets", ["builtin", "sh3d"])
def test_start_and_every_open_doorway_share_one_component(assets):
    from pathlib import Path

    from efficienteqa.envs.synthetic.catalog import DEFAULT_SOURCE
    from efficienteqa.envs.synthetic.env import catalog_for

    if assets == "sh3d" and not Path(DEFAULT_SOURCE).exists():
        pytest.skip("apt-get install sweethome3d-furniture")
    catalog = catalog_for(assets)
    for seed in range(12):
        house = generate_house(seed, catalog, assets)
        grid = navigation_grid(house)
        start = grid.label_at((house.start.x, house.start.y), ROBOT_RADIUS_M)
        assert start > 0
        for door in house.layout.doors:
            if door.open:
                assert grid.label_at((door.x, door.y), ROBOT_RADIUS_M) == start, (seed, door)
