"""``episode.json``: one episode as plain JSON, with what produced it."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from efficienteqa.agent import AgentConfig
from efficienteqa.models.recording import Exchange
from efficienteqa.records import code_version, plain
from efficienteqa.redact import redact_urls
from efficienteqa.report.evidence import FIELDS
from efficienteqa.trace import EpisodeResult, StepRecord
from efficienteqa.vc.parse import clean_answer


def step_dict(r: StepRecord) -> dict[str, Any]:
    c = r.check
    return plain({
        "step": r.step, "pose": r.pose, "valid": r.valid,
        "sim": c.sim if c else None, "mu": c.mu if c else None, "sigma": c.sigma if c else None,
        "z": c.z if c else None, "threshold": c.threshold if c else None,
        "z_applied": c.z_applied if c else None,
        "tested_step": c.tested_step if c else None,
        "prompts": r.prompts, "lsv": r.lsv, "gsv": r.gsv, "p_yes": r.p_yes,
        "frontier": r.frontier_xy, "target": r.target_xy, "n_frontiers": r.n_frontiers,
        "decision": r.decision, "blocked": r.blocked, "short": r.short, "refused": r.refused,
        "calls": r.calls,
        "step_answer": r.step_answer, "gate": r.gate,
        "explore_problems": r.explore_problems, "relevancy_problems": r.relevancy_problems,
        "timings_ms": {k: round(v, 2) for k, v in r.timings_ms.items()},
    })


def episode_record(result: EpisodeResult, *, config: AgentConfig, backends: dict[str, Any],
                   scene: str, exchanges: Sequence[Exchange] = (),
                   reference: dict[str, Any] | None = None,
                   evidence: dict[str, Any] | None = None) -> dict[str, Any]:
    """The whole episode. ``backends``: which environment, perception, VLM, relevancy scorer
    (and judge) produced it; ``reference``: ground truth where known (answer, oracle_steps);
    ``evidence``: when the evidence was in view (``report.evidence``; None where unknown).
    The answer is recorded as ``vc.parse.clean_answer`` reads it (no markdown, no "The answer
    is"); each exchange keeps the references of the images it sent (``image_refs``)."""
    a = result.answer_result
    calls = list(exchanges)
    return plain({
        "question": result.question, "target": result.target.as_dict(),
        "answer": clean_answer(result.answer) if result.answer else result.answer,
        "confidence": result.confidence,
        "steps": result.steps, "stop_reason": result.stop_reason, "budget": result.budget,
        "refused_moves": result.refused_moves,
        "oracle_steps": (reference or {}).get("oracle_steps"),
        **{k: (evidence or {}).get(k) for k in FIELDS},
        "reference": reference, "scene": scene,
        "retrieved": [{"step": s, "sim": sim} for s, sim in result.retrieved],
        "answer_classes": [{"text": c.text, "confidence": c.confidence} for c in a.classes],
        "answer_candidates": [{"text": c.text, "confidence": c.confidence} for c in a.candidates],
        "answer_problems": a.problems,
        "explore_problems": _problems(result.records, "explore_problems"),
        "relevancy_problems": _problems(result.records, "relevancy_problems"),
        "problems": problem_counts(result),
        "per_step": [step_dict(r) for r in result.records],
        "model": model_block(calls),
        "timing": {"wall_s": round(result.wall_s, 3), "answer_s": round(result.answer_s, 3),
                   "per_step_s": round((result.wall_s - result.answer_s) / max(result.steps, 1), 3)},
        "backends": backends, "config": config, "code_version": code_version(),
    })


def model_block(calls: Sequence[Exchange]) -> dict[str, Any]:
    """The episode's model calls: their totals and each exchange."""
    return {"calls": len(calls), "prompt_tokens": sum(e.prompt_tokens for e in calls),
            "completion_tokens": sum(e.completion_tokens for e in calls),
            "latency_s": round(sum(e.latency_s for e in calls), 3),
            "cost_usd": round(sum(e.cost_usd for e in calls), 6),
            "exchanges": [e.to_dict() for e in calls]}


def failed_record(question: str, error: BaseException, *, records: Sequence[StepRecord],
                  config: AgentConfig, backends: dict[str, Any], scene: str,
                  exchanges: Sequence[Exchange] = ()) -> dict[str, Any]:
    """What an episode that failed part-way had done: its steps and every model call made
    (paid for), with the error, so that neither the exploration nor the usage is lost. An
    episode stopped by Ctrl-C (``KeyboardInterrupt``) is "interrupted", not "failed"."""
    message = str(error).splitlines()[0] if str(error) else ""
    interrupted = isinstance(error, KeyboardInterrupt)
    return plain({
        "question": question, "status": "interrupted" if interrupted else "failed",
        "error": ("interrupted (Ctrl-C)" if interrupted
                  else f"{type(error).__name__}: {message}".rstrip(": ")),
        "steps": len(records), "scene": scene, "per_step": [step_dict(r) for r in records],
        "model": model_block(list(exchanges)),
        "backends": backends, "config": config, "code_version": code_version(),
    })


def _problems(records: Sequence[StepRecord], kind: str) -> list[str]:
    """Every step's problems of one kind, each prefixed with its step."""
    return [f"step {r.step}: {p}" for r in records for p in getattr(r, kind)]


def problem_counts(result: EpisodeResult) -> dict[str, int]:
    """How many replies of each kind of model call were not read plainly: the explore call's,
    the relevancy and gate calls', and the answer's."""
    return {"explore": sum(len(r.explore_problems) for r in result.records),
            "relevancy": sum(len(r.relevancy_problems) for r in result.records),
            "answer": len(result.answer_result.problems)}


def episode_lines(record: dict[str, Any]) -> list[str]:
    """What ``efficienteqa ask`` prints of an episode first, from its ``episode.json`` record:
    the answer and its confidence, the steps, the stop and the time, the reference answer."""
    oracle = record.get("oracle_steps")
    lines = [f"answer: {record.get('answer') or '(none)'}  (confidence "
             f"{record.get('confidence') or 0.0:.2f})",
             f"steps: {record['steps']} of {record['budget']}"
             + (f" (oracle {oracle})" if oracle else "")
             + f"   stop: {record['stop_reason']}   time: {record['timing']['wall_s']:.0f} s"]
    reference = (record.get("reference") or {}).get("answer")
    if reference:
        lines.append(f"reference answer: {reference}")
    return lines


def ask_lines(record: dict[str, Any], episode_json: Path, report_html: Path | None, *,
              reference: str | None = None, rerun: str | None = None,
              recorded: Path | None = None, warnings: Sequence[str] = ()) -> list[str]:
    """What ``efficienteqa ask`` prints when an episode is done: ``episode_lines`` (as the
    README's demo block shows them; ``reference``, an --episode's answer, where the record has
    none), the back-ends (passwords in URLs as ***), the model calls and their cost, and where
    the episode, the report, the rerun log and the recorded walk are (one that ``warnings``
    says failed is not listed)."""
    lines = episode_lines(record)
    if not record.get("reference") and reference:
        lines.append(f"reference answer: {reference}")
    shown = {k: v for k, v in record["backends"].items() if v and k != "capabilities"}
    lines.append(redact_urls(f"back-ends: {', '.join(f'{k}={v}' for k, v in shown.items())}"))
    model = record["model"]
    lines.append(f"model calls: {model['calls']}" + (f"   cost: ${model['cost_usd']:.4f}"
                                                     if model.get("cost_usd") else ""))
    lines += [f"episode: {episode_json}", f"report:  {report_html}"]
    failed = " ".join(warnings)
    if rerun is not None and rerun != "live" and str(rerun) not in failed:
        lines.append(f"rerun:   {rerun}   (open it: rerun {rerun})")
    if recorded is not None and str(recorded) not in failed:
        lines.append(f"recorded: {recorded} (replay: --scene recorded:{recorded})")
    return lines


def interrupted_note(stop: BaseException, out: Path, rerun: str | None,
                     recorded: Path | None) -> str:
    """The rest of the line that says an ask was interrupted: what was kept (the partial
    episode ``ask`` wrote to ``out``, the recordings), and how to ask again (an ask is not
    resumed; its recordings are not written over)."""
    partial = getattr(stop, "partial_episode", None)
    kept = (f" at step {partial['steps']}: the episode so far (its steps and model calls) is in "
            f"{out / 'episode.json'}" if isinstance(partial, dict) else " before exploring began")
    again = []
    if recorded is not None and recorded.exists():
        kept += f", its frames in {recorded}"
        again.append("another --record path")
    if rerun is not None and rerun != "live" and Path(rerun).exists():
        kept += f", its rerun log in {rerun}"
        again.append("--overwrite (or another --rerun file)")
    return (f"{kept}; the same command asks again" + (f", with {' and '.join(again)}"
                                                      if again else ""))
