"""Throughput of the evaluation runner on 1, 2, 4, 8 Ray workers at API latency (DESIGN 6, results/ray/).

The model is the replay server (``benchmarks/replay_server.py``), started here on a free port: it
answers every call from the response cache after ``--latency-s`` seconds, as GPT-4o or a shared
vLLM server would, so the runner is bound by latency and not by the CPU that runs the model. For
each worker count the same questions run through ``efficienteqa.eval.runner.run_eval`` on a
fresh Ray started with ``num_cpus=N`` (one CPU per task, so at most N episodes at once); the
runner is given that Ray's address, as it would be given a cluster's.

Two times per worker count:
- ``warm``: ``run_eval``'s own wall time, after Ray is up and its N worker processes have
  imported the package (a warm-up task per worker): the steady state of a long run;
- ``cold``: from ``ray.init`` to the last episode, Ray start-up and imports included (its
  shutdown not).
Episodes/minute and the speed-up against 1 worker are given for both.

    python -m benchmarks.ray_scaling --questions 32 --latency-s 1.5
    python -m benchmarks.ray_scaling --method frontier-only --max-steps 4 --questions 8

Writes ``results/ray/<method>-latency<L>.json`` (``--out`` to change): the command, the latency,
each worker count's figures, the replay hits and misses, the machine and the code version.
The client runs with its own cache off (else it would not ask the server). ``--grouping rules``
by default: the default "llm" grouping loads MiniLM (torch) in every worker, CPU work that this
benchmark does not mean to measure.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shlex
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from benchmarks.replay_server import serve
from efficienteqa.agent import AgentConfig
from efficienteqa.datasets import load_dataset
from efficienteqa.eval.methods import RunSpec
from efficienteqa.eval.runner import machine, run_eval
from efficienteqa.records import code_version
from efficienteqa.stack import Stack

ROOT = Path(__file__).resolve().parents[1]  # the repository: Ray's workers import from it too
MODEL = "qwen2.5-coder-1.5b"  # the model the response cache holds replies of


def _warm_up() -> str:
    """Import what an episode imports; the worker's id (run once per worker)."""
    import openai  # noqa: F401

    import efficienteqa.eval.methods  # noqa: F401

    time.sleep(0.5)  # keeps this worker busy so that the next warm-up lands on another
    return f"{platform.node()}:{os.getpid()}"


def run_one(spec: RunSpec, questions: list, workers: int, server: Any) -> dict[str, Any]:
    import ray

    before = server.stats.to_dict()
    t0 = time.perf_counter()
    # No key in runtime_env (Ray logs it in plain text): the workers of this local Ray inherit
    # this process's OPENAI_API_KEY, set in main().
    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
             configure_logging=False,
             runtime_env={"env_vars": {"PYTHONPATH": os.pathsep.join(
                 p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)}})
    try:
        warm = ray.remote(num_cpus=1)(_warm_up)
        pids = set(ray.get([warm.remote() for _ in range(workers)]))
        startup_s = time.perf_counter() - t0
        address = ray.get_runtime_context().gcs_address
        with tempfile.TemporaryDirectory(prefix=f"ray_scaling_{workers}_") as out:
            result = run_eval(spec, questions, Path(out), workers=workers, address=address,
                              prepare=False)
            cold_s = time.perf_counter() - t0
    finally:
        ray.shutdown()
    after = server.stats.to_dict()
    return {"workers": workers, "episodes": result.ran, "failed": result.failed,
            "worker_processes": len(pids), "ray_startup_s": round(startup_s, 2),
            "warm_wall_s": round(result.wall_s, 2), "cold_wall_s": round(cold_s, 2),
            "warm_episodes_per_min": round(60 * result.ran / result.wall_s, 2),
            "cold_episodes_per_min": round(60 * result.ran / cold_s, 2),
            "model_calls": after["requests"] - before["requests"],
            "replay_hits": after["hits"] - before["hits"],
            "replay_misses": after["misses"] - before["misses"],
            "max_calls_in_flight": after["max_in_flight"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--method", default="blind")
    parser.add_argument("--dataset", default="synthetic")
    parser.add_argument("--questions", type=int, default=32)
    parser.add_argument("--workers", default="1,2,4,8")
    parser.add_argument("--latency-s", type=float, default=1.5)
    parser.add_argument("--max-steps", type=int, default=None)
    parser.add_argument("--grouping", default="rules")
    parser.add_argument("--cache", default=None, help="the response cache the server replays")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)

    server = serve(args.cache, latency_s=args.latency_s)
    os.environ["OPENAI_API_KEY"] = "replay"  # the server checks no key; the client wants one
    stack = Stack(vlm=f"openai:{MODEL}@{server.base_url}", grouping=args.grouping, cache=False)
    config = AgentConfig() if args.max_steps is None else replace(AgentConfig(),
                                                                  max_steps=args.max_steps)
    spec = RunSpec(method=args.method, dataset=args.dataset, stack=stack, config=config, judge=None)
    questions = load_dataset(args.dataset, limit=args.questions)
    rows = []
    try:
        for workers in [int(w) for w in args.workers.split(",")]:
            row = run_one(spec, questions, workers, server)
            rows.append(row)
            print(json.dumps(row), flush=True)
    finally:
        server.shutdown()
        server.server_close()
    base = rows[0]
    for row in rows:
        row["warm_speedup"] = round(row["warm_episodes_per_min"] / base["warm_episodes_per_min"], 2)
        row["cold_speedup"] = round(row["cold_episodes_per_min"] / base["cold_episodes_per_min"], 2)

    import ray

    record = {
        "command": "python -m benchmarks.ray_scaling "
                   + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:])),
        "method": args.method, "dataset": args.dataset, "questions": len(questions),
        "question_ids": [q.id for q in questions], "max_steps": args.max_steps,
        "grouping": args.grouping, "vlm": f"openai:{MODEL}@<replay server>",
        "latency_s": args.latency_s, "runs": rows,
        "machine": {**machine(), "processor": platform.processor(),
                    "load_average_at_end": os.getloadavg()},
        "ray": ray.__version__, "code_version": code_version(), "created": time.time(),
    }
    out = args.out or (Path(__file__).resolve().parents[1] / "results" / "ray"
                       / f"{args.method}-latency{args.latency_s:g}.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=2) + "\n")
    print(f"\n{args.method}, {len(questions)} questions, latency {args.latency_s:g} s per call")
    print(f"{'workers':>7} {'episodes/min':>13} {'speed-up':>9} {'cold ep/min':>12} "
          f"{'cold speed-up':>14} {'misses':>7}")
    for row in rows:
        print(f"{row['workers']:>7} {row['warm_episodes_per_min']:>13.1f} "
              f"{row['warm_speedup']:>8.2f}x {row['cold_episodes_per_min']:>12.1f} "
              f"{row['cold_speedup']:>13.2f}x {row['replay_misses']:>7}")
    print(f"written: {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
