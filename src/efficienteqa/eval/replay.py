"""Ablations replayed, not re-explored (DESIGN 3.6): the stop for another ``Z_th`` or
stop rule, and the answer for another K, from one episode explored to its budget.

Exploration does not depend on the stop rule or on K: the relevancy stopper only reads the
frames (``agent.Agent.run`` feeds it one Sim per valid frame and nothing else reads its state),
and the top-K heap is filled as the robot goes. So an episode run with ``--stop.no-early-stop``,
whose ``episode.json`` records every step's pose, validity and Sim, holds every shorter
episode: the one that the rule would have stopped is its prefix up to the stop step.

- ``replay_stop`` feeds the recorded Sims of the valid steps, in order, to the stop module's own
  ``RelevancyStopper`` (never a copy of its rule), so a replayed stop equals the live one by
  construction (``tests/test_ablation_replay.py`` checks it against a live episode).
- ``retrieve`` pushes the frames up to a step into the answer module's ``TopK``, with a ``View``
  per frame when views are distinct, exactly as the agent does: the K frames the answer call of
  that shorter episode would have read.
- ``reobserve`` gives the frames' contents back. Frame descriptions are not stored, but the
  synthetic simulator is deterministic: ``SyntheticEnv.observe(Pose2D(x, y, yaw))`` at a
  recorded pose (JSON round-trips floats exactly) renders the frame the agent saw, and the
  stack's perception describes it as the agent did. Checked: on a run of the synthetic split
  (``efficienteqa eval --eval.method frontier-only --eval.dataset synthetic --eval.limit 3
  --stop.no-early-stop``)
  the re-observed descriptions of the retrieved steps, numbered as ``answer.prompting.evidence_text``
  numbers them, are exactly the evidence of the answer prompt stored in ``model.exchanges``
  (``answer_prompt_matches`` checks one episode; the benchmark checks every episode it replays).

Only the answer call of a replayed setting reaches a model (``experiments/ablation_replay.py``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Generic, TypeVar

from efficienteqa.answer.prompting import evidence_text
from efficienteqa.answer.rag import Ranked, TopK, View
from efficienteqa.answer.views import focus_views
from efficienteqa.geometry import Pose2D
from efficienteqa.stop.rules import RelevancyStopper, StopCheck, StopConfig

T = TypeVar("T")


@dataclass(frozen=True)
class RecordedFrame:
    """One valid step of a recorded episode: what the stop rule and retrieval read."""

    step: int
    sim: float
    pose: tuple[float, float, float]
    eligible: bool | None = None  # the rules gate's recorded verdict (None: no gate recorded)


def recorded_frames(per_step: Iterable[Mapping[str, Any]]) -> list[RecordedFrame]:
    """The valid steps of ``episode.json``'s ``per_step``, in order: the frames the agent fed to
    the stop rule and to retrieval (an invalid frame has no Sim and reaches no model)."""
    out = []
    for s in per_step:
        if s.get("valid") and s.get("sim") is not None:
            x, y, yaw = s["pose"]
            gate = s.get("gate")
            eligible = bool(gate["ok"]) if isinstance(gate, Mapping) and "ok" in gate else None
            out.append(RecordedFrame(int(s["step"]), float(s["sim"]), (x, y, yaw), eligible))
    return out


def replay_checks(sims: Sequence[tuple[int, float] | tuple[int, float, bool | None]],
                  config: StopConfig) -> list[StopCheck]:
    """The stop module's check of each ``(step, Sim)`` or ``(step, Sim, eligible)`` (a rules
    gate's verdict, as the agent passes it), in order, up to and including the first that stops
    (all of them when none does)."""
    stopper = RelevancyStopper(config)
    checks = []
    for step, sim, *verdict in sims:
        check = stopper.check(step, sim, verdict[0] if verdict else None)
        checks.append(check)
        if check.stop:
            break
    return checks


def replay_stop(sims: Sequence[tuple[int, float] | tuple[int, float, bool | None]],
                config: StopConfig) -> int | None:
    """The step at which ``config``'s rule stops the robot, given the ``(step, Sim)`` of the valid
    frames in order; None where it never stops within them (the episode then ends as recorded:
    at its budget, or where nothing was left to explore). ``config.enabled`` False never stops,
    as live."""
    checks = replay_checks(sims, config)
    return checks[-1].step if checks and checks[-1].stop else None


def stop_config_for(recorded: StopConfig | Mapping[str, Any], *, z_th: float | None = None,
                    rule: str | None = None, gated: bool = False) -> StopConfig:
    """The stop of a replayed setting: the recorded configuration (``episode.json``'s
    ``config.stop``, recorded with the stop off) switched on, with another threshold or rule.
    ``z_th`` sets the threshold that acts: ``z_gated`` where ``gated`` (the run's gate judged
    every frame, ``stop.rules.z_th_acts``: Z_th decides nothing there), else ``z_th``."""
    base = recorded if isinstance(recorded, StopConfig) else StopConfig(**dict(recorded))
    changes: dict[str, Any] = {"enabled": True}
    if z_th is not None:
        changes["z_gated" if gated else "z_th"] = float(z_th)
    if rule is not None:
        changes["rule"] = rule
    return replace(base, **changes)


@dataclass(frozen=True)
class Stopped:
    """Where a replayed episode ends: ``steps`` taken and why (``agent.STOP_REASONS``)."""

    step: int | None  # the stop step, None where the rule never fired
    steps: int
    reason: str


def replay_episode_stop(per_step: Sequence[Mapping[str, Any]], recorded_reason: str,
                        config: StopConfig) -> Stopped:
    """The replayed stop of one recorded episode (explored without early stop): the relevancy
    stop step, or the recorded end (``len(per_step)`` steps, for the recorded reason). A rules
    gate's verdicts, recorded for every frame, are replayed with the Sims; a model gate's, asked
    only of flagged frames, cannot be."""
    if recorded_reason == "relevancy":
        raise ValueError("this episode stopped early: its frames after the stop were never "
                         "seen, so other stops cannot be replayed (run with --stop.no-early-stop)")
    frames = recorded_frames(per_step)
    step = replay_stop([(f.step, f.sim, f.eligible) for f in frames], config)
    if step is None:
        return Stopped(None, len(per_step), recorded_reason)
    return Stopped(step, step, "relevancy")


@dataclass(frozen=True)
class Frame(Generic[T]):
    """A recorded frame with what the model reads of it: a description (text perception) or
    an image."""

    step: int
    sim: float
    pose: tuple[float, float, float]
    item: T


def retrieve(frames: Iterable[Frame[T]], k: int, upto: int | None = None,
             distinct_views: bool = True) -> list[Ranked[T]]:
    """The top-``k`` frames of the steps up to ``upto`` (all where None), best first, as the
    agent's ``TopK`` holds them when it stops at ``upto``: with ``distinct_views`` each frame
    comes with its ``View`` (pose, and the description for text), as in ``Agent.run``."""
    top: TopK[T] = TopK(k)
    for f in frames:
        if upto is not None and f.step > upto:
            break
        view = (View(*f.pose, f.item if isinstance(f.item, str) else None)
                if distinct_views else None)
        top.push(f.sim, f.step, f.item, view)
    return top.best()


def reobserve(observe: Callable[[Pose2D], Any], describe: Callable[[Any], T],
              recorded: Iterable[RecordedFrame]) -> list[Frame[T]]:
    """Each recorded frame rendered again at its pose (``observe``: e.g. ``SyntheticEnv.observe``)
    and described (``describe``: the stack's ``perception.frame``)."""
    return [Frame(r.step, r.sim, r.pose, describe(observe(Pose2D(*r.pose)))) for r in recorded]


def answer_prompt_matches(frames: Sequence[Frame[Any]], retrieved: Sequence[Mapping[str, Any]],
                          prompt: str, question: str | None = None) -> bool:
    """Whether the re-observed descriptions of the recorded ``retrieved`` steps (best first) are
    the evidence in the stored answer ``prompt`` (text perception): as they are, or, given the
    ``question``, as the direct answer reads them (``focus_views``)."""
    by_step = {f.step: f.item for f in frames}
    items = [by_step.get(int(r["step"])) for r in retrieved]
    if not items or not all(isinstance(i, str) for i in items):
        return False
    views = [str(i) for i in items]
    forms = [views] + ([focus_views(question, views)] if question is not None else [])
    return any(evidence_text(form)[0] in prompt for form in forms)
