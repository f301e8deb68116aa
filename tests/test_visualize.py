"""Top-down map picture: size, north-up orientation, frontier dots, overlays."""

from __future__ import annotations

import numpy as np

from efficienteqa.explore.base import Frontier
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.state import MapState
from efficienteqa.mapping.visualize import FREE, FRONTIER, OCCUPIED, map_image, world_to_image
from efficienteqa.observation import PromptPoint

GRID = GridSpec((-1.0, 2.0), 0.1, (20, 30))  # 3 m wide (x), 2 m tall (y)


def _state() -> MapState:
    free = np.zeros(GRID.shape, dtype=bool)
    free[2:18, 2:28] = True
    occupied = np.zeros(GRID.shape, dtype=bool)
    occupied[17, 5] = True  # near the top (large y), left
    free[17, 5] = False
    explored = np.zeros(GRID.shape, dtype=bool)
    explored[2:8, 2:10] = True
    return MapState(GRID, free, occupied, explored, free.copy(), (0.0, 2.5))


def test_shape_dtype_and_north_up():
    img = map_image(_state(), scale=4)
    assert img.shape == (80, 120, 3) and img.dtype == np.uint8
    # grid row 17 of 20 is image block row 2 (row 0 of the image = largest y)
    assert tuple(img[2 * 4 + 1, 5 * 4 + 2]) == OCCUPIED
    assert tuple(img[17 * 4 + 1, 5 * 4 + 2]) != OCCUPIED
    assert tuple(img[3 * 4 + 1, 12 * 4 + 2]) == FREE
    u, v = world_to_image(GRID, GRID.cell_to_world((17, 5)), 4)
    assert (u, v) == (22.0, 10.0)  # the cell's centre, in continuous pixel coordinates


def test_frontier_dot_and_overlays_appear_where_expected():
    state = _state()
    base = map_image(state, scale=4)
    f = Frontier(cell=(10, 20), xy=tuple(GRID.cell_to_world((10, 20))), normal=(1.0, 0.0), size=9)
    values = np.zeros(GRID.shape)
    values[4:8, 22:26] = 1.0
    img = map_image(state, values=values, frontiers=[f], scale=4,
                    trajectory=[Pose2D(0.0, 2.5, 0.0), Pose2D(0.5, 3.0, 1.0)],
                    target_xy=(1.2, 3.2), prompts=[PromptPoint("A", (0.3, 3.5), (10.0, 10.0))])
    u, v = world_to_image(GRID, f.xy, 4)
    assert tuple(img[int(v), int(u)]) == FRONTIER
    assert tuple(base[int(v), int(u)]) != FRONTIER
    hot = img[(20 - 6) * 4 + 1, 23 * 4 + 1].astype(int)
    assert hot[0] > hot[2] + 50  # the heat overlay tints red
    assert (img != base).any(axis=2).sum() > 200
