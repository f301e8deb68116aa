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
