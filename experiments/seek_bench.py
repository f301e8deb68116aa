"""Seeing the evidence and stopping at it (DESIGN 9): the real agent, without the language model.

Back-ends: synthetic houses (Sweet Home 3D CC0 furniture), semantic-sensor perception (the
simulator's labels as text, not pixels), MiniLM text relevancy, the model-free
``direction-logit`` explore scorer; the answer call goes to a stub that says "unknown", so no
answer is graded here (``eval`` does that). Everything this benchmark reports is decided before
the answer: where the robot went, when the evidence was first in view (every evidence object
with >= 250 px, as the oracle counts), where and why it stopped.

    python -m experiments.seek_bench --split main --limit 48 --variant default --variant target
    python -m experiments.seek_bench --split training --variant target --set gate=rules

Variants are named sets of ``AgentConfig`` fields (``VARIANTS``); ``--set FIELD=VALUE`` adds to
every variant (``min_step=2`` goes to the stop config). Splits: ``training`` (houses 0-20, the
tuning houses: 6 questions each), ``main`` (the main table's held-out questions: the synthetic
split, houses 100-999, in its order), ``hidden`` (houses 3000-3099, never used by the project
before this benchmark). Rows go to ``--out`` as JSON lines, one per episode and variant.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.agent import AgentConfig
from efficienteqa.config.knobs import with_leaves
from efficienteqa.datasets import load_dataset
from efficienteqa.envs.synthetic.questions import evidence_visible
from efficienteqa.geometry import Pose2D
from efficienteqa.models.stub import StubChatModel
from efficienteqa.records import code_version
from efficienteqa.scenes import open_scene, synthetic_questions
from efficienteqa.stack import Stack, build_agent
from efficienteqa.trace import StepRecord

VARIANTS: dict[str, dict[str, Any]] = {
    "default": {},
    "paper": {"paper": True},
    "gate": {"gate": "rules"},
    "target": {"steering": "target"},
    "target+gate": {"steering": "target", "gate": "rules"},
    "frontier-only": {"explorer": "frontier-only"},
}


def config_for(variant: str, sets: dict[str, Any]) -> AgentConfig:
    from efficienteqa.agent import PAPER_CONFIG

    fields = {**VARIANTS[variant], **sets}
    base = PAPER_CONFIG if fields.pop("paper", False) else AgentConfig()
    return with_leaves(base, **fields)


def questions(split: str, limit: int) -> list[tuple[str, int, str, list[int], str, int | None,
                                                    Pose2D | None, str]]:
    """(id, house, question, evidence, category, oracle steps, start, answer)."""
    out = []
    if split == "main":
        for q in load_dataset("synthetic", limit=limit):
            src = q.source
            out.append((q.id, int(q.scene.partition(":")[2]), q.question,
                        list(src.get("evidence", [])), q.category, q.oracle_steps,
                        Pose2D(*q.start) if q.start else None, q.answer))
        return out
    seeds = range(0, 21) if split == "training" else range(3000, 3100)
    for seed in seeds:
        scene = open_scene(f"synthetic:{seed}")
        try:
            for q in synthetic_questions(scene.env):  # type: ignore[arg-type]
                out.append((q.id, seed, q.question, q.evidence, q.category, q.oracle_steps, None,
                            q.answer))
        finally:
            scene.env.close()
        if len(out) >= limit:
            break
    return out[:limit]


def run_one(env: Any, question: str, evidence: list[int], start: Pose2D | None,
            config: AgentConfig) -> dict[str, Any]:
    model = StubChatModel(lambda messages: "unknown", name="stub")
    built = build_agent(env, Stack(grouping="rules"), config, "synthetic", model=model)
    seen: dict[int, bool] = {}

    def hook(record: StepRecord, obs: Any, _: Any) -> None:
        seen[record.step] = evidence_visible(obs.instance, evidence) if evidence else False

    t = time.perf_counter()
    result = built.agent.run(env, question, start=start, on_step=hook,
                              budget=built.agent.config.budget(env))
    first = next((s for s in sorted(seen) if seen[s]), None)
    last = result.records[-1]
    tested = last.check.tested_step if last.check is not None and last.check.tested_step else last.step
    return {"steps": result.steps, "budget": result.budget, "stop_reason": result.stop_reason,
            "first_seen": first, "stop_shows": bool(seen.get(tested)),
            "retrieved_shows": any(seen.get(s) for s, _ in result.retrieved),
            "refused": result.refused_moves, "wall_s": round(time.perf_counter() - t, 1),
            "decisions": [r.decision for r in result.records]}


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    has = [r for r in rows if r["evidence"]]
    oracle = np.mean([r["oracle"] for r in has if r["oracle"]])
    first = [r["first_seen"] if r["first_seen"] is not None else r["budget"] + 1 for r in has]
    stops = [r for r in has if r["stop_reason"] == "relevancy"]
    waits = [r["steps"] - r["first_seen"] for r in has
             if r["first_seen"] is not None and r["stop_reason"] == "relevancy"]
    no = [r for r in rows if not r["evidence"]]
    steps = [r["steps"] for r in has]
    return {
        "n": len(rows), "with_evidence": len(has),
        "first_seen_x_oracle": float(np.mean(first) / oracle) if has else None,
        "never_seen": sum(r["first_seen"] is None for r in has),
        "never_seen_before_stop": sum(r["first_seen"] is None or r["first_seen"] > r["steps"]
                                      for r in has),
        "relevancy_stops": len(stops),
        "stops_showing_evidence": sum(r["stop_shows"] for r in stops),
        "retrieved_shows": sum(r["retrieved_shows"] for r in has),
        "sight_to_stop_mean": float(np.mean(waits)) if waits else None,
        "sight_to_stop_median": float(np.median(waits)) if waits else None,
        "steps_mean": float(np.mean(steps)) if steps else None,
        "steps_x_oracle": float(np.mean(steps) / oracle) if steps else None,
        "no_questions": len(no), "no_false_stops": sum(r["stop_reason"] == "relevancy" for r in no),
        "no_steps_mean": float(np.mean([r["steps"] for r in no])) if no else None,
        "explored_stops": sum(r["stop_reason"] == "explored" for r in rows),
        "searched_stops": sum(r["stop_reason"] == "searched" for r in rows),
        "refused_per_step": sum(r["refused"] for r in rows) / max(sum(r["steps"] for r in rows), 1),
    }


def parse_sets(items: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for item in items:
        key, _, value = item.partition("=")
        out[key] = json.loads(value) if value[:1].isdigit() or value in ("true", "false") else value
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--split", choices=("training", "main", "hidden"), default="training")
    ap.add_argument("--limit", type=int, default=48)
    ap.add_argument("--variant", action="append", choices=tuple(VARIANTS))
    ap.add_argument("--set", action="append", default=[], help="FIELD=VALUE for every variant")
    ap.add_argument("--seeds", default="0", help="explorer seeds, e.g. 0,1,2")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    variants = args.variant or ["default"]
    sets = parse_sets(args.set)
    explorer_seeds = [int(s) for s in args.seeds.split(",")]
    qs = questions(args.split, args.limit)
    rows: dict[str, list[dict[str, Any]]] = {v: [] for v in variants}
    out = args.out.open("a") if args.out else None
    for house in dict.fromkeys(q[1] for q in qs):
        scene = open_scene(f"synthetic:{house}", oracle=False)
        try:
            for qid, _, text, evidence, category, oracle, start, answer in (q for q in qs
                                                                           if q[1] == house):
                for v in variants:
                    for seed in explorer_seeds:
                        config = with_leaves(config_for(v, sets), seed=seed)
                        row = {"id": qid, "house": house, "category": category,
                               "question": text, "answer": answer, "evidence": evidence,
                               "oracle": oracle, "variant": v, "seed": seed,
                               **run_one(scene.env, text, evidence, start, config)}
                        rows[v].append(row)
                        if out:
                            out.write(json.dumps(row) + "\n")
                            out.flush()
                        print(f"{qid:12s} {v:12s} s{seed} steps {row['steps']:2d}/{row['budget']} "
                              f"{row['stop_reason']:9s} first {row['first_seen']} oracle {oracle} "
                              f"stop-shows {row['stop_shows']} {text}", flush=True)
        finally:
            scene.env.close()
    print(f"\n{args.split}: {len(qs)} questions x seeds {explorer_seeds}; sets {sets}; "
          f"code {code_version()}")
    for v in variants:
        print(v, json.dumps(summarise(rows[v])))


if __name__ == "__main__":
    main()
