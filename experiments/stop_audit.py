"""The stop-and-answer audit on the stop's frame (DESIGN 9): does the frame a relevancy
stop tested show the evidence, at the oracle's 250 px rule and at 150 px?

An evaluation run keeps no frames, so each of its synthetic episodes is walked again: the run's
recorded agent configuration (run.json) with the run's perception, relevancy and explore scorer
and a stub model in place of the language model (the stop and the walk do not read the model;
the answer does, and is not audited here). Each walk is checked against its recorded row (the
same steps and stop reason); a walk that differs is listed and left out of the figures.

Per episode it records the fewest pixels of any evidence object in the frame the stop tested
(the stop's frame, or under look-back the earlier frame it stopped for), in pixels of a
640 x 480 frame (``report.evidence.evidence_pixels``, as eval rows now record it in
``evidence_stop_pixels``; ``MIN_EVIDENCE_PIXELS`` scales the same way), and the idle steps (a step whose
pose and view are the previous step's again, ``idle_steps``). The gate's item threshold is then
chosen by these counts, not by guess.

    python -m experiments.stop_audit results/main-heldout/default [--out audit.jsonl]

Back-ends: synthetic houses (the run's assets), the run's perception (labels as text or pixels:
both read the same sightings; a VLM over images would be audited the same way, the frame's
evidence pixels being ground truth of the renderer, not of the perception).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

from efficienteqa.agent import AgentConfig
from efficienteqa.datasets import load_dataset
from efficienteqa.envs.synthetic.questions import MIN_EVIDENCE_PIXELS
from efficienteqa.eval.methods import method_config
from efficienteqa.geometry import Pose2D
from efficienteqa.models.stub import StubChatModel
from efficienteqa.records import code_version
from efficienteqa.report.evidence import evidence_pixels
from efficienteqa.scenes import open_scene
from efficienteqa.stack import Stack, build_agent
from efficienteqa.stop.rules import StopConfig
from efficienteqa.trace import StepRecord
from experiments.common import idle_steps

THRESHOLDS_PX = (MIN_EVIDENCE_PIXELS, 150)  # the oracle's rule, and the one measured beside it


def recorded_config(run: dict[str, Any]) -> AgentConfig:
    """The agent configuration a run's episodes ran with (its recorded options, today's
    defaults for those it did not set, then the method's own: eval.methods.method_config)."""
    rec = dict(run["config"])
    stop_names = {f.name for f in fields(StopConfig)}
    stop = StopConfig(**{k: v for k, v in rec.pop("stop").items() if k in stop_names})
    names = {f.name for f in fields(AgentConfig)}
    config = AgentConfig.of(stop=stop, **{k: v for k, v in rec.items()
                                       if k in names and v is not None})
    return method_config(run["method"], config)


def walk(env: Any, stack: Stack, config: AgentConfig, question: str, evidence: list[int],
         start: Pose2D | None) -> dict[str, Any]:
    """One episode again, without the language model: its steps, stop, the frame it tested and
    that frame's evidence pixels, when the evidence was first in view at each threshold."""
    built = build_agent(env, stack, config, "synthetic",
                        model=StubChatModel(lambda messages: "unknown", name="stub"))
    pixels: dict[int, float] = {}
    poses: list[tuple[float, float, float]] = []

    def hook(record: StepRecord, obs: Any, _: Any) -> None:
        poses.append((obs.pose.x, obs.pose.y, obs.pose.yaw))
        if evidence and obs.instance is not None:
            pixels[record.step] = evidence_pixels(obs.instance, evidence)

    result = built.agent.run(env, question, start=start, on_step=hook,
                              budget=built.agent.config.budget(env))
    last = result.records[-1]
    tested = (last.check.tested_step if last.check is not None and last.check.tested_step
              else last.step)
    out: dict[str, Any] = {"steps": result.steps, "stop_reason": result.stop_reason,
                           "tested_step": tested, "idle_steps": idle_steps(poses)}
    if evidence:
        out["stop_pixels"] = round(pixels.get(tested, 0.0), 1)
        for px in THRESHOLDS_PX:
            out[f"stop_shows_{px}"] = pixels.get(tested, 0.0) >= px
            out[f"first_seen_{px}"] = next((s for s in sorted(pixels) if pixels[s] >= px), None)
    return out


def audit(folder: Path, limit: int | None = None) -> list[dict[str, Any]]:
    """Every done synthetic episode of a run folder walked again (module docstring)."""
    run = json.loads((folder / "run.json").read_text())
    rows = [json.loads(line) for line in (folder / "episodes.jsonl").read_text().splitlines()
            if line.strip()]
    rows = [r for r in rows if r.get("status") == "done"][:limit]
    questions = {q.id: q for q in load_dataset(run["dataset"].partition("-")[0])}
    config = recorded_config(run)
    stack = replace(Stack(**{k: v for k, v in run["stack"].items()
                             if k in {f.name for f in fields(Stack)}}), grouping="rules")
    out: list[dict[str, Any]] = []
    by_scene: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        by_scene.setdefault(r["scene"], []).append(r)
    for scene_name, group in by_scene.items():
        scene = open_scene(scene_name, run.get("assets") or "sh3d", oracle=False)
        try:
            for r in group:
                q = questions[r["id"]]
                evidence = list(q.source.get("evidence") or [])
                start = Pose2D(*q.start) if q.start else None
                got = walk(scene.env, stack, config, r["question"], evidence, start)
                row = {"id": r["id"], "category": r["category"], "evidence": bool(evidence),
                       "recorded": {"steps": r["steps"], "stop_reason": r["stop_reason"]},
                       "same": (got["steps"], got["stop_reason"]) == (r["steps"],
                                                                      r["stop_reason"]),
                       **got}
                out.append(row)
                print(json.dumps(row), flush=True)
        finally:
            scene.env.close()
    return out


def summary(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Relevancy stops with evidence whose tested frame shows it at each threshold, over the
    walks that reproduced their record; idle steps over every walk."""
    same = [r for r in rows if r["same"]]
    stops = [r for r in same if r["evidence"] and r["stop_reason"] == "relevancy"]
    out: dict[str, Any] = {"walks": len(rows), "reproduced": len(same),
                           "differ": [r["id"] for r in rows if not r["same"]],
                           "relevancy_stops": len(stops)}
    for px in THRESHOLDS_PX:
        out[f"stops_showing_{px}px"] = sum(r[f"stop_shows_{px}"] for r in stops)
    out["stop_pixels_without_250"] = sorted(r["stop_pixels"] for r in stops
                                            if not r[f"stop_shows_{MIN_EVIDENCE_PIXELS}"])
    out["idle_steps"] = sum(len(r["idle_steps"]) for r in rows)
    out["walks_with_idle"] = sum(bool(r["idle_steps"]) for r in rows)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", type=Path, help="an evaluation run folder of synthetic questions")
    ap.add_argument("--limit", type=int, default=None, help="the first N episodes only")
    ap.add_argument("--out", type=Path, default=None, help="the per-episode rows (JSON lines)")
    args = ap.parse_args()
    rows = audit(args.run, args.limit)
    if args.out:
        args.out.write_text("".join(json.dumps(r) + "\n" for r in rows))
    print(f"\n{args.run}: code {code_version()}")
    print(json.dumps(summary(rows), indent=1))


if __name__ == "__main__":
    main()
