"""The methods an evaluation compares (DESIGN 3.6), each as a configuration of the one agent.

=====================  =========  ==========  ==========  ====================  ==================
method                 explorer   confidence  early stop  answer                model calls
=====================  =========  ==========  ==========  ====================  ==================
efficienteqa           SFE        verbalized  z > Z_th    RAG over top-K        see below
explore-eqa            SFE        token       none        best step (Sim x p)   explore + answers
explore-eqa-blackbox   SFE        verbalized  none        best step (Sim x C)   explore + answers
frontier-only          frontier   --          z > Z_th    RAG over top-K        answer (+ gate)
random                 random     --          z > Z_th    RAG over top-K        answer (+ gate)
blind                  --         verbalized  --          question only         1 (+ grouping)
blind, closed-set      --         token       --          letter of max P       1
=====================  =========  ==========  ==========  ====================  ==================

Model calls of ``efficienteqa``: on the offline default none while exploring (the
``direction-logit`` scorer and the rules gate need no model), one answer at the end; with a VLM
over images one exploration call per step (two: letters on the marked frame, "worth exploring"
on the plain one), one per frame with ``vlm-match`` relevancy, one per flagged frame for the
model gate, and one answer. ExploreEQA answers lazily at the steps that can still win
(``answer.best_step``); the count is in each episode's ``model`` block.

The RAG answer is ``AnswerConfig.answer``'s: by default the direct answer (one hinted answer,
its token probability as confidence; DESIGN 8), DESIGN 3.5's M verbalized guesses with ``paper``.
``frontier-only`` and ``random`` keep EfficientEQA's stop and answer and only drop the semantic
values: they show what SFE's steering is worth. A method may also be given as
``module:function`` (a user's own), called like ``run_agent_method`` but with the question as
the robot may know it (``without_answer``): no reference answer, alternatives or accepted
answers, no oracle step count, and none of the source fields that give the answer away.
"""

from __future__ import annotations

import functools
from dataclasses import replace
from pathlib import Path
from typing import Any

from efficienteqa.agent import AgentConfig
from efficienteqa.config.knobs import with_leaves
from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.judge_prompts import DEFAULT_JUDGE
from efficienteqa.eval.outcome import MethodFn, Outcome
from efficienteqa.eval.spec import RunSpec


def default_judge(dataset: str) -> str | None:
    """The LLM-Match judge of a run that names none: no model for synthetic datasets (the
    ``rule`` judge grades them, exactly and for free), the local model for the others."""
    return None if dataset.startswith("synthetic") else DEFAULT_JUDGE



# Each agent method: (explorer, confidence, early stop, answer_at).
_AGENT_METHODS: dict[str, tuple[str, str, bool, str]] = {
    "efficienteqa": ("sfe", "verbalized", True, "retrieval"),
    "explore-eqa": ("sfe", "token", False, "best-step"),
    "explore-eqa-blackbox": ("sfe", "verbalized", False, "best-step"),
    "frontier-only": ("frontier-only", "verbalized", True, "retrieval"),
    "random": ("random", "verbalized", True, "retrieval"),
}
METHODS = (*_AGENT_METHODS, "blind")


def method_config(method: str, config: AgentConfig) -> AgentConfig:
    """``config`` with the method's explorer, confidence reading, stop and answer source."""
    explorer, confidence, early_stop, answer_at = _AGENT_METHODS[method]
    answer = config.answer.answer if answer_at == "retrieval" else "paper"  # ExploreEQA's own
    # Steering by the question's target is EfficientEQA's (beyond the paper); the references
    # explore as they always did. ExploreEQA never stops early, so it has no gate.
    steering = config.explore.steering if method == "efficienteqa" else "none"
    return with_leaves(config, explorer=explorer, confidence=confidence, answer_at=answer_at,
                       answer=answer, steering=steering, enabled=config.stop.enabled and early_stop,
                       gate=config.stop.gate if early_stop else "none")


def effective_config(method: str, config: AgentConfig) -> AgentConfig | None:
    """What an agent method's episodes run with (``method_config``); None for the others (blind,
    a user's ``module:function``). ``run.json`` records it beside the options given, so a reader
    sees, say, white-box ExploreEQA's token confidence and its stop turned off."""
    return method_config(method, config) if method in _AGENT_METHODS else None


def usage_of(exchanges: list[dict[str, Any]]) -> dict[str, Any]:
    """The usage totals of an episode's recorded exchanges (``Exchange.to_dict()``)."""
    return {"calls": len(exchanges), "cached_calls": sum(bool(e["cached"]) for e in exchanges),
            "prompt_tokens": sum(e["prompt_tokens"] for e in exchanges),
            "completion_tokens": sum(e["completion_tokens"] for e in exchanges),
            "latency_s": round(sum(e["latency_s"] for e in exchanges), 3),
            "cost_usd": round(sum(e.get("cost_usd") or 0.0 for e in exchanges), 6)}


def run_agent_method(q: EvalQuestion, spec: RunSpec, out: Path) -> Outcome:
    """One episode of an agent method in the question's scene; ``out`` gets ``episode.json``
    (and ``report.html`` with ``spec.reports``)."""
    from efficienteqa.ask import ask
    from efficienteqa.datasets.questions_file import is_questions_file
    from efficienteqa.datasets.synthetic import check_question
    from efficienteqa.geometry import Pose2D

    config = method_config(spec.method, spec.config)
    scene = spec.open_scene(q)
    try:
        if q.scene.startswith("synthetic:") and not is_questions_file(q.dataset):
            check_question(scene, q)  # the generator's own (a user's question is the user's)
        start = Pose2D(*q.start) if q.start is not None else None
        done = ask(q.question, scene, out, stack=spec.stack, config=config, start=start,
                   assets=spec.assets, report=spec.reports, known_as=q.original_question)
    finally:
        scene.env.close()
    r = done.result
    record = done.record
    return Outcome(r.answer, r.confidence, r.steps, r.budget, r.stop_reason,
                   usage=usage_of(record["model"]["exchanges"]), backends=record["backends"],
                   extra={"retrieved": record["retrieved"],
                          "answer_problems": record["answer_problems"],
                          "problems": record["problems"],  # per kind of model call
                          "timing": record["timing"],
                          # the model calls of ExploreEQA asking at every step (answer.best_step)
                          "valid_frames": sum(s["valid"] for s in record["per_step"])},
                   evidence_first_seen_step=record["evidence_first_seen_step"],
                   evidence_in_top_k=record["evidence_in_top_k"],
                   evidence_stop_pixels=record.get("evidence_stop_pixels"),
                   refused_moves=record.get("refused_moves"))


def run_blind(q: EvalQuestion, spec: RunSpec, out: Path) -> Outcome:
    """The Blind LLM: the question only, no scene and no steps. A closed-set question (with
    ``choices``) is answered by the letter of highest token probability; the answer recorded is
    that choice's text, the letter and every letter's probability go to ``extra``."""
    from efficienteqa.answer.blind import blind_answer, blind_choice
    from efficienteqa.models.backends import build_chat_model
    from efficienteqa.models.recording import RecordingChatModel
    from efficienteqa.stack import MINILM_KINDS, build_grouper, build_relevancy, parse_vlm

    model = RecordingChatModel(build_chat_model(parse_vlm(
        spec.stack.vlm, images=False, cache=spec.stack.cache, temperature=spec.stack.temperature,
        **spec.stack.server_options())))
    closed = bool(q.choices)
    grouping = None if closed else spec.stack.grouping
    backends = {"environment": None, "perception": None, "vlm": model.name,
                "vlm_backend": spec.stack.vlm, "relevancy": None, "grouping": grouping,
                "explore_scorer": None}
    if closed:
        choice = blind_choice(model, q.question, q.choices)
        return Outcome(choice.answer, choice.confidence, 0,
                       usage=usage_of([e.to_dict() for e in model.exchanges]), backends=backends,
                       extra={"letter": choice.letter, "letter_probs": choice.letter_probs,
                              "answer_problems": choice.problems})
    # Answers are grouped by text: only a text embedder of the stack helps, and an image
    # scorer (blip2-itm, vlm-match) is neither needed nor built.
    text = spec.stack.grouping == "llm" and spec.stack.relevancy in MINILM_KINDS
    embedder = build_relevancy(spec.stack.relevancy) if text else None
    grouper = build_grouper(spec.stack.grouping, model, embedder)  # type: ignore[arg-type]
    result = blind_answer(model, q.question, grouper)
    return Outcome(result.answer, result.confidence, 0,
                   usage=usage_of([e.to_dict() for e in model.exchanges]),
                   backends=backends, extra={"answer_problems": result.problems})


# Source fields that say the answer or where to find it: HM-EQA's answer letter and filler
# flag, a synthetic question's evidence objects and the oracle's pose.
ANSWER_SOURCE_KEYS = frozenset({"letter", "filler_answer", "evidence", "no_evidence", "oracle_pose"})


def without_answer(q: EvalQuestion) -> EvalQuestion:
    """``q`` with nothing that gives its answer away (see the module docstring)."""
    return replace(q, answer="", alternatives=(), accepted=(), oracle_steps=None,
                   source={k: v for k, v in q.source.items() if k not in ANSWER_SOURCE_KEYS})


def _blindfolded(fn: MethodFn) -> MethodFn:
    """A user's method, given each question without its answer."""
    @functools.wraps(fn)
    def run(q: EvalQuestion, spec: RunSpec, out: Path) -> Outcome:
        return fn(without_answer(q), spec, out)
    return run


def resolve(method: str) -> MethodFn:
    """The function that runs one episode of ``method``: a built-in name, ``module:function``
    (called like ``run_agent_method``), or a user's agent, ``module:Class`` or an installed
    entry point (``eval.agents``). A user's method gets each question without its answer."""
    from efficienteqa.eval.agents import agent_method, is_agent_class, load_method

    if method == "blind":
        return run_blind
    if method in _AGENT_METHODS:
        return run_agent_method
    obj = load_method(method)
    if is_agent_class(obj):
        return agent_method(obj)  # the agent gets the question's words alone
    if callable(obj) and not isinstance(obj, type):
        return _blindfolded(obj)
    raise EfficientEQAError(f"method {method!r} is neither a function nor an agent class (with "
                            "reset and act)", fix=f"use one of {', '.join(METHODS)}, "
                            "module:function or module:Class")
