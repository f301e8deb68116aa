import itertools

import numpy as np
import pytest

from efficienteqa.envs.synthetic.layout import DOOR_HEIGHT_M, MIN_ROOM_SIDE_M, generate_layout


@pytest.mark.parametrize("seed,n", list(itertools.product(range(12), range(5, 10))))
def test_rooms_tile_the_house_and_doors_connect_them(seed, n):
    lay = generate_layout(np.random.default_rng(seed), n)
    assert len(lay.rooms) == n
    assert sum(r.area_m2 for r in lay.rooms) == pytest.approx(lay.width_m * lay.depth_m, rel=1e-6)
    for a, b in itertools.combinations(lay.rooms, 2):
        overlap_x = min(a.x1, b.x1) - max(a.x0, b.x0)
        overlap_y = min(a.y1, b.y1) - max(a.y0, b.y0)
        assert overlap_x <= 1e-6 or overlap_y <= 1e-6, "rooms overlap"
    for r in lay.rooms:
        if r.type != "hallway":
            assert min(r.x1 - r.x0, r.y1 - r.y0) >= MIN_ROOM_SIDE_M - 0.05
    types = [r.type for r in lay.rooms]
    assert {"living room", "kitchen", "bedroom", "bathroom"} <= set(types)
    assert ("hallway" in types) == (n >= 6)
    # Doors link every room into one component.
    parent = {r.id: r.id for r in lay.rooms}

    def find(i):
        while parent[i] != i:
            i = parent[i]
        return i

    for d in lay.doors:
        if d.open:
            parent[find(d.room_a)] = find(d.room_b)
    assert len({find(r.id) for r in lay.rooms}) == 1


def test_door_openings_are_not_walled_up():
    lay = generate_layout(np.random.default_rng(5), 8)
    for d in lay.doors:
        for w in lay.walls:
            if w.z0 >= DOOR_HEIGHT_M - 1e-6:
                continue  # a lintel above the opening
            lo_x, hi_x = sorted((w.x0, w.x1))
            lo_y, hi_y = sorted((w.y0, w.y1))
            inside = (lo_x - 0.05 < d.x < hi_x + 0.05) and (lo_y - 0.05 < d.y < hi_y + 0.05)
            assert not inside, f"door {d} is blocked by wall {w}"


def test_same_seed_same_plan_and_bad_room_count():
    a = generate_layout(np.random.default_rng(9), 7)
    b = generate_layout(np.random.default_rng(9), 7)
    assert a == b
    assert a != generate_layout(np.random.default_rng(10), 7)
    with pytest.raises(ValueError):
        generate_layout(np.random.default_rng(0), 4)
