"""The EfficientEQA agent: explore -> stop -> answer, composed from injected parts.

Per step t (the start view is step 1; DESIGN 3.1):
1. the frame's relevancy ``Sim(I_t, Q)`` is checked against the earlier frames (stop module);
   an outlier from ``stop.min_step`` on (the paper's 10; 2 past the default gate) ends
   exploration;
2. otherwise the explore module fuses the frame into the map, asks the scorer for semantic
   values and picks the next pose, and the robot moves there.
Then the K most relevant frames of the whole history answer the question (answer module).
Frames with >= 50% invalid depth are mapped but never reach a model.

The ExploreEQA baselines are configurations of the same loop (DESIGN 3.6): no early stop, and
``answer_at="best-step"``: the episode's answer is the one of the frame with the highest
relevancy x confidence. The model answers the frames after exploration, most relevant first,
until none left can win (``answer.best_step``): the answer of asking at every step, in fewer calls.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from efficienteqa.answer.best_step import StepAnswer, StepFrame, best_step_answer
from efficienteqa.answer.confident import confident_probability
from efficienteqa.answer.config import AnswerConfig
from efficienteqa.answer.rag import RagAnswerer, TopK, View
from efficienteqa.config.knobs import with_leaves
from efficienteqa.envs.base import Environment, Observation, SimulatedScene, is_recording
from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.base import Decision
from efficienteqa.explore.config import ExploreConfig
from efficienteqa.explore.module import (
    ExploreModule,
    ExploreStep,
    SemanticScorer,
    Steered,
    move,
)
from efficienteqa.explore.prompting import PROMPT_CONFIGS
from efficienteqa.explore.registry import make_explorer
from efficienteqa.explore.sfe import FrontierExplorer
from efficienteqa.explore.target import TargetExplorer
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.extent import volume_around
from efficienteqa.mapping.instances import asked_count
from efficienteqa.mapping.maps2d import MAX_INVALID_FRACTION, Mapper
from efficienteqa.mapping.state import MapState
from efficienteqa.mapping.tsdf import VolumeSpec
from efficienteqa.models.recording import RecordingChatModel
from efficienteqa.perception.base import Perception
from efficienteqa.question import Target, parse_question, perceived_words
from efficienteqa.reading.target import TargetReading
from efficienteqa.relevancy.base import RelevancyScorer, check_question
from efficienteqa.stop.gate import AnswerGate
from efficienteqa.stop.rules import (
    PAPER_MIN_STEP,
    RelevancyStopper,
    StopCheck,
    StopConfig,
    env_step_budget,
    gated_stop,
    step_budget,
)
from efficienteqa.trace import EpisodeResult, StepHook, StepRecord, fill_decision, fill_explore
from efficienteqa.vc.parse import AnswerResult

# Why exploration ended: a relevancy outlier (z > Z_th, past the gate when there is one), the
# step budget, no frontier left, (the "target" explorer) the named room searched in vain, or
# the end of a recorded walk.
STOP_REASONS = ("relevancy", "budget", "explored", "searched", "ended")


@dataclass(frozen=True)
class AgentConfig:
    """Every knob of an episode, one section per module of the paper: ``explore`` (DESIGN
    3.2-3.3), ``stop`` with its answerability gate (3.4), ``answer`` (3.5). Ablations are values
    here. Each default is a value, written once in its section and recorded in run.json as it
    is (a run that types the default is the same run). The stop section's default has the
    gated floor (``min_step`` 2): the default gate judges every frame, so no step-10 floor is
    needed (DESIGN 9)."""

    explore: ExploreConfig = field(default_factory=ExploreConfig)
    stop: StopConfig = field(default_factory=gated_stop)
    answer: AnswerConfig = field(default_factory=AnswerConfig)

    @classmethod
    def of(cls, **values: Any) -> AgentConfig:
        """The defaults with settings given by their names (``knobs.with_leaves``):
        ``AgentConfig.of(top_k=10, gate="none")``."""
        return with_leaves(cls(), **values)

    def budget(self, env: Environment) -> int | None:
        """The step budget an evaluation gives an episode in ``env``: ``max_steps``, or the
        scene's (``stop.env_step_budget``); for a recording, its length (or ``max_steps`` when
        fewer); None where the environment knows no floor area (a robot): the agent then
        budgets by the floor it has seen."""
        steps = self.explore.max_steps
        if is_recording(env):
            return recording_budget(steps, env)
        return steps if steps is not None else env_step_budget(env)


def recording_budget(steps: int | None, env: Environment) -> int:
    """A recorded walk's budget: its length, or ``steps`` when fewer."""
    length: int = env.length  # type: ignore[attr-defined]
    return length if steps is None else min(steps, length)


# The paper's algorithm (DESIGN 3.2-3.5) with every option beyond it off: what `--preset paper`
# sets besides the back-ends (with the VLM as explore scorer), `--preset paper-offline`
# (config/toml/paper-offline.toml, tests/test_presets.py holds them equal), and what a table calls
# "paper configuration".
PAPER_CONFIG = AgentConfig.of(rule="paper", min_step=PAPER_MIN_STEP, gate="none",
                              refusal_retries=0, stop_clearance_m=0.0, prompts="paper",
                              distinct_views=False, exploration="paper", answer="paper",
                              steering="none", reading="rules", matching="words",
                              question_words="asked")


def mapper_for(env: SimulatedScene, start_xy: tuple[float, float], **options: Any) -> Mapper:
    """A map over a simulated scene's bounds with the floor at the bottom of the bounds, for
    experiments that compare maps with the scene's truth; ``options`` go to ``Mapper`` (e.g.
    ``explored_window``). The agent's own map is ``map_around``: no scene box."""
    lo, hi = env.bounds
    floor_z = float(lo[2])
    return Mapper(VolumeSpec.around(lo[:2], hi[:2], floor_z=floor_z), floor_z=floor_z,
                  start_xy=start_xy, **options)


def map_around(start_xy: tuple[float, float], size_m: float) -> Mapper:
    """The agent's map: a ``size_m`` square around the start, the floor at z = 0."""
    return Mapper(volume_around(start_xy, size_m), floor_z=0.0, start_xy=start_xy)


def seen_budget(state: MapState) -> int:
    """DESIGN 3.1's budget on the free floor ``state`` has seen: what a robot that knows no
    floor area budgets by (it grows as the map does)."""
    cell = state.spec.resolution_m
    return step_budget(max(float(state.free.sum()) * cell * cell, cell * cell))


@dataclass
class _Episode:
    """What one episode carries from step to step (``Agent.run``): the question, as read and as
    the relevancy reads it, the explorer, the stop rule, the gate and the frames it may judge,
    the top-K heap, the step budget, and how it ended."""

    question: str
    scored: str
    target: Target
    explore: ExploreModule
    recorded: bool
    fixed: int | None  # the budget given (None: re-read from the floor seen, every step)
    budget: int
    stopper: RelevancyStopper
    top: TopK[str | np.ndarray]
    gate: AnswerGate | None
    sightings: Callable[..., Any] | None
    remember: Callable[..., Any] | None
    candidates: list[StepFrame[str | np.ndarray]] = field(default_factory=list)
    records: list[StepRecord] = field(default_factory=list)
    frames: dict[int, str | np.ndarray] = field(default_factory=dict)  # frames a model gate judges
    decision: Decision | None = None
    stop_reason: str = "budget"


class Agent:
    """``scorer`` None explores without semantic values (the frontier-only reference).
    ``exchanges``: the recording wrapper of the model the scorer and answerer call, so each
    step knows its model calls."""

    def __init__(self, perception: Perception, scorer: SemanticScorer | None,
                 relevancy: RelevancyScorer, answerer: RagAnswerer,
                 config: AgentConfig | None = None,
                 exchanges: RecordingChatModel | None = None,
                 gate: AnswerGate | None = None, reading: TargetReading | None = None) -> None:
        if relevancy.modality == "text" and perception.modality != "text":
            raise ValueError(f"relevancy scorer {relevancy.name!r} reads text, but perception "
                             f"{perception.name!r} gives images")
        self.perception, self.scorer, self.relevancy = perception, scorer, relevancy
        self.answerer = answerer
        self.config = config or AgentConfig()
        self.exchanges = exchanges
        self.gate = gate
        if self.config.stop.gate in ("rules", "model") and gate is None:
            raise ValueError(f"config asks for the {self.config.stop.gate!r} gate, and none was given")
        self.reading = reading
        if (self.config.explore.reading, self.config.explore.matching) != ("rules", "words") and (
                reading is None or (reading.reading, reading.matching)
                != (self.config.explore.reading, self.config.explore.matching)):
            raise ValueError(f"config asks for the {self.config.explore.reading!r} reading and "
                             f"{self.config.explore.matching!r} matching, and no such reading was given")

    def _map(self, env: Environment, start_xy: tuple[float, float]) -> Mapper:
        """The episode's empty map: around the start, or (``map_extent`` "scene", to re-run a
        run recorded before format 4) over a simulated scene's box."""
        explore = self.config.explore
        if explore.map_extent == "start":
            return map_around(start_xy, explore.map_size_m)
        if not isinstance(env, SimulatedScene):
            raise EfficientEQAError("explore.map-extent scene maps a simulated scene's box, and "
                                    "this environment has none",
                                    fix="use --explore.map-extent start")
        return mapper_for(env, start_xy)

    def _phase(self, name: str) -> AbstractContextManager[None]:
        return self.exchanges.in_phase(name) if self.exchanges is not None else nullcontext()

    def _calls_since(self, n: int) -> list[int]:
        return list(range(n, len(self.exchanges.exchanges))) if self.exchanges is not None else []

    def _problems_said(self) -> tuple[int, int, int]:
        """How many problems the relevancy scorer, the gate and the model's sightings have
        noted so far."""
        return (len(getattr(self.relevancy, "problems", ())),
                len(getattr(self.gate, "problems", ())),
                len(getattr(self.perception, "problems", ())))

    def _problems_since(self, said: tuple[int, int, int]) -> list[str]:
        """The problems noted since ``_problems_said``."""
        return [*getattr(self.relevancy, "problems", [])[said[0]:],
                *(f"gate: {p}" for p in getattr(self.gate, "problems", [])[said[1]:]),
                *(f"sightings: {p}" for p in getattr(self.perception, "problems", [])[said[2]:])]

    def _n_calls(self) -> int:
        return len(self.exchanges.exchanges) if self.exchanges is not None else 0

    def run(self, env: Environment, question: str, start: Pose2D | None = None,
            on_step: StepHook | None = None, budget: int | None = None) -> EpisodeResult:
        """One episode in ``env``. The agent reads only what a robot gives: observations and
        what each move did. ``budget``: the step budget an evaluation sets (its scene's, see
        ``AgentConfig.budget``); else ``explore.max_steps``; else ``step_budget`` of the free
        floor the map has seen so far, re-read every step."""
        question = check_question(question)
        t0 = time.perf_counter()
        ep, obs = self._begin(env, question, start, budget)
        step = 0
        while step < ep.budget:
            step += 1
            record = StepRecord(step, (obs.pose.x, obs.pose.y, obs.pose.yaw),
                                valid=obs.invalid_fraction < MAX_INVALID_FRACTION)
            ep.records.append(record)
            n_calls, said = self._n_calls(), self._problems_said()
            self._stop(ep, record, obs)  # 1. stop (DESIGN 3.4): this frame's Sim, an outlier?
            record.relevancy_problems = self._problems_since(said)
            if ep.stop_reason == "relevancy" or step == ep.budget:
                ep.explore.mapper.update(obs)  # the last frame is on the final map too
                record.calls = self._calls_since(n_calls)
                _notify(on_step, record, obs, None)
                if ep.recorded and ep.stop_reason != "relevancy" and step == env.length:  # type: ignore[attr-defined]
                    ep.stop_reason = "ended"
                break
            if ep.recorded:  # map the frame, then read the next one: the walk goes where it went
                ep.explore.mapper.integrate(obs)
                record.calls = self._calls_since(n_calls)
                _notify(on_step, record, obs, None)
                obs, _, ended, _, _ = env.step(obs.pose)
                if ended:
                    ep.stop_reason = "ended"
                    break
                continue
            # 2. explore (DESIGN 3.2-3.3): map the frame, choose the next pose, move there
            obs, ended = self._explore(ep, env, record, obs, n_calls, on_step)
            if ended:
                break
        result, retrieved, answer_s = self._answer(ep)  # 3. answer (DESIGN 3.5)
        state = ep.explore.mapper.state((obs.pose.x, obs.pose.y))
        return EpisodeResult(question, result.answer, result.confidence, len(ep.records),
                             ep.stop_reason, ep.budget, ep.records, retrieved,
                             result, time.perf_counter() - t0, answer_s, state,
                             ep.explore.values.smoothed(), ep.decision, ep.target)

    def _begin(self, env: Environment, question: str, start: Pose2D | None,
               budget: int | None) -> tuple[_Episode, Observation]:
        """The episode's parts, before its first step: the scene reset, the explorer (steered
        by the question's target where configured), the target read once, the stop rule, the
        gate, the top-K heap and the step budget; and the first observation."""
        cfg = self.config
        fixed = budget if budget is not None else cfg.explore.max_steps
        if fixed is not None and fixed < 1:
            raise ValueError(f"the step budget must be at least 1, not {fixed}")
        recorded = is_recording(env)  # a walk recorded beforehand: read in order, no moves
        if recorded:
            fixed = recording_budget(fixed, env)
        obs, _ = env.reset(options={"start": start} if start is not None else None)
        reset = getattr(self.perception, "reset", None)  # a perception that keeps what it saw
        if reset is not None:  # over an episode (pixels' room votes) starts afresh
            reset()
        explorer = make_explorer(cfg.explore.explorer, **cfg.explore.explorer_options())
        if cfg.explore.steering == "target" and isinstance(explorer, FrontierExplorer):
            explorer = TargetExplorer(explorer, cfg.explore.target_config())
        with self._phase("question"):
            reads_target = cfg.explore.steering != "none" or cfg.stop.gate != "none"
            target = (self.reading.target(question)
                      if self.reading is not None and reads_target else parse_question(question))
        prompts = PROMPT_CONFIGS[cfg.explore.prompts]
        if self.perception.modality == "text":  # no circles are drawn: none can overlap
            prompts = replace(prompts, min_px=0.0)
        explore = ExploreModule(self._map(env, (obs.pose.x, obs.pose.y)), explorer,
                                self.scorer, seed=cfg.explore.seed, prompts=prompts, target=target)
        ask_about = getattr(self.perception, "ask_about", None)  # model sightings: the question
        if ask_about is not None:
            ask_about(question)
        gate = self.gate if cfg.stop.gate != "none" else None
        if gate is not None:
            gate.reset()
        ep = _Episode(
            question=question, target=target, explore=explore, recorded=recorded, fixed=fixed,
            gate=gate, stopper=RelevancyStopper(cfg.stop), top=TopK(cfg.answer.top_k),
            # what the relevancy reads (StopConfig.question_words)
            scored=(perceived_words(question, target) if cfg.stop.question_words == "perceived"
                    else question),
            sightings=(getattr(self.perception, "sightings", None)
                       if isinstance(explorer, Steered) and not recorded else None),
            # a count question: each frame's objects go to the perception's instance map, which
            # the gate and the answer's count read (StopConfig.count_from)
            remember=(getattr(self.perception, "instances_seen", None)
                      if cfg.stop.count_from == "instances" and target.kind == "count" else None),
            budget=fixed if fixed is not None else seen_budget(explore.mapper.state(
                (obs.pose.x, obs.pose.y))))
        return ep, obs

    def _stop(self, ep: _Episode, record: StepRecord, obs: Observation) -> None:
        """The stop module on one frame: its Sim against the question, the gate's verdict, the
        stop rule's check (``record.check``), the frame offered to the top-K heap; an outlier
        that passes the gate sets ``ep.stop_reason``."""
        if not record.valid:
            return
        cfg, step = self.config, record.step
        t = time.perf_counter()
        frame = self.perception.frame(obs)
        if ep.remember is not None:
            with self._phase(f"step {step}"):  # model sightings are a call
                ep.remember(obs, ep.target)
        with self._phase(f"step {step}"):  # relevancy may be a model call too
            if self.relevancy.modality == "image":
                sim = self.relevancy.score(ep.scored, image=obs.rgb)
            else:
                sim = self.relevancy.score(ep.scored, text=self.perception.relevancy_text(obs))
        if math.isnan(sim):  # an unreadable reply: no Sim, never an outlier
            record.timings_ms["relevancy"] = 1e3 * (time.perf_counter() - t)
            return
        eligible: bool | None = None
        gate = ep.gate
        if gate is not None and gate.eager:  # a cheap gate judges every frame
            with self._phase(f"step {step}"):  # model sightings are a call
                verdict = gate.check(ep.question, ep.target, obs, frame)
            record.gate = {"ok": verdict.ok, "why": verdict.why}
            eligible = verdict.ok
        record.check = ep.stopper.check(step, sim, eligible)
        if (cfg.stop.gate_final and gate is not None and gate.eager and record.gate
                and verdict.final and cfg.stop.enabled and step >= cfg.stop.min_step):
            record.gate["final"] = True
            record.check = replace(record.check, stop=True, tested_step=step)
        view = (View(obs.pose.x, obs.pose.y, obs.pose.yaw, frame if isinstance(frame, str) else None)
                if cfg.answer.distinct_views else None)
        ep.top.push(sim, step, frame, view)
        record.timings_ms["relevancy"] = 1e3 * (time.perf_counter() - t)
        if cfg.answer.answer_at == "best-step":
            ep.candidates.append(StepFrame(step, sim, frame))
        if gate is not None and not gate.eager:  # a model gate: flagged frames only
            ep.frames[step] = frame
            if record.check.stop:
                record.check = self._gated(record.check, ep.question, ep.target, obs, ep.frames,
                                           ep.records)
        if record.check.stop:
            ep.stop_reason = "relevancy"

    def _explore(self, ep: _Episode, env: Environment, record: StepRecord, obs: Observation,
                 n_calls: int, on_step: StepHook | None) -> tuple[Observation, bool]:
        """The explore module's step (the map, the semantic values, the next pose) and the move
        there; the observation after it, and whether exploration ended (nothing left to explore,
        or the named room searched)."""
        step = record.step
        said = self._problems_said()  # the explore step's own (its model sightings)
        t = time.perf_counter()
        with self._phase(f"step {step}"):
            seen = (ep.sightings(obs, ep.target)
                    if ep.sightings is not None and record.valid else None)
            out = ep.explore.step(obs, step, ep.question, seen)
        record.timings_ms["explore"] = 1e3 * (time.perf_counter() - t)
        record.calls = self._calls_since(n_calls)
        decision = ep.decision = out.decision
        if ep.fixed is None:
            ep.budget = max(step + 1, seen_budget(out.state))
        fill_explore(record, out)
        record.explore_problems += self._problems_since(said)
        _notify(on_step, record, obs, out)
        if decision.done:
            ep.stop_reason = "searched" if decision.reason == "searched" else "explored"
            return obs, True
        t = time.perf_counter()
        moved = move(env, ep.explore, obs.pose, decision, step,
                     self.config.explore.refusal_retries)
        record.timings_ms["env"] = 1e3 * (time.perf_counter() - t)
        record.refused, record.blocked = moved.refused, moved.blocked
        record.short = bool(moved.info.get("short"))  # planned on from where it ended
        if moved.decision is not decision:  # re-planned after a refusal
            ep.decision = moved.decision
            fill_decision(record, moved.decision)
            if moved.decision.done:
                ep.stop_reason = "explored"
                return moved.obs, True
        return moved.obs, False

    def _answer(self, ep: _Episode) -> tuple[AnswerResult, list[tuple[int, float]], float]:
        """The answer module: the K most relevant frames answered (EfficientEQA), or the
        ExploreEQA baselines' best step; with the frames used and the seconds it took."""
        t = time.perf_counter()
        if self.config.answer.answer_at == "best-step":
            best = self._best_step(ep.question, ep.candidates, ep.records)
            if best is None:  # no valid frame at all: nothing was seen
                with self._phase("answer"):
                    result = self.answerer.answer(ep.question, [])
                retrieved = []
            else:
                result, retrieved = best.answer, [(best.step, best.sim)]
        else:
            top_k = ep.top.best()
            counted = (asked_count(getattr(self.perception, "instances", None), ep.target)
                       if self.config.stop.count_from == "instances" else None)
            with self._phase("answer"):
                result = self.answerer.answer(ep.question, [r.item for r in top_k], ep.target,
                                              counted.n if counted is not None else None)
            retrieved = [(r.step, r.sim) for r in top_k]
        return result, retrieved, time.perf_counter() - t

    def _gated(self, check: StopCheck, question: str, target: Target, obs: Observation,
               frames: dict[int, str | np.ndarray], records: list[StepRecord]) -> StopCheck:
        """``check`` with ``stop`` kept only when the gate passes the frame it tested (the
        current one, or under ``lookback`` an earlier one: judged on its kept frame)."""
        assert self.gate is not None
        tested = check.tested_step or check.step
        record = records[tested - 1]
        if record.gate is None:
            verdict = self.gate.check(question, target, obs, frames[tested])
            record.gate = {"ok": verdict.ok, "why": verdict.why}
        return check if record.gate["ok"] else replace(check, stop=False)

    def _best_step(self, question: str, candidates: list[StepFrame[str | np.ndarray]],
                   records: list[StepRecord]) -> StepAnswer | None:
        """ExploreEQA's answer; each step the model answered gets its ``step_answer``."""
        def ask(c: StepFrame[str | np.ndarray]) -> AnswerResult:
            n = self._n_calls()
            with self._phase(f"step {c.step}"):
                said = self.answerer.answer(question, [c.item])
            records[c.step - 1].calls += self._calls_since(n)
            return said

        weights: dict[int, float] = {}
        if self.config.answer.step_weight == "confident":  # ExploreEQA's: the model's own P(yes)
            model = self.answerer.model
            token = self.config.answer.confidence == "token"
            weighed = []
            for c in candidates:
                n = self._n_calls()
                with self._phase(f"step {c.step}"):
                    p, problems = confident_probability(model, question, c.item, token=token)
                record = records[c.step - 1]
                record.calls += self._calls_since(n)
                record.relevancy_problems += [f"confident: {x}" for x in problems]
                weights[c.step] = p
                weighed.append(StepFrame(c.step, p, c.item))
            candidates = weighed
        best, asked = best_step_answer(candidates, ask, every_step=self.config.answer.answer_every_step)
        for a in asked:
            records[a.step - 1].step_answer = {"answer": a.answer.answer,
                                               "confidence": a.answer.confidence, "value": a.value}
        for step, p in weights.items():
            records[step - 1].step_answer = {**(records[step - 1].step_answer or {}),
                                             "weight": p}
        return best


def _notify(hook: StepHook | None, record: StepRecord, obs: Observation,
            out: ExploreStep | None) -> None:
    if hook is not None:
        hook(record, obs, out)
