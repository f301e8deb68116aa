import numpy as np

from efficienteqa.envs.base import Observation
from efficienteqa.explore.oracle import OracleScorer
from efficienteqa.explore.prompting import PromptPoint
from efficienteqa.geometry import Pose2D

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
