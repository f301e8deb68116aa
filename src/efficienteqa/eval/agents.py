"""Your agent in our houses: ``efficienteqa eval --eval.method module:Class`` (or the name of a
Python entry point in the group ``efficienteqa.agents``) runs a user's agent through the same
runner, resume, Ray, judge and report as the built-in methods.

The protocol is two methods, on a class made with no arguments (one per episode):

- ``reset(question, info)``: a new episode; ``info["budget"]`` is the benchmark's step budget,
  ``info["vlm"]`` the run's ``--backends.vlm``, for an agent that wants the run's model (any
  other setting of the explore, stop and answer sections configures the built-in agent only,
  and is refused for yours).
- ``act(observation) -> action``: ``observation`` is ``envs.episode``'s dict (RGB, depth,
  intrinsics, camera-to-world pose, the question; ``info`` of the last move under ``"info"``),
  the action ``envs.episode.move(x, y, yaw)`` or ``answer(text)``. An answer may carry
  ``"confidence"`` (0-1); without one the record says 0.

An optional ``name`` attribute names the agent in ``run.json`` (default: the class's name),
beside a digest of its module's source (``agent_identity``). The agent sees what the
Gymnasium environment gives (``efficienteqa.gym``): no labels, no navigability, no answer.
An agent that does not answer within the budget answers "" (graded wrong).
"""

from __future__ import annotations

import hashlib
import importlib
import inspect
import json
from importlib.metadata import entry_points
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.outcome import MethodFn, Outcome

if TYPE_CHECKING:
    from efficienteqa.eval.spec import RunSpec
    from efficienteqa.observation import Observation

ENTRY_POINTS = "efficienteqa.agents"
# The budget of an episode in a scene that knows none (a robot's): as ``ask`` without one.
FALLBACK_BUDGET = 30


class EQAAgent(Protocol):
    def reset(self, question: str, info: dict[str, Any]) -> None: ...

    def act(self, observation: dict[str, Any]) -> dict[str, Any]: ...


def is_agent_class(obj: object) -> bool:
    return isinstance(obj, type) and all(callable(getattr(obj, m, None)) for m in ("reset", "act"))


def entry_point(name: str) -> Any | None:
    """The object an installed package registers as agent ``name``, or None."""
    found = [e for e in entry_points(group=ENTRY_POINTS) if e.name == name]
    return found[0].load() if found else None


def load_method(method: str) -> Any:
    """The object ``module:name`` (or the entry point ``method``) names, failing in one line."""
    if ":" not in method:
        obj = entry_point(method)
        if obj is None:
            raise EfficientEQAError(f"unknown method {method!r} (not built in, and no installed "
                                    f"agent of that name in the entry points {ENTRY_POINTS})",
                                    fix="use a built-in method (efficienteqa eval --help), "
                                        "module:function or module:Class")
        return obj
    module, _, name = method.partition(":")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise EfficientEQAError(f"cannot load method {method!r}: {exc}",
                                fix="give module:Class (or module:function) importable on "
                                    "every worker, e.g. run from the folder that holds it") from None


def agent_identity(method: str) -> dict[str, Any]:
    """What ``run.json`` records of a user's method: its name, module and a digest of the
    module's source (its code version: a changed agent is a different run)."""
    obj = load_method(method)
    module = inspect.getmodule(obj)
    try:
        source = inspect.getsource(module) if module is not None else ""
    except (OSError, TypeError):
        source = ""
    digest = hashlib.sha256(source.encode()).hexdigest()[:12] if source else None
    return {"name": str(getattr(obj, "name", getattr(obj, "__name__", method))),
            "module": getattr(module, "__name__", None), "code_version": digest}


def agent_method(cls: type) -> MethodFn:
    """The runner's method for agent class ``cls``: one episode per question. The agent gets
    the question's words and the observations only, so the method itself may read the whole
    question: its evidence, for the record's ``evidence_first_seen_step``."""
    def run(q: EvalQuestion, spec: RunSpec, out: Path) -> Outcome:
        return run_agent(cls(), q, spec, out)
    run.__name__ = run.__qualname__ = getattr(cls, "__name__", "agent")
    return run


def run_agent(agent: EQAAgent, q: EvalQuestion, spec: RunSpec, out: Path) -> Outcome:
    """``agent`` answers ``q`` in its scene, opened as for the built-in methods; ``out`` gets
    ``episode.json`` (the question, the answer, the poses the robot reached)."""
    from efficienteqa.envs.episode import QuestionEpisode
    from efficienteqa.envs.synthetic.moves import path_moves
    from efficienteqa.envs.synthetic.questions import evidence_visible
    from efficienteqa.geometry import Pose2D
    from efficienteqa.stop.rules import env_step_budget

    scene = spec.open_scene(q)
    try:
        budget = env_step_budget(scene.env) or FALLBACK_BUDGET
        start = Pose2D(*q.start) if q.start is not None else None
        evidence = [int(e) for e in q.source.get("evidence") or []]
        seen: list[int] = []  # the steps whose frames show every evidence object

        def watch(step: int, frame: Observation) -> None:
            if evidence and not seen and frame.instance is not None \
                    and evidence_visible(frame.instance, evidence):
                seen.append(step)  # the first such step: later frames are not read

        episode = QuestionEpisode(path_moves(scene.env), q.question, budget, start,
                                  on_view=watch)
        first, info = episode.reset()
        agent.reset(q.question, {**info, "vlm": spec.stack.vlm})
        obs: dict[str, Any] | None = first
        confidence = 0.0
        while obs is not None and not episode.over:
            action = agent.act({**obs, "info": info})
            if isinstance(action, dict) and "confidence" in action:
                confidence = float(action["confidence"])
            obs, info = episode.step(action)
    finally:
        scene.env.close()
    reply = episode.reply or ""
    out.mkdir(parents=True, exist_ok=True)
    (out / "episode.json").write_text(json.dumps(
        {"question": q.question, "scene": scene.name, "answer": reply, "steps": episode.steps,
         "budget": budget, "poses": [[p.x, p.y, p.yaw] for p in episode.poses]}, indent=1))
    return Outcome(reply, confidence, episode.steps, budget,
                   "answered" if episode.reply is not None else "budget",
                   refused_moves=episode.refused,
                   evidence_first_seen_step=seen[0] if seen else None)
