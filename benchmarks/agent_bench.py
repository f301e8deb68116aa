"""The agent end to end on synthetic questions: steps, stops, answers, wall time.

Back-ends (the offline default stack): synthetic houses with Sweet Home 3D CC0 furniture rendered
by moderngl/EGL on the CPU; semantic-sensor perception (object labels as text, no pixels);
Qwen2.5-Coder-1.5B Q4_K_M on the local llama.cpp server; MiniLM text relevancy; LLM grouping.
Answers are compared with the ground truth by normalised string match, not LLM-Match (the
judge belongs to the evaluation). The response cache is off, so every model call is timed.

    python -m benchmarks.agent_bench --questions 12 [--relevancy minilm-match] [--out out/bench]
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import time
from pathlib import Path

from efficienteqa.ask import ask
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.questions import Question, evidence_visible
from efficienteqa.explore.module import ExploreStep
from efficienteqa.observation import Observation
from efficienteqa.scenes import synthetic_questions
from efficienteqa.stack import Stack
from efficienteqa.trace import StepRecord


def normalise(text: str) -> str:
    words = re.findall(r"[a-z0-9]+", text.lower())
    return " ".join(w for w in words if w not in {"a", "an", "the", "it", "is"})


def matches(answer: str, q: Question) -> bool:
    got = normalise(answer)
    return bool(got) and any(normalise(ref) == got or f" {normalise(ref)} " in f" {got} "
                             for ref in [q.answer, *q.alternatives])


def pick_questions(n: int, per_house: int) -> list[tuple[int, Question]]:
    """``per_house`` questions with evidence from each house in seed order, categories rotated."""
    chosen: list[tuple[int, Question]] = []
    seed = 0
    while len(chosen) < n:
        with SyntheticEnv.from_seed(seed) as env:
            qs = [q for q in synthetic_questions(env) if q.evidence and q.oracle_steps]
        start = seed % max(len(qs), 1)
        for q in (qs[start:] + qs[:start])[::2][:per_house]:
            chosen.append((seed, q))
        seed += 1
    return chosen[:n]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--questions", type=int, default=10)
    parser.add_argument("--per-house", type=int, default=2)
    parser.add_argument("--vlm", default="local:qwen2.5-coder-1.5b")
    parser.add_argument("--relevancy", default="minilm",
                        help="minilm | minilm-match | overlap | vlm-match | ...")
    parser.add_argument("--out", default="out/bench")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    log = out / "agent.jsonl"
    rows = []
    # The response cache is off: every call reaches the model, so the timings are honest.
    stack = Stack(vlm=args.vlm, relevancy=args.relevancy, cache=False)
    for seed, q in pick_questions(args.questions, args.per_house):
        first_seen: list[int] = []

        def hook(record: StepRecord, obs: Observation, _: ExploreStep | None,
                 q: Question = q, first_seen: list[int] = first_seen) -> None:
            if not first_seen and evidence_visible(obs.instance, q.evidence):
                first_seen.append(record.step)

        start = time.perf_counter()
        done = ask(q.question, f"synthetic:{seed}", out / "agent" / q.id, stack=stack,
                   on_step=hook)
        wall = time.perf_counter() - start
        r = done.result
        row = {"id": q.id, "category": q.category, "question": q.question, "reference": q.answer,
               "answer": r.answer, "confidence": round(r.confidence, 3), "correct": matches(r.answer, q),
               "steps": r.steps, "budget": r.budget, "oracle_steps": q.oracle_steps,
               "first_seen": first_seen[0] if first_seen else None, "stop_reason": r.stop_reason,
               "wall_s": round(r.wall_s, 1), "total_s": round(wall, 1),
               "s_per_step": round((r.wall_s - r.answer_s) / r.steps, 2),
               "answer_s": round(r.answer_s, 1), "model_calls": done.record["model"]["calls"],
               "backends": done.record["backends"], "report": str(done.report_html)}
        rows.append(row)
        with log.open("a") as f:
            f.write(json.dumps(row) + "\n")
        print(f"{q.id} {q.category:14s} steps {r.steps:2d}/{r.budget} (oracle {q.oracle_steps}, "
              f"seen at {row['first_seen']}) stop {r.stop_reason:9s} {r.wall_s:5.0f} s  "
              f"{'OK ' if row['correct'] else 'no '} {r.answer!r} vs {q.answer!r}", flush=True)
    backends = {k: v for k, v in rows[0]["backends"].items() if k != "environment"}
    print(f"\n{len(rows)} questions in synthetic houses (sh3d); back-ends: {backends}")
    print(f"steps mean {statistics.mean(r['steps'] for r in rows):.1f} "
          f"(oracle mean {statistics.mean(r['oracle_steps'] for r in rows):.1f})")
    for reason in ("relevancy", "budget", "explored"):
        print(f"  stop {reason}: {sum(r['stop_reason'] == reason for r in rows)}")
    seen = [r for r in rows if r["first_seen"] is not None]
    early = [r for r in seen if r["stop_reason"] == "relevancy"]
    print(f"evidence seen in {len(seen)} episodes; stopped by the z-rule in {len(early)} of them")
    false = [r for r in rows if r["stop_reason"] == "relevancy" and r["first_seen"] is None]
    print(f"z-rule stops without the evidence ever in view: {len(false)}")
    print(f"answers matching the ground truth (string match): {sum(r['correct'] for r in rows)}"
          f"/{len(rows)}")
    walls = [r["wall_s"] for r in rows]
    print(f"episodes and reports: {out / 'agent'}")
    print(f"episode wall time (explore + stop + answer) median {statistics.median(walls):.0f} s, "
          f"max {max(walls):.0f} s; with opening the scene and writing the report, median "
          f"{statistics.median(r['total_s'] for r in rows):.0f} s; "
          f"per step median {statistics.median(r['s_per_step'] for r in rows):.1f} s")


if __name__ == "__main__":
    main()
