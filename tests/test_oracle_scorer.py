import math

import numpy as np

from efficienteqa.explore.oracle import OracleScorer
from efficienteqa.geometry import Pose2D
from efficienteqa.observation import Observation, PromptPoint

EVIDENCE = np.array([10.0, 0.0])


def _obs(x: float, seen: bool) -> Observation:
    inst = np.full((4, 4), 7 if seen else -1, np.int32)
    return Observation(np.zeros((4, 4, 3), np.uint8), np.ones((4, 4), np.float32), np.eye(4),
                       np.eye(3), Pose2D(x, 0.0, 0.0), inst)


def _scorer() -> OracleScorer:
    return OracleScorer(lambda xy: float(np.linalg.norm(np.asarray(xy) - EVIDENCE)),
                        lambda inst: bool((inst == 7).any()))


def test_lsv_on_the_prompt_nearest_the_evidence_and_gsv_when_it_leads_closer():
    prompts = [PromptPoint("A", (4.0, 3.0), (10, 10)), PromptPoint("B", (6.0, 0.0), (20, 10))]
    score = _scorer().score(_obs(3.0, seen=False), prompts, "q")
    assert score.letters == {"A": 0.0, "B": 1.0} and score.p_yes == 1.0
    # From 6.5 m away the best prompt is only 0.5 m closer: not worth it.
    assert _scorer().score(_obs(5.5, seen=False), prompts, "q").p_yes == 0.0
    # Seeing the evidence is always worth it.
    assert _scorer().score(_obs(5.5, seen=True), prompts, "q").p_yes == 1.0


def test_evidence_distance_goes_round_the_wall_not_through_it():
    from efficienteqa.explore.oracle import evidence_distance_field
    from efficienteqa.mapping.grid import GridSpec
    from efficienteqa.mapping.navgrid import OccupancyGrid

    # 10 m x 6 m, a wall at y = 3 m (rows 29-30) with a doorway at x = 8-9 m.
    spec = GridSpec((0.0, 0.0), 0.1, (60, 100))
    free = np.ones(spec.shape, bool)
    free[29:31, :] = False
    free[29:31, 80:90] = True
    grid = OccupancyGrid(spec, free)
    evidence = (2.0, 3.2)  # on the wall, in the north room (y 3-6 m)
    north, south = (0.0, 3.0, 10.0, 6.0), (0.0, 0.0, 10.0, 3.0)
    field_m = evidence_distance_field(grid, evidence, 0.0, [north], reach_m=2.0)
    across = field_m[spec.world_to_cell((2.05, 2.65))]  # just behind the wall
    assert across > 10.0  # round by the doorway: ~6 m there, ~6 m back
    inside = field_m[spec.world_to_cell((2.05, 3.95))]
    assert abs(inside - 0.75) < 0.1  # straight line from a seed next to it
    # Without the room, the nearest floor wins, wall or not (the old snap behaviour).
    loose = evidence_distance_field(grid, evidence, 0.0, [], reach_m=2.0)
    assert loose[spec.world_to_cell((2.05, 2.65))] < 1.0
    # The room of the evidence decides, not the nearest floor.
    assert evidence_distance_field(grid, evidence, 0.0, [south])[
        spec.world_to_cell((2.05, 2.65))] < 1.0


def _rooms_grid():
    """10 m x 6 m: a west room (x 0-6 m) and, behind a wall at x = 6 m with no door, a closed
    east pocket (x 6.2-10 m). Nothing in the pocket can be reached from the west room."""
    from efficienteqa.mapping.grid import GridSpec
    from efficienteqa.mapping.navgrid import OccupancyGrid

    spec = GridSpec((0.0, 0.0), 0.1, (60, 100))
    free = np.ones(spec.shape, bool)
    free[:, 60:62] = False
    return OccupancyGrid(spec, free)


def _prompt_obs(x: float, y: float) -> Observation:
    return Observation(np.zeros((4, 4, 3), np.uint8), np.ones((4, 4), np.float32), np.eye(4),
                       np.eye(3), Pose2D(x, y, 0.0), np.full((4, 4), -1, np.int32))


def test_a_point_off_the_navigable_floor_is_measured_from_the_nearest_navigable_cell():
    from efficienteqa.explore.oracle import EvidenceDistance, evidence_distance_field

    grid = _rooms_grid()
    start = (1.0, 3.0)
    evidence = (5.9, 5.5)  # on the dividing wall, in the west room's corner
    field_m = evidence_distance_field(grid, evidence, 0.2, [(0.0, 0.0, 6.0, 6.0)],
                                      start_xy=start)
    distance = EvidenceDistance(grid, field_m, 0.2)
    assert distance.reachable
    # B is free floor 0.1 m from the wall, inside the robot's 0.2 m radius: not navigable, so
    # the field itself has no value there, though B is right beside the evidence.
    b = (5.85, 5.0)
    assert not grid.is_navigable(*b, radius_m=0.2)
    assert not np.isfinite(field_m[grid.spec.world_to_cell(b)])
    assert distance(b) < 1.0
    # Measured from the nearest navigable cell (x 5.75 m), plus the straight line to it.
    assert abs(distance(b) - (distance((5.75, 5.05)) + 0.1)) < 0.02
    prompts = [PromptPoint("A", (2.0, 1.0), (10, 10)), PromptPoint("B", b, (20, 10))]
    score = OracleScorer(distance, lambda inst: False).score(_prompt_obs(*start), prompts, "q")
    assert score.letters == {"A": 0.0, "B": 1.0} and score.p_yes == 1.0
    # Farther than snap_m from every navigable cell (outside the house): unreachable.
    assert distance((-1.0, 3.0)) == math.inf
    assert distance((-0.3, 3.0)) < math.inf


def test_evidence_in_a_pocket_unreachable_from_the_start_is_flagged_not_scored_as_a():
    from efficienteqa.explore.oracle import EvidenceDistance, evidence_distance_field

    grid = _rooms_grid()
    start = (1.0, 3.0)
    wardrobe = (9.0, 3.0)  # in the closed east pocket
    east = (6.2, 0.0, 10.0, 6.0)
    field_m = evidence_distance_field(grid, wardrobe, 0.2, [east], start_xy=start)
    distance = EvidenceDistance(grid, field_m, 0.2)
    assert not distance.reachable and np.isinf(field_m).all()
    prompts = [PromptPoint("A", (3.0, 1.0), (10, 10)), PromptPoint("B", (3.0, 5.0), (20, 10))]
    score = OracleScorer(distance, lambda inst: False).score(_prompt_obs(*start), prompts, "q")
    assert score.letters == {"A": 0.5, "B": 0.5}  # no letter wins, A least of all
    assert "unreachable" in score.info and score.p_yes == 0.0
    # Without the start, the pocket's own floor counts as a view (the old field): the pocket
    # is finite, the robot's room is not, and the prompts still learn nothing from it.
    loose = evidence_distance_field(grid, wardrobe, 0.2, [east])
    assert np.isfinite(loose).any() and not np.isfinite(loose[grid.spec.world_to_cell(start)])


def test_a_known_view_reachable_from_the_start_makes_a_pocket_reachable():
    from efficienteqa.explore.oracle import EvidenceDistance, evidence_distance_field

    grid = _rooms_grid()
    start = (1.0, 3.0)
    wardrobe = (9.0, 3.0)
    # The oracle saw the wardrobe from (5.0, 3.0) (say, over a low wall): that view is reachable.
    field_m = evidence_distance_field(grid, wardrobe, 0.2, [(6.2, 0.0, 10.0, 6.0)],
                                      start_xy=start, views=[(5.0, 3.0)])
    distance = EvidenceDistance(grid, field_m, 0.2)
    assert distance.reachable
    assert abs(distance(start) - (4.0 + 4.0)) < 0.05  # walk to the view, then 4 m of sight
    prompts = [PromptPoint("A", (2.0, 1.0), (10, 10)), PromptPoint("B", (4.0, 3.0), (20, 10))]
    score = OracleScorer(distance, lambda inst: False).score(_prompt_obs(*start), prompts, "q")
    assert score.letters == {"A": 0.0, "B": 1.0}
    # A view inside the pocket is no reachable view.
    assert np.isinf(evidence_distance_field(grid, wardrobe, 0.2, [(6.2, 0.0, 10.0, 6.0)],
                                            start_xy=start, views=[(8.0, 3.0)])).all()


def test_tied_letters_share_the_confidence():
    prompts = [PromptPoint("A", (4.0, 3.0), (10, 10)), PromptPoint("B", (4.0, -3.0), (20, 10)),
               PromptPoint("C", (0.0, 0.0), (30, 10))]
    score = _scorer().score(_obs(0.0, seen=False), prompts, "q")
    assert score.letters == {"A": 0.5, "B": 0.5, "C": 0.0}


def test_no_finite_distance_is_no_information_not_letter_a():
    prompts = [PromptPoint("A", (4.0, 3.0), (10, 10)), PromptPoint("B", (6.0, 0.0), (20, 10))]
    blind = OracleScorer(lambda xy: math.inf, lambda inst: bool((inst == 7).any()))
    score = blind.score(_obs(3.0, seen=False), prompts, "q")
    assert score.letters == {"A": 0.5, "B": 0.5} and score.p_yes == 0.0
    assert score.info["unreachable"]
    # Seeing the evidence is still worth it, reachable views or not.
    assert blind.score(_obs(3.0, seen=True), prompts, "q").p_yes == 1.0
