"""mapping.coverage: how much of a room its views covered (DESIGN 9, defect 2 of the walks)."""

from __future__ import annotations

import numpy as np

from efficienteqa.mapping.coverage import hull_mask, room_coverage


def test_the_hull_of_a_rooms_seen_floor_fills_what_lies_between_its_glimpses():
    seen = np.zeros((20, 40), bool)
    seen[2:18, 2:6] = True  # the west end of the room, seen up close
    seen[2:18, 34:38] = True  # its east end, glimpsed from the west end
    hull = hull_mask(seen)
    assert hull[2:18, 2:38].all() and hull.sum() == 16 * 36
    assert not hull[0:2].any() and not hull[:, 38:].any()


def test_coverage_counts_the_unexplored_middle_and_leaves_out_furniture():
    seen = np.zeros((20, 40), bool)
    seen[2:18, 2:6] = seen[2:18, 34:38] = True
    explored = np.zeros_like(seen)
    explored[:, :20] = True  # views covered the west half
    none = np.zeros_like(seen)
    assert abs(room_coverage(seen, explored, none) - 0.5) < 0.01
    furniture = np.zeros_like(seen)
    furniture[2:18, 20:38] = True  # the east half is a bed: nothing there to see
    assert room_coverage(seen, explored, furniture) == 1.0
    assert room_coverage(np.zeros_like(seen), explored, none) == 0.0
