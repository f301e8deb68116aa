"""Exploration efficiency options of the frontier explorer (DESIGN 8)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from efficienteqa.explore.registry import make_explorer
from efficienteqa.explore.settings import PAPER_SFE, FrontierConfig, SFEConfig
from efficienteqa.explore.sfe import FrontierExplorer, idle, ray_gain, view_yaw
from efficienteqa.geometry import Pose2D
from test_sfe import corridor, make_state


def spec_explorer(**options: object) -> FrontierExplorer:
    """Frontier-only as DESIGN 3.2 (every option off) but for ``options``, seeded 0."""
    explorer = FrontierExplorer(SFEConfig(**{**PAPER_SFE, "use_values": False, **options}))
    explorer.reset(0)
    return explorer


def test_idle_is_the_same_view_again():
    pose = Pose2D(1.0, 1.0, math.pi - 0.1)
    assert idle(Pose2D(1.1, 1.1, -math.pi + 0.1), pose, 0.3, 30.0)  # wrapped: 11 deg
    assert not idle(Pose2D(1.1, 1.1, 0.0), pose, 0.3, 30.0)  # turned round
    assert not idle(Pose2D(1.5, 1.0, pose.yaw), pose, 0.3, 30.0)  # moved


def one_end() -> tuple:
    """The corridor with only its +x end unexplored; the robot on that frontier's standing
    point, facing it: the DESIGN 3.2 choice is to stay and look again."""
    state = corridor(slice(0, 110))
    explorer = spec_explorer()
    d = explorer.decide(state, Pose2D(6.0, 1.0, 0.0), None, 1)
    stand = Pose2D(d.target_xy[0], d.target_xy[1], 0.0)
    return make_state(state.free, state.explored, stand.xy), stand


def test_skip_idle_goes_up_close_instead_of_taking_the_same_view():
    state, pose = one_end()
    paper = spec_explorer()
    d = paper.decide(state, pose, None, 2)
    assert idle(d.pose, pose, 0.3, 30.0)
    skip = spec_explorer(skip_idle=True)
    d = skip.decide(state, pose, None, 2)
    assert not d.done and d.pose.x - pose.x == pytest.approx(1.5, abs=0.15)


def doorway() -> tuple:
    """Two 10 x 3 m rooms, a wall at y = 3 m with a 1 m door at x = 4-5 m; the robot at
    (8, 1.5) in the lower room. Of the upper room only x > 4 m is explored: its frontier lies
    just past the door, its normal along -x, so DESIGN 3.2's back-off point is beside the door in
    the upper room, out of the doorway's line."""
    free = np.zeros((62, 100), dtype=bool)
    free[1:-1, 1:-1] = True
    free[30:32, :] = False
    free[30:32, 40:50] = True
    explored = np.ones_like(free)
    explored[32:, :40] = False
    return make_state(free, explored, (8.0, 1.5)), Pose2D(8.0, 1.5, 0.0)


def test_approach_unreachable_heads_for_a_sliver_instead_of_ending():
    free = np.zeros((60, 60), dtype=bool)
    free[1:20, 1:-1] = True  # the robot's room, 6 x 2 m, all explored
    free[20:59, 30] = True  # a 1-cell passage (navigable at no radius) 3.9 m long
    explored = np.ones_like(free)
    explored[50:, :] = False  # its far end unexplored: 1.5 m back from there is no floor
    state = make_state(free, explored, (1.0, 1.0))
    pose = Pose2D(1.0, 1.0, 0.0)
    paper = spec_explorer()
    assert paper.decide(state, pose, None, 1).reason == "no reachable frontier"
    explorer = spec_explorer(approach_unreachable=True)
    d = explorer.decide(state, pose, None, 1)
    assert not d.done and abs(d.target_xy[0] - 3.05) < 0.3 and d.target_xy[1] > 1.4


def test_view_yaw_turns_to_the_unexplored_room_in_sight():
    state, _ = doorway()  # unexplored: the upper room's x < 4 m, seen through the door
    below_door = np.array([4.5, 2.5])
    yaw = view_yaw(state, below_door, 0.0, 5.0, 40.0, 0.8)
    assert 60 < math.degrees(yaw) < 130  # through the door, not along the explored room
    assert view_yaw(state, below_door, math.radians(100), 5.0, 40.0, 0.8) == pytest.approx(
        math.radians(100))  # facing there already: kept
    walled = np.array([9.0, 0.5])  # the wall hides the upper room: nothing to turn to
    assert view_yaw(state, walled, 0.3, 5.0, 40.0, 0.8) == 0.3
    assert ray_gain(state, walled, 5.0).sum() == 0


def test_approach_unreachable_goes_on_after_every_frontier_was_looked_at():
    state, pose = one_end()  # a frontier that stays unexplored however often it is looked at
    ends = {}
    for approach in (False, True):
        explorer = spec_explorer(approach_unreachable=approach)
        here = pose
        for step in range(1, 10):
            d = explorer.decide(make_state(state.free, state.explored, here.xy), here, None, step)
            if d.done:
                break
            here = d.pose
        ends[approach] = d.reason if d.done else None
    assert ends == {False: "no reachable frontier", True: None}


def test_the_paper_exploration_switches_every_option_off():
    from efficienteqa.explore.config import ExploreConfig

    options = ExploreConfig(exploration="paper").explorer_options()
    paper = SFEConfig(**options)
    assert not (paper.skip_idle or paper.approach_unreachable or paper.view_gain)
    assert paper.frontier == FrontierConfig()
    assert ExploreConfig(explorer="random", exploration="paper").explorer_options() == {}
    frontier = ExploreConfig(explorer="frontier-only", exploration="paper").explorer_options()
    assert make_explorer("frontier-only", **frontier).config == replace(paper, use_values=False)
