"""What an episode leaves behind: a ``StepRecord`` per step (the frame's Sim and stop check,
the gate's verdict, the explore module's prompts, values and decision, the move and its
refusals, the model calls and timings) and the ``EpisodeResult`` at its end. ``agent.Agent``
fills them; the reports, the evaluation and the recorded-walk tools read them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from efficienteqa.explore.base import Decision
from efficienteqa.explore.module import ExploreStep
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.state import MapState
from efficienteqa.observation import Observation
from efficienteqa.question import Target
from efficienteqa.stop.rules import StopCheck
from efficienteqa.vc.parse import AnswerResult


@dataclass
class StepRecord:
    """What happened at one step. Poses are (x, y, yaw) in metres and radians."""

    step: int
    pose: tuple[float, float, float]
    valid: bool
    check: StopCheck | None = None
    prompts: list[dict[str, Any]] = field(default_factory=list)
    lsv: dict[str, float] = field(default_factory=dict)
    gsv: float | None = None
    p_yes: float | None = None
    frontier_xy: tuple[float, float] | None = None
    target_xy: tuple[float, float] | None = None
    n_frontiers: int = 0
    decision: str = ""
    blocked: bool = False  # the step's move was refused, every try: the robot stayed
    short: bool = False  # the move ended away from its goal (a robot's navigation stopped short)
    refused: int = 0  # moves the environment refused during this step (re-planned or not)
    calls: list[int] = field(default_factory=list)  # indices into the model exchanges
    timings_ms: dict[str, float] = field(default_factory=dict)
    step_answer: dict[str, Any] | None = None  # answer_at="best-step": answer, confidence, value
    gate: dict[str, Any] | None = None  # the answerability gate's verdict ("ok", "why"): every
    # frame with a rules gate, the frames the stop flagged with a model gate
    # What the step's model replies did not say plainly: the explore call's, and the relevancy
    # and gate calls' (an unreadable relevancy reply leaves ``check`` None: Sim is missing).
    explore_problems: list[str] = field(default_factory=list)
    relevancy_problems: list[str] = field(default_factory=list)


@dataclass
class EpisodeResult:
    question: str
    answer: str
    confidence: float
    steps: int
    stop_reason: str
    budget: int
    records: list[StepRecord]
    retrieved: list[tuple[int, float]]  # (step, Sim) of the top-K frames, best first
    answer_result: AnswerResult
    wall_s: float
    answer_s: float
    state: MapState  # the final map, for pictures
    values: np.ndarray
    last_decision: Decision | None
    target: Target = field(default_factory=Target)  # the question's target, as parsed

    @property
    def trajectory(self) -> list[Pose2D]:
        return [Pose2D(*r.pose) for r in self.records]

    @property
    def refused_moves(self) -> int:
        return sum(r.refused for r in self.records)


StepHook = Callable[[StepRecord, Observation, ExploreStep | None], None]



def fill_explore(record: StepRecord, out: ExploreStep) -> None:
    """``record`` filled with what the explore module did at its step."""
    record.explore_problems = list(out.score.info.get("problems") or []) if out.score else []
    record.prompts = [{"letter": p.letter, "xy": p.xy, "pixel": p.pixel} for p in out.prompts]
    record.lsv, record.gsv = dict(out.lsv), out.gsv
    record.p_yes = out.score.p_yes if out.score is not None else None
    fill_decision(record, out.decision)


def fill_decision(record: StepRecord, d: Decision) -> None:
    """``record`` filled with the decision it acted on."""
    record.frontier_xy = d.frontier.xy if d.frontier is not None else None
    record.target_xy = d.target_xy
    record.n_frontiers = len(d.frontiers)
    record.decision = d.reason
