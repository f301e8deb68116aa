"""What the experiments share: house seed sets, the evidence's path distance, the AUC, and one
exploration episode run by the agent's own loop (``efficienteqa.agent.Agent``).

An exploration episode here is the agent without its language model: the semantic perception
(the simulator's labels as text), a semantic scorer given by the experiment (the ground-truth
oracle, a model-free direction scorer, a recorder) or none (frontier-only, random), the early
stop off (``StopConfig(enabled=False)``), no gate, and a stub answer at the end. What the
experiments measure (when the evidence is first in view, floor coverage, refused moves, the
time a step takes) is read from the agent's per-step hook and its records.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import rankdata

from efficienteqa.agent import Agent, AgentConfig
from efficienteqa.answer.rag import RagAnswerer
from efficienteqa.config.knobs import with_leaves
from efficienteqa.datasets.synthetic import parse_seeds
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M
from efficienteqa.envs.synthetic.questions import Question
from efficienteqa.explore.module import ExploreStep, SemanticScorer
from efficienteqa.explore.oracle import EvidenceDistance, evidence_distance_field
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.maps2d import Mapper
from efficienteqa.mapping.state import MapState
from efficienteqa.models.stub import StubChatModel
from efficienteqa.observation import Observation
from efficienteqa.perception.semantic import SemanticPerception
from efficienteqa.reading.target import TargetReading
from efficienteqa.relevancy.text import WordOverlapScorer
from efficienteqa.stop.rules import StopConfig
from efficienteqa.trace import StepRecord
from efficienteqa.vc.grouping import RuleGrouper

TRAINING_SEEDS = range(0, 21)  # development houses: tuned on
HELD_OUT_SEEDS = range(2000, 3000)  # never used for tuning


def seed_set(spec: str) -> list[int]:
    """"training" (0-20), "held-out" (2000-2999), or explicit seeds ("0-9", "3,5")."""
    named = {"training": TRAINING_SEEDS, "held-out": HELD_OUT_SEEDS}
    return list(named[spec]) if spec in named else parse_seeds(spec)


def auc(scores: Sequence[float], right: Sequence[bool]) -> float | None:
    """P(score of a right answer > score of a wrong one), ties counting 1/2 (the Mann-Whitney
    U over n_right * n_wrong, by average ranks). None when either side is empty."""
    if len(scores) != len(right):
        raise ValueError("one label per score")
    pos = np.asarray(right, bool)
    n_pos, n_neg = int(pos.sum()), int((~pos).sum())
    if n_pos == 0 or n_neg == 0:
        return None
    ranks = rankdata(np.asarray(scores, float))
    return float((ranks[pos].sum() - n_pos * (n_pos + 1) / 2) / (n_pos * n_neg))


def evidence_centre(env: SyntheticEnv, q: Question) -> np.ndarray:
    """The mean (x, y) of the question's evidence objects, metres."""
    return np.mean([[o.x, o.y] for o in (env.house.object(e) for e in q.evidence)], axis=0)


def evidence_distance(env: SyntheticEnv, q: Question) -> EvidenceDistance:
    """Path distance to the evidence's views reachable from the start: the floor near it in its
    own room(s) (a plain snap to the nearest floor cell can land behind a wall) and the oracle's
    pose; a point off the navigable floor counts from the nearest navigable cell (see
    explore/oracle.py). ``reachable`` is False when no view is reachable from the start."""
    objects = [env.house.object(e) for e in q.evidence]
    rooms = {(r.x0, r.y0, r.x1, r.y1) for r in (env.house.room(o.room_id) for o in objects)}
    start = (env.house.start.x, env.house.start.y)
    views = [q.oracle_pose[:2]] if q.oracle_pose else []
    field_m = evidence_distance_field(env.grid, evidence_centre(env, q), ROBOT_RADIUS_M,
                                      sorted(rooms), 2.0, start_xy=start, views=views)
    return EvidenceDistance(env.grid, field_m, ROBOT_RADIUS_M)


def truth_floor(env: SyntheticEnv, mapper: Mapper | None = None,
                config: AgentConfig | None = None) -> np.ndarray:
    """Ground-truth free floor sampled at the cell centres of the agent's map of ``env`` (as
    ``config`` lays it out: around the start, or over the scene's box)."""
    from efficienteqa.agent import map_around, mapper_for

    explore = (config or AgentConfig()).explore
    start = (env.start.x, env.start.y)
    mapper = mapper or (map_around(start, explore.map_size_m) if explore.map_extent == "start"
                        else mapper_for(env, start))
    xs, ys = mapper.spec.centres()
    i, j = env.grid.spec.world_to_cell(np.stack([xs, ys], axis=-1))
    ok = env.grid.spec.contains((i, j))
    out = np.zeros(xs.shape, bool)
    out[ok] = env.grid.free[i[ok], j[ok]]
    return out


NEAR_M = 2.0  # "near the evidence": within this path distance
IDLE_M, IDLE_RAD = 0.01, 1e-3  # a pose this close to the step before's is the same view again


def idle_steps(poses: Sequence[tuple[float, float, float]]) -> list[int]:
    """The steps (1-based; poses[0] is step 1) whose pose and view are the step before's again:
    a move that ended where the robot stood, facing as it faced (refused moves included)."""
    return [k + 1 for k in range(1, len(poses))
            if math.dist(poses[k][:2], poses[k - 1][:2]) < IDLE_M
            and abs(math.remainder(poses[k][2] - poses[k - 1][2], math.tau)) < IDLE_RAD]


@dataclass
class Episode:
    """What an exploration episode showed. Steps count as the agent counts them (the start
    view is step 1)."""

    coverage: list[float] = field(default_factory=list)  # explored floor share after each step
    first_seen: int | None = None
    first_near: int | None = None  # first step within NEAR_M (path) of the evidence
    steps: int = 0
    step_ms: list[float] = field(default_factory=list)  # the explore module's time per step
    moves: int = 0  # moves asked of the environment (re-planned tries included)
    refused: int = 0  # of which the environment refused
    lost: int = 0  # steps whose every try was refused: the robot stayed
    asked: int = 0  # steps that offered lettered directions to the scorer
    points: int = 0  # prompted points
    off_floor: int = 0  # of which not navigable on the true grid
    uninformed: int = 0  # asked steps where no point had a finite oracle distance
    explored: int | None = None  # the step at which the explorer found nothing left to explore
    poses: list[Pose2D] = field(default_factory=list)  # the robot's pose at each step
    state: MapState | None = None  # the final map (None: ended at the first sight)


class _Seen(Exception):
    """Raised by the step hook to end an episode at the first sight of the evidence."""


def explore_episode(env: SyntheticEnv, config: AgentConfig, question: str = "What is in the house?",
                    scorer: SemanticScorer | None = None,
                    seen: Callable[[np.ndarray], bool] | None = None,
                    near: Callable[[tuple[float, float]], float] | None = None,
                    coverage: bool = False, to_budget: bool = False,
                    on_step: Callable[[StepRecord, Observation, ExploreStep | None], None] | None = None,
                    reading: TargetReading | None = None) -> Episode:
    """One episode of the agent's loop with ``config`` (its explorer, seed, budget, prompts,
    exploration options, steering) and ``scorer`` as its semantic scorer; the early stop is
    off. It ends at the budget, when nothing is left to explore, or, unless ``to_budget``,
    when ``seen`` (of a frame's instance ids) first holds, before that step's move. ``near``:
    the path distance to the evidence of a point (``first_near``); ``coverage``: the floor
    share explored after each step; ``on_step``: called with the agent's hook arguments first;
    ``reading``: a reading by rules and words that adds the named room's neighbours
    (``TargetConfig.near_rooms``).
    """
    # No language model here: the question is read by rules, its words matched as words.
    config = with_leaves(config, stop=StopConfig(enabled=False), gate="none", reading="rules",
                     matching="words")
    perception = SemanticPerception(env.scene_labels())
    answerer = RagAnswerer(StubChatModel(lambda messages: "unknown"), RuleGrouper(), m=1,
                           direct=True)
    agent = Agent(perception, scorer, WordOverlapScorer(), answerer, config, reading=reading)
    floor = truth_floor(env, config=config) if coverage else None
    ep = Episode()
    moved: list[StepRecord] = []  # steps whose decision sent the robot on (filled in after)

    def hook(record: StepRecord, obs: Observation, out: ExploreStep | None) -> None:
        if on_step is not None:
            on_step(record, obs, out)
        ep.steps = record.step
        ep.poses.append(obs.pose)
        if ep.first_near is None and near is not None and near((obs.pose.x, obs.pose.y)) <= NEAR_M:
            ep.first_near = record.step
        sight = ep.first_seen is None and seen is not None and seen(obs.instance)
        if sight:
            ep.first_seen = record.step
        if out is None:
            return
        if floor is not None:
            ep.coverage.append(out.state.explored_floor_share(floor))
        if sight and not to_budget:
            raise _Seen
        ep.step_ms.append(record.timings_ms["explore"])
        if out.prompts:
            ep.asked += 1
            ep.points += len(out.prompts)
            ep.off_floor += sum(not env.is_navigable(*p.xy) for p in out.prompts)
            ep.uninformed += bool(out.score and "unreachable" in out.score.info)
        if not out.decision.done:
            moved.append(record)

    try:
        result = agent.run(env, question, on_step=hook, budget=config.budget(env))
    except _Seen:
        pass
    else:
        ep.state = result.state
        if result.stop_reason in ("explored", "searched"):
            ep.explored = result.steps
        if floor is not None and len(ep.coverage) < ep.steps:  # the last frame, not planned on
            ep.coverage.append(result.state.explored_floor_share(floor))
    for r in moved:  # the agent fills in a step's refusals after its hook
        ep.moves += r.refused + (not r.blocked)
        ep.refused += r.refused
        ep.lost += r.blocked
    return ep
