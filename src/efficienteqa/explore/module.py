"""The explore module of the paper, one step at a time (DESIGN 3.2-3.3).

Per observation: fuse the frame into the map, pick lettered candidate directions, ask the
semantic scorer for the local (per letter) and global values, paint SV = LSV * GSV into the
value map, and let the explorer choose the next pose. The scorer is a protocol: a VLM with
verbalized confidence in the agent, ground truth in the benchmarks.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from efficienteqa.envs.base import Environment
from efficienteqa.explore.base import Decision, Explorer
from efficienteqa.explore.prompting import PromptConfig, prompt_points
from efficienteqa.explore.settings import REFUSAL_RETRIES, VALUE_WARMUP_STEPS
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.maps2d import MAX_INVALID_FRACTION, Mapper
from efficienteqa.mapping.state import MapState
from efficienteqa.mapping.values import SemanticValueMap, gsv_from_yes, lsv_from_confidences
from efficienteqa.observation import Observation, PromptPoint
from efficienteqa.perception.base import Sightings
from efficienteqa.question import Target


@dataclass
class SemanticScore:
    """What the scorer said about one frame: confidence per letter and P(worth exploring)."""

    letters: dict[str, float]
    p_yes: float
    info: dict = field(default_factory=dict)


@runtime_checkable
class Steered(Protocol):
    """An explorer that steers by the question's target and what frames show of it."""

    def set_target(self, target: Target) -> None: ...

    def see(self, spec: GridSpec, seen: Sightings) -> None: ...


class SemanticScorer(Protocol):
    def score(self, obs: Observation, prompts: list[PromptPoint], question: str) -> SemanticScore:
        ...


@dataclass
class ExploreStep:
    """Everything the explore module did on one observation."""

    step: int
    state: MapState
    decision: Decision
    prompts: list[PromptPoint]
    lsv: dict[str, float]
    gsv: float | None
    score: SemanticScore | None
    # The smoothed semantic value map after this step's painting (what the explorer reads from
    # the warm-up on), for pictures; None without a scorer.
    values: np.ndarray | None = None


class ExploreModule:
    """Map + prompts + semantic values + explorer. ``scorer=None`` explores without semantics
    (the frontier-only and random references)."""

    def __init__(self, mapper: Mapper, explorer: Explorer, scorer: SemanticScorer | None = None,
                 values: SemanticValueMap | None = None, seed: int = 0,
                 prompts: PromptConfig | None = None, target: Target | None = None) -> None:
        self.mapper, self.explorer, self.scorer = mapper, explorer, scorer
        self.prompt_config = prompts or PromptConfig()
        self.values = values if values is not None else SemanticValueMap(mapper.spec)
        self.seed = seed
        explorer.reset(seed)
        if target is not None and isinstance(explorer, Steered):
            explorer.set_target(target)

    def step(self, obs: Observation, step: int, question: str = "",
             sightings: Sightings | None = None) -> ExploreStep:
        """``sightings``: what the frame shows of the question's target, for an explorer that
        steers by it (``explore.target``); ignored by the others."""
        state = self.mapper.update(obs)
        if sightings is not None and isinstance(self.explorer, Steered):
            self.explorer.see(state.spec, sightings)
        prompts: list[PromptPoint] = []
        lsv: dict[str, float] = {}
        gsv = score = None
        if self.scorer is not None and obs.invalid_fraction < MAX_INVALID_FRACTION:
            h, w = obs.depth_m.shape
            prompts = prompt_points(state, obs.cam_to_world, obs.intrinsics, (w, h),
                                    np.random.default_rng([self.seed, step]), self.prompt_config)
            if prompts:
                score = self.scorer.score(obs, prompts, question)
                letters = [p.letter for p in prompts]
                lsv = lsv_from_confidences(score.letters, letters)
                gsv = gsv_from_yes(score.p_yes)
                self.values.paint([p.xy for p in prompts], [lsv[p.letter] * gsv for p in prompts])
        values = self.values.smoothed() if self.scorer is not None else None
        decision = self.explorer.decide(state, obs.pose,
                                        values if step > VALUE_WARMUP_STEPS else None, step)
        return ExploreStep(step, state, decision, prompts, lsv, gsv, score, values)

    def blocked(self, pose_xy: tuple[float, float], radius_m: float = 0.3) -> None:
        """The environment refused a move there: keep the planner away from it."""
        self.mapper.block(pose_xy, radius_m)

    def replan(self, pose: Pose2D, step: int) -> Decision:
        """Decide again on the map as it is (a refused move learnt): no frame is fused and no
        scorer is asked, so a retry costs no step and no model call."""
        state = self.mapper.state((pose.x, pose.y))
        use_values = self.scorer is not None and step > VALUE_WARMUP_STEPS
        return self.explorer.decide(state, pose, self.values.smoothed() if use_values else None,
                                    step)




@dataclass
class Moved:
    """The outcome of ``move``: the observation after it, the decision carried out (the last
    one tried when every try was refused), and the refusals on the way."""

    obs: Observation
    info: dict
    decision: Decision
    refused: int

    @property
    def blocked(self) -> bool:
        return bool(self.info.get("blocked"))


def move(env: Environment, explore: ExploreModule, pose: Pose2D, decision: Decision, step: int,
         retries: int = REFUSAL_RETRIES) -> Moved:
    """Ask ``env`` to move to ``decision.pose``; when it refuses, mark the spot blocked on the
    map and re-plan from ``pose`` within the same step, at most ``retries`` times (0: a
    refused move spends the step, as the paper's loop would). A re-plan that finds nothing
    left to explore ends the tries; the caller sees it as ``decision.done``."""
    refused = 0
    while True:
        obs, _, _, _, info = env.step(decision.pose)
        if not info.get("blocked"):
            return Moved(obs, info, decision, refused)
        refused += 1
        explore.blocked((decision.pose.x, decision.pose.y))
        if refused > retries:
            return Moved(obs, info, decision, refused)
        decision = explore.replan(pose, step)
        if decision.done:
            return Moved(obs, info, decision, refused)
