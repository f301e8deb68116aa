"""The synthetic environment's start pose (DESIGN 9, defect 8 of the walks): a start that open doors' leaves
wall into a pocket (house 129) is moved to the house's main navigable region."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from efficienteqa.envs.synthetic.catalog import DEFAULT_SOURCE
from efficienteqa.envs.synthetic.env import catalog_for, start_clear_of_doors
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M, generate_house, navigation_grid

pytestmark = pytest.mark.skipif(not Path(DEFAULT_SOURCE).exists(),
                                reason="apt-get install sweethome3d-furniture")


def test_a_start_walled_in_by_a_door_leaf_moves_to_the_nearest_cell_outside_the_pocket():
    house = generate_house(129, catalog_for("sh3d"), "sh3d")
    grid = navigation_grid(house)
    leaf = next(o for o in house.objects if o.category == "door"
                and np.hypot(o.x - house.start.x, o.y - house.start.y) < 0.5)
    start = start_clear_of_doors(house, grid)
    assert grid.is_navigable(start.x, start.y, ROBOT_RADIUS_M) and start.yaw == house.start.yaw
    # the leaf lies along x at its y: the generated start is on its wall side, the new one not
    assert (house.start.y - leaf.y) * (start.y - leaf.y) < 0
    assert np.hypot(start.x - house.start.x, start.y - house.start.y) < 0.5


def test_a_start_clear_of_every_leaf_is_kept():
    for seed in (100, 101, 4):
        house = generate_house(seed, catalog_for("sh3d"), "sh3d")
        assert start_clear_of_doors(house, navigation_grid(house)) == house.start
