"""Stop rules replayed on recorded trajectories, no model (DESIGN 8, results/stop/).

``record``: the agent (``Agent.run``, early stop off, a stub chat model that is never asked
anything but the final answer) walks each synthetic house; every valid frame keeps its step,
every question's ``Sim`` (the offline default relevancy, all-MiniLM-L6-v2 over the
semantic-sensor perception's relevancy text, exactly as the agent scores it) and whether the
question's evidence is in view (``envs.synthetic.questions.evidence_visible``). With
``--explorer frontier-only`` (default) the walk does not depend on the question, so one walk per
house serves all its questions; with ``--explorer sfe`` (the default explorer, model-free
``direction-logit`` scorer) each question walks its own. Trajectories are cached as JSON, one
file per house, under ``--out``.

``replay``: each stop rule (``stop.rules.STOP_RULES``) over the cached trajectories:

- precision: relevancy stops whose stop frame, or one of the top-5 frames by Sim up to the stop,
  shows the evidence (a stop on a "no" question never does);
- recall: episodes that saw the evidence and stopped within 3 steps of first seeing it;
  ``recall@10`` allows for the minimum step: stop at most 3 steps after
  ``max(first seen, min_step)``;
- false stops per "no" episode (existence questions whose answer is "no": nothing to see);
- steps saved: mean of (the walk's last step without a stop - the stop step) over all episodes,
  and the mean steps used / budget.

    python -m experiments.stop_bench record --seeds 0-20 [--explorer frontier-only]
    python -m experiments.stop_bench replay --seeds 0-20
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.agent import AgentConfig
from efficienteqa.envs.base import Observation
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.questions import Question, evidence_visible
from efficienteqa.models.stub import StubChatModel
from efficienteqa.scenes import synthetic_questions
from efficienteqa.stack import Stack, build_agent, build_relevancy
from efficienteqa.stop.rules import (
    MIN_STEP,
    SIGMA_FLOOR,
    STOP_RULES,
    RelevancyStopper,
    StopConfig,
)
from efficienteqa.trace import StepRecord

TOP_K = 5
WITHIN = 3


def parse_seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def is_no(q: Question) -> bool:
    return q.category == "existence" and q.answer.strip().lower().startswith("no")


def walk(env: SyntheticEnv, questions: list[Question], explorer: str, seed: int) -> dict[str, Any]:
    """One early-stop-free agent episode asking ``questions[0]``: per valid frame its step,
    every question's Sim and evidence in view."""
    stack = Stack(grouping="rules")
    config = AgentConfig.of(stop=StopConfig(enabled=False), explorer=explorer, seed=seed)
    built = build_agent(env, stack, config, "synthetic", model=StubChatModel(lambda m: "no"))
    relevancy = build_relevancy(stack.relevancy)
    perception = built.agent.perception
    frames: list[dict[str, Any]] = []

    def hook(record: StepRecord, obs: Observation, _out: Any) -> None:
        if record.check is None:
            return
        text = perception.relevancy_text(obs)
        frames.append({"step": record.step,
                       "sim": [record.check.sim if k == 0 else
                               float(relevancy.score(q.question, text=text))
                               for k, q in enumerate(questions)],
                       "seen": [bool(evidence_visible(obs.instance, q.evidence))
                                for q in questions]})

    result = built.agent.run(env, questions[0].question, on_step=hook,
                              budget=built.agent.config.budget(env))
    return {"frames": frames, "end_step": len(result.records), "end_reason": result.stop_reason,
            "budget": result.budget, "backends": built.backends}


def record_house(seed: int, explorer: str) -> list[dict[str, Any]]:
    with SyntheticEnv.from_seed(seed) as env:
        qs = synthetic_questions(env)
        walks = ([(qs, walk(env, qs, explorer, 0))] if explorer == "frontier-only"
                 else [([q], walk(env, [q], explorer, 0)) for q in qs])
    episodes = []
    for group, w in walks:
        for k, q in enumerate(group):
            episodes.append({
                "house": seed, "id": q.id, "category": q.category, "question": q.question,
                "answer": q.answer, "no": is_no(q), "oracle_steps": q.oracle_steps,
                "budget": w["budget"], "end_step": w["end_step"], "end_reason": w["end_reason"],
                "steps": [f["step"] for f in w["frames"]],
                "sims": [f["sim"][k] for f in w["frames"]],
                "seen": [f["seen"][k] for f in w["frames"]],
                "backends": w["backends"] | {"explorer": explorer}})
    return episodes


def load(out: Path, seeds: list[int], explorer: str) -> list[dict[str, Any]]:
    episodes = []
    for seed in seeds:
        path = out / explorer / f"house_{seed}.json"
        if not path.exists():
            t = time.perf_counter()
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(record_house(seed, explorer)))
            print(f"house {seed}: recorded ({time.perf_counter() - t:.0f} s)", flush=True)
        episodes += json.loads(path.read_text())
    return episodes


def replay(ep: dict[str, Any], config: StopConfig) -> dict[str, Any]:
    """The rule over one trajectory: stop step (None: none), and whether it shows the evidence."""
    stopper = RelevancyStopper(config)
    first_seen = None
    for k, (step, sim, seen) in enumerate(zip(ep["steps"], ep["sims"], ep["seen"])):
        if seen and first_seen is None:
            first_seen = step
        if stopper.check(step, sim).stop:
            top = np.argsort(-np.asarray(ep["sims"][:k + 1]), kind="stable")[:TOP_K]
            shows = bool(seen or any(ep["seen"][i] for i in top))
            return {"stop": step, "shows": shows, "first_seen": first_seen}
    return {"stop": None, "shows": False, "first_seen": first_seen}


def metrics(episodes: list[dict[str, Any]], config: StopConfig) -> dict[str, Any]:
    rows = [replay(ep, config) | {"ep": ep} for ep in episodes]
    stops = [r for r in rows if r["stop"] is not None]
    seen = [r for r in rows if any(r["ep"]["seen"])]

    def recalled(r: dict[str, Any], allow_min: bool) -> bool:
        first = next(s for s, v in zip(r["ep"]["steps"], r["ep"]["seen"]) if v)
        base = max(first, config.min_step) if allow_min else first
        return r["stop"] is not None and first <= r["stop"] <= base + WITHIN

    no = [r for r in rows if r["ep"]["no"]]
    saved = [r["ep"]["end_step"] - r["stop"] if r["stop"] is not None else 0 for r in rows]
    used = [(r["stop"] or r["ep"]["end_step"]) / r["ep"]["budget"] for r in rows]
    return {
        "rule": config.rule, "episodes": len(rows), "stops": len(stops),
        "precision": sum(r["shows"] for r in stops) / len(stops) if stops else float("nan"),
        "shows": sum(r["shows"] for r in stops),
        "seen": len(seen), "recall": sum(recalled(r, False) for r in seen) / max(len(seen), 1),
        "recall_min": sum(recalled(r, True) for r in seen) / max(len(seen), 1),
        "no_episodes": len(no),
        "false_per_no": sum(r["stop"] is not None for r in no) / len(no) if no else float("nan"),
        "saved": float(np.mean(saved)), "used_frac": float(np.mean(used))}


def label(m: dict[str, Any]) -> str:
    floor = f", floor {m['sigma_floor']:g}" if "floor" in m["rule"] else ""
    return f" (min step {m.get('min_step', MIN_STEP)}{floor})"


def table(results: list[dict[str, Any]]) -> str:
    lines = ["| rule | relevancy stops | precision | recall (3 steps) | recall@10 | "
             "false stops / \"no\" episode | steps saved | steps / budget |",
             "|---|---|---|---|---|---|---|---|"]
    for m in results:
        lines.append(
            f"| {m['rule']}{label(m)} | {m['stops']}/{m['episodes']} | {m['precision']:.0%} "
            f"({m['shows']}/{m['stops']}) | {m['recall']:.0%} | {m['recall_min']:.0%} "
            f"(of {m['seen']}) | {m['false_per_no']:.2f} ({m['no_episodes']}) | "
            f"{m['saved']:.1f} | {m['used_frac']:.2f} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("action", choices=["record", "replay"])
    parser.add_argument("--seeds", default="0-20", help="e.g. 0-20 (training), 2000-2005")
    parser.add_argument("--explorer", default="frontier-only", choices=["frontier-only", "sfe"])
    parser.add_argument("--rules", default=",".join(STOP_RULES))
    parser.add_argument("--floors", default="", help="sigma floors to try on rules with floor, "
                        "e.g. 0.05,0.1 (default: StopConfig.sigma_floor)")
    parser.add_argument("--min-steps", default="", help="minimum stop steps to try with every "
                        "rule, e.g. 5,7,10 (default: StopConfig.min_step)")
    parser.add_argument("--out", default="out/stop_bench")
    args = parser.parse_args()
    seeds = parse_seeds(args.seeds)
    episodes = load(Path(args.out), seeds, args.explorer)
    if args.action == "record":
        print(f"{len(episodes)} episodes cached under {args.out}/{args.explorer}")
        return
    configs = []
    min_steps = [int(m) for m in args.min_steps.split(",")] if args.min_steps else [MIN_STEP]
    for rule in args.rules.split(","):
        floors = args.floors.split(",") if "floor" in rule and args.floors else [SIGMA_FLOOR]
        configs += [StopConfig(rule=rule, sigma_floor=float(f), min_step=m)
                    for f in floors for m in min_steps]
    results = [metrics(episodes, c) | {"sigma_floor": c.sigma_floor, "min_step": c.min_step}
               for c in configs]
    print(f"houses {args.seeds}, explorer {args.explorer}, {len(episodes)} episodes; "
          f"back-ends: {episodes[0]['backends']['perception']}, "
          f"{episodes[0]['backends']['relevancy']}\n")
    print(table(results))
    path = Path(args.out) / f"replay_{args.explorer}_{args.seeds}.json"
    path.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
