"""Exploration benchmarks (DESIGN 3.2, 8; results/explore/): per-step cost, coverage, and semantic steering.

Back-ends: synthetic environment (Sweet Home 3D CC0 furniture, or --assets builtin), depth and
instance buffers rendered with moderngl/EGL on the CPU; no model: semantic values are either
absent (frontier-only, random), the ground-truth oracle (explore/oracle.py) or a model-free
direction scorer. Every episode is the agent's own loop (``experiments.common.explore_episode``:
``Agent.run`` with the early stop off), configured by ``AgentConfig`` from the options below.

    python -m experiments.explore_bench cost      # ms per step in a 6-room house
    python -m experiments.explore_bench coverage  # explored floor vs step, frontier-only vs random
    python -m experiments.explore_bench steering  # steps to see the evidence, oracle SFE vs frontier-only
    python -m experiments.explore_bench steering --methods reference:target-room,reference:room-by-room
                                                 # the reference policies (reference_policies.py)
    python -m experiments.explore_bench steering --seeds 2000-2009 --no-to-budget \
        --methods target:direction-logit,reference:named-room
                                                 # the default explorer against the yardstick
                                                 # "knows the named room" (DESIGN 9)

House seeds: the development houses 0-20 (``--seeds training``) are the ones every earlier
choice of the explorer was tuned on; the held-out houses 2000-2999 (``--seeds held-out``, the
default of ``steering``) were never used for tuning and are disjoint from the synthetic split
(100-999, ``datasets/synthetic.py``) and the relevancy calibration (1000-1019). Report targets
on held-out houses only.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from efficienteqa.agent import AgentConfig
from efficienteqa.config.knobs import with_leaves
from efficienteqa.envs.synthetic.env import SyntheticEnv, catalog_for
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.envs.synthetic.questions import Question, evidence_visible
from efficienteqa.explore.module import SemanticScorer
from efficienteqa.explore.oracle import EvidenceDistance, OracleScorer
from efficienteqa.explore.prompting import PROMPT_CONFIGS
from efficienteqa.explore.settings import EXPLORATIONS, REFUSAL_RETRIES
from efficienteqa.reading.target import TargetReading
from efficienteqa.records import code_version
from efficienteqa.scenes import synthetic_questions
from efficienteqa.stop.rules import env_step_budget
from experiments.common import NEAR_M, evidence_distance, explore_episode, idle_steps, seed_set
from experiments.reference_policies import POLICIES as REFERENCE_POLICIES
from experiments.reference_policies import run_policy

# Semantic scorers for steering: name -> factory(env, question, evidence distance, glimpsed).
# "oracle" is the ground truth; others (model-free text scorers, model elicitations) register
# here. A steering method is "frontier-only" or "sfe:SCORER" ("sfe" alone is "sfe:oracle").
# An explorer that finds nothing left to explore before this step failed (its map held no
# frontier from the start); the benchmark reports it as a failure, not as a fast episode.
EXPLORED_EARLY_STEP = 5

ScorerFactory = Callable[[SyntheticEnv, Question, EvidenceDistance, Callable[[np.ndarray], bool]],
                         SemanticScorer]
STEERING_SCORERS: dict[str, ScorerFactory] = {
    "oracle": lambda env, q, distance_m, glimpsed: OracleScorer(distance_m, glimpsed),
}


def _text_scorer(name: str) -> ScorerFactory:
    """A model-free direction scorer over the semantic perception's direction texts (DESIGN 8):
    the offline stack's (stack.EXPLORE_SCORERS) or a baseline of the direction experiment."""
    def factory(env: SyntheticEnv, q: Question, distance_m: EvidenceDistance,
                glimpsed: Callable[[np.ndarray], bool]) -> SemanticScorer:
        from efficienteqa.explore.text_scorers import DirectionScorer
        from efficienteqa.perception.semantic import SemanticPerception
        from efficienteqa.stack import EXPLORE_SCORERS
        from experiments.direction_scorers import KeywordDirections, NearestDirections

        perception = SemanticPerception(env.scene_labels())
        baselines = {"nearest": NearestDirections, "keyword": KeywordDirections}
        if name in baselines:
            return DirectionScorer(baselines[name](), perception)
        return EXPLORE_SCORERS.build(name, perception=perception)
    return factory


for _name in ("direction-logit", "nearest", "keyword"):
    STEERING_SCORERS[_name] = _text_scorer(_name)


def _sharp_logit(temperature: float) -> ScorerFactory:
    """direction-logit with its softmax at ``temperature`` (sharper values, same ranking)."""
    def factory(env: SyntheticEnv, q: Question, distance_m: EvidenceDistance,
                glimpsed: Callable[[np.ndarray], bool]) -> SemanticScorer:
        from efficienteqa.explore.text_scorers import (
            LOGIT_WEIGHTS,
            DirectionScorer,
            LogitDirections,
        )
        from efficienteqa.perception.semantic import SemanticPerception

        return DirectionScorer(LogitDirections(LOGIT_WEIGHTS, temperature=temperature),
                               SemanticPerception(env.scene_labels()))
    return factory


for _t in (0.5, 0.25):
    STEERING_SCORERS[f"direction-logit-t{_t}"] = _sharp_logit(_t)


def agent_config(args: argparse.Namespace) -> AgentConfig:
    """The agent's configuration of the exploration options on the command line (the explorer,
    its seed and the budget are set per episode)."""
    given = {"stop_clearance_m": args.stop_clearance, "refusal_retries": args.refusal_retries}
    return AgentConfig.of(exploration=args.exploration, prompts=args.prompts, steering="none",
                       map_extent=args.map_extent,
                       **{k: v for k, v in given.items() if v is not None})


def houses(n: int, assets: str, rooms: int | None = None) -> list[int]:
    catalog = catalog_for(assets)
    seeds = [s for s in range(1000)
             if rooms is None or len(generate_house(s, catalog, assets).layout.rooms) == rooms]
    return seeds[:n]


def cmd_cost(args: argparse.Namespace) -> None:
    seed = houses(1, args.assets, rooms=6)[0]
    config = with_leaves(agent_config(args), explorer="frontier-only")
    with SyntheticEnv.from_seed(seed, args.assets) as env:
        explore_episode(env, with_leaves(config, max_steps=5))  # warm-up (numba compilation)
        for explorer_seed in range(10):  # an episode long enough to show the cost is flat
            ep = explore_episode(env, with_leaves(config, max_steps=40, seed=explorer_seed))
            if len(ep.step_ms) >= 30:
                break
    ms = np.array(ep.step_ms)
    print(f"house {seed} (6 rooms), 640x480, frontier-only (explorer seed {explorer_seed}), "
          f"{len(ms)} steps; map update + frontiers + planning per step (rendering excluded)")
    print(f"median {np.median(ms):.1f} ms, p95 {np.percentile(ms, 95):.1f} ms; "
          f"steps 1-10 median {np.median(ms[:10]):.1f} ms, last 10 median {np.median(ms[-10:]):.1f} ms")


def cmd_coverage(args: argparse.Namespace) -> None:
    curves: dict[str, list[list[float]]] = {"frontier-only": [], "random": []}
    for seed in houses(args.houses, args.assets):
        with SyntheticEnv.from_seed(seed, args.assets) as env:
            budget = env_step_budget(env)
            for name in curves:
                ep = explore_episode(env, with_leaves(agent_config(args), explorer=name, seed=seed,
                                                  max_steps=budget), coverage=True)
                curves[name].append(ep.coverage + [ep.coverage[-1]] * (budget - len(ep.coverage)))
                print(f"house {seed}: {name:13s} explored {ep.coverage[-1]:.0%} of the floor "
                      f"after {len(ep.coverage)} steps (budget {budget})")
    length = min(len(c) for cs in curves.values() for c in cs)
    mean = {k: np.mean([c[:length] for c in v], axis=0) for k, v in curves.items()}
    print("\nstep  " + "  ".join(f"{k:>13s}" for k in mean))
    for s in (1, 5, 10, 15, 20, length):
        if s <= length:
            print(f"{s:4d}  " + "  ".join(f"{mean[k][s - 1]:13.1%}" for k in mean))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for k, m in mean.items():
        ax.plot(np.arange(1, length + 1), 100 * m, label=k)
    ax.set_xlabel("step")
    ax.set_ylabel("explored floor (%)")
    ax.set_title(f"Coverage over {len(curves['random'])} synthetic houses ({args.assets})")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "coverage.png", dpi=120)
    print(f"plot: {out / 'coverage.png'}")


def steering_questions(args: argparse.Namespace):
    """(house seed, env, budget, question) for the steering run: ``--per-house`` questions of
    each house of ``--seeds`` (their order turned by the seed), or with ``--split N`` the
    questions with evidence among the first N of the synthetic split (the main table's)."""
    if args.split:
        from efficienteqa.datasets.synthetic import load_split

        by_house: dict[int, list[Question]] = {}
        for e in load_split()[:args.split]:
            if e.source.get("evidence"):
                by_house.setdefault(int(e.source["house_seed"]), []).append(Question(
                    id=e.source["question_id"], house_seed=int(e.source["house_seed"]),
                    category=e.category, question=e.question, answer=e.answer,
                    evidence=list(e.source["evidence"]), oracle_steps=e.oracle_steps,
                    oracle_pose=tuple(e.source["oracle_pose"]) if e.source["oracle_pose"]
                    else None))
        for seed, qs in by_house.items():
            with SyntheticEnv.from_seed(seed, args.assets) as env:
                for q in qs:
                    yield seed, _noisy(env, args.noise, seed), env_step_budget(env), q
        return
    for seed in seed_set(args.seeds):
        with SyntheticEnv.from_seed(seed, args.assets) as env:
            asked = [q for q in synthetic_questions(env) if q.evidence]
            # A few questions per house, their order turned by the seed: many houses, every kind.
            turn = seed % len(asked) if asked else 0
            for q in (asked[turn:] + asked[:turn])[:args.per_house]:
                yield seed, _noisy(env, args.noise, seed), env_step_budget(env), q


def _noisy(env: SyntheticEnv, noise: str, seed: int) -> SyntheticEnv:
    """``env`` as a robot with the noise profile ``noise`` sees it (envs/synthetic/noise.py);
    the evidence and the oracle stay the simulator's."""
    if noise == "none":
        return env
    from efficienteqa.envs.synthetic.noise import NoisyEnv, profile

    return NoisyEnv(env, profile(noise), seed=seed)  # type: ignore[return-value]


def cmd_steering(args: argparse.Namespace) -> None:
    rows: list[dict] = []
    flagged: list[dict] = []  # questions whose evidence has no view reachable from the start
    asked = [steering_method(m) for m in args.methods.split(",")]
    # frontier-only is the explorers' baseline: it comes first unless only reference policies
    # are asked for.
    baseline = [] if all(is_reference(m) for m in asked) else ["frontier-only"]
    methods = tuple(dict.fromkeys(baseline + asked))
    for seed, env, budget, q in steering_questions(args):
        if len(rows) >= args.questions:
            break
        row = _steer(env, q, agent_config(args), budget, seed, args.repeats, args.to_budget,
                     methods)
        if not row["reachable"]:
            flagged.append(row)
            print(f"{q.id} FLAGGED: no view of the evidence is reachable from the start; "
                  "left out", flush=True)
            continue
        rows.append(row)
        print(f"{q.id} {q.category:14s} oracle {row['oracle']:2d}  "
              + "  ".join(f"{m} {np.mean(_steps(row, m)):5.1f}" for m in methods)
              + f"  {q.question}", flush=True)
    source = (f"the first {args.split} questions of the synthetic split" if args.split
              else f"seeds {args.seeds}")
    print(f"\n{len(rows)} questions in {len({r['house'] for r in rows})} houses "
          f"({source}: {sorted({r['house'] for r in rows})}) x {args.repeats} explorer "
          f"seeds ({args.assets}; a reference policy is deterministic: one episode); steps until "
          "the evidence is first in view (budget + 1 when never seen):")
    if flagged:
        print(f"  left out, no reachable view of the evidence: {', '.join(r['id'] for r in flagged)}")
    oracle = np.mean([r["oracle"] for r in rows])
    print(f"  oracle steps   mean {oracle:.2f}")
    means = {}
    for m in methods:
        f = method_summary(rows, m, args.to_budget)
        means[m] = f["steps"]
        line = (f"  {m:13s}  mean {f['steps']:.2f} (x{f['x_oracle']:.2f} oracle; per question "
                f"x{f['x_oracle_q']:.2f}), never seen {f['never_n']}/{f['episodes']} "
                f"({f['never']:.1%})")
        if is_reference(m):
            total = {k: sum(sum(r[m][k]) for r in rows)
                     for k in ("steps", "moves", "turns", "approaches", "refused")}
            stops = [s for r in rows for s in r[m]["stop"]]
            print(line + f"; {total['moves']} moves and {total['turns']} turns in "
                  f"{total['steps']} steps, {total['approaches']} glimpse walks, "
                  f"{total['refused']} refused moves; stops: "
                  + ", ".join(f"{k} {stops.count(k)}" for k in ("seen", "budget", "exhausted")))
            continue
        moves = sum(sum(r[m]["moves"]) for r in rows)
        refused = sum(sum(r[m]["refused"]) for r in rows)
        lost = sum(sum(r[m]["lost"]) for r in rows)
        taken = sum(sum(r[m]["steps"]) for r in rows)
        print(line + f", floor explored at the "
              f"{'budget' if args.to_budget else 'end'} {f['coverage']:.1%}, refused moves "
              f"{refused}/{moves} ({refused / max(taken, 1):.1%} of {taken} steps; "
              f"{lost / max(taken, 1):.1%} of steps lost); 'explored' stops (no frontier left) "
              f"{f['explored_n']}/{f['episodes']}"
              + (f" (questions {', '.join(f['explored_ids'])})" if f["explored_ids"] else "")
              + f"; FAILED, 'explored' before step {EXPLORED_EARLY_STEP}: "
              f"{f['explored_early_n']}/{f['episodes']}"
              + (f" (questions {', '.join(f['explored_early_ids'])})"
                 if f["explored_early_ids"] else "")
              + f"; idle steps (the step before's pose and view again) {f['idle']} in "
              f"{f['idle_walks']} of {f['episodes']} walks")
    explorers = [m for m in methods if not is_reference(m)]
    near = {m: np.mean([np.mean(r[m]["near"]) for r in rows]) for m in explorers}
    for m in explorers:
        if m == "frontier-only":
            continue
        total = {k: sum(sum(r[m][k]) for r in rows)
                 for k in ("steps", "asked", "points", "off_floor", "uninformed")}
        print(f"  {m}: {1 - means[m] / means['frontier-only']:.0%} fewer steps than "
              f"frontier-only; {total['asked'] / max(total['steps'], 1):.0%} of steps offered "
              f"lettered directions; {total['off_floor']}/{total['points']} prompted points off "
              f"the navigable floor; {total['uninformed']} asked steps where no point led to the "
              f"evidence; steps until within {NEAR_M} m (path) of the evidence or seeing it "
              f"{near[m]:.2f} against frontier-only {near['frontier-only']:.2f} "
              f"({1 - near[m] / near['frontier-only']:.0%} fewer)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "steering.json").write_text(json.dumps({"args": vars(args), "rows": rows,
                                                   "flagged": flagged,
                                                   "code_version": code_version()}, indent=1))
    print(f"rows: {out / 'steering.json'}")


def method_summary(rows: list[dict], method: str, to_budget: bool = True) -> dict:
    """One method's figures over ``rows`` of a steering run: mean steps until the evidence is
    first in view (never seen: budget + 1), the same over the oracle's mean steps
    (``x_oracle``) and per question (``x_oracle_q``: each question's mean over its episodes of
    steps / oracle steps, averaged over questions), never seen (share and count), floor
    coverage at the episode's end, refused moves and prompted steps per step, and the explorer's
    "explored" stops (no frontier left; in runs recorded before they were counted: the
    episodes that ended before the budget without the evidence in view, or, in a ``to_budget``
    run, before the budget at all). An "explored" stop before step ``EXPLORED_EARLY_STEP`` is a
    failure (the map held no frontier from the start, e.g. a start pose against a door leaf),
    counted apart (``explored_early_n``): such an episode is not a fast one. ``idle``: steps
    whose pose and view are the step before's again (``common.idle_steps``), in ``idle_walks``
    episodes."""
    steps = np.concatenate([_steps(r, method) for r in rows])
    taken = max(sum(sum(r[method]["steps"]) for r in rows), 1)
    cover = [c for r in rows for c in r[method].get("coverage", [])]
    never = [s is None for r in rows for s in r[method]["first_seen"]]
    explored_ids = []
    explored_n = 0
    early_ids = []
    early_n = 0
    for r in rows:
        got = r[method]
        early = [e is not None and e < EXPLORED_EARLY_STEP for e in got.get("explored", [])]
        early_n += sum(early)
        if any(early):
            early_ids.append(r["id"])
        if "explored" in got:
            stops = [e is not None for e in got["explored"]]
        elif "coverage" in got:  # an explorer's episode ends early only by the stop or a sight
            stops = [n < r["budget"] and (to_budget or seen is None)
                     for n, seen in zip(got["steps"], got["first_seen"])]
        else:
            stops = []
        explored_n += sum(stops)
        if any(stops):
            explored_ids.append(r["id"])
    return {"steps": float(steps.mean()),
            "x_oracle": float(steps.mean() / np.mean([r["oracle"] for r in rows])),
            "x_oracle_q": float(np.mean([np.mean(_steps(r, method)) / r["oracle"] for r in rows])),
            "never": float(np.mean(never)), "never_n": int(sum(never)), "episodes": len(never),
            "coverage": float(np.mean(cover)) if cover else float("nan"),
            "refused": sum(sum(r[method]["refused"]) for r in rows) / taken,
            "asked": sum(sum(r[method].get("asked", [0])) for r in rows) / taken,
            "explored_n": explored_n, "explored_ids": explored_ids,
            "explored_early_n": early_n, "explored_early_ids": early_ids,
            "idle": sum(sum(r[method].get("idle", [])) for r in rows),
            "idle_walks": sum(n > 0 for r in rows for n in r[method].get("idle", []))}


def cmd_table(args: argparse.Namespace) -> None:
    """A markdown table of steering runs (their steering.json files): one line per run and
    method, with the share of steps fewer than the run's frontier-only."""
    print("| run | method | steps to the evidence (x oracle) | never seen | floor explored | "
          "fewer steps than frontier-only | steps offering directions | refused moves / step | "
          "first sight / oracle, per question | 'explored' stops | failed: 'explored' before "
          f"step {EXPLORED_EARLY_STEP} |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    notes: list[str] = []
    for name in args.files:
        run = json.loads(Path(name).read_text())
        rows, a = run["rows"], run["args"]
        label = Path(name).parent.name
        methods = [m for m in rows[0] if m == "frontier-only" or m.startswith(("sfe", "target"))
                   or is_reference(m)]
        refs = "; reference policies: one deterministic episode per question" * any(
            is_reference(m) for m in methods)
        notes.append(f"- `{label}`: {len(rows)} questions in houses "
                     f"{', '.join(map(str, sorted({r['house'] for r in rows})))} x {a['repeats']} "
                     f"explorer seeds{refs}; code {run.get('code_version', 'not recorded')}")
        base = (method_summary(rows, "frontier-only", a["to_budget"])["steps"]
                if "frontier-only" in methods else None)
        for m in methods:
            f = method_summary(rows, m, a["to_budget"])
            ref = is_reference(m)
            fewer = "" if m == "frontier-only" or base is None else f"{1 - f['steps'] / base:.0%}"
            asked = "" if m == "frontier-only" or ref else f"{f['asked']:.0%}"
            cover = ("" if ref else f"{f['coverage']:.1%}" if a["to_budget"]
                     else "(episodes end at first sight)")
            explored = "" if ref else f"{f['explored_n']}/{f['episodes']}"
            early = "" if ref else f"{f['explored_early_n']}/{f['episodes']}"
            print(f"| {label} | {m} | {f['steps']:.2f} (x{f['x_oracle']:.2f}) | {f['never']:.1%} "
                  f"| {cover} | {fewer} | {asked} | {f['refused']:.1%} | x{f['x_oracle_q']:.2f} "
                  f"| {explored} | {early} |")
    print("\n" + "\n".join(notes))


def _steps(row: dict, method: str) -> np.ndarray:
    """Steps until first in view per explorer seed; budget + 1 when never seen."""
    return np.array([s if s is not None else row["budget"] + 1 for s in row[method]["first_seen"]],
                    float)


def is_reference(method: str) -> bool:
    return method.startswith("reference:")


def steering_method(name: str) -> str:
    """"frontier-only", "sfe:SCORER" ("sfe" is "sfe:oracle") or "reference:POLICY" (a
    reference policy of reference_policies.py); an unknown one is an error."""
    if name == "frontier-only":
        return name
    explorer, _, scorer = name.partition(":")
    if explorer == "reference" and scorer in REFERENCE_POLICIES:
        return name
    if explorer == "target" and scorer in ("", "frontier-only"):
        return "target:frontier-only"
    if explorer not in ("sfe", "target") or (scorer or "oracle") not in STEERING_SCORERS:
        raise SystemExit(f"unknown steering method {name!r}: frontier-only, sfe:SCORER with "
                         f"SCORER one of {', '.join(STEERING_SCORERS)}, or reference:POLICY "
                         f"with POLICY one of {', '.join(REFERENCE_POLICIES)}")
    return f"{explorer}:{scorer or 'oracle'}"


def _steer(env: SyntheticEnv, q: Question, config: AgentConfig, budget: int, seed: int,
           repeats: int, to_budget: bool,
           methods: tuple[str, ...] = ("frontier-only", "sfe:oracle"),
           reading: TargetReading | None = None) -> dict:
    """Each method's episodes over ``repeats`` explorer seeds (SFE samples frontiers), run by
    the agent with ``config``'s exploration options (``reading``: ``explore_episode``'s)."""
    distance_m = evidence_distance(env, q)

    def seen(instance: np.ndarray) -> bool:
        return evidence_visible(instance, q.evidence)

    def glimpsed(instance: np.ndarray) -> bool:  # GSV: any evidence in view, even small
        return any(evidence_visible(instance, [e], min_pixels=20) for e in q.evidence)

    row: dict = {"id": q.id, "house": seed, "category": q.category, "oracle": q.oracle_steps,
                 "budget": budget, "reachable": distance_m.reachable}
    for name in methods:
        if is_reference(name):
            row[name] = _reference(env, q, name.partition(":")[2], budget, distance_m)
            continue
        kind, _, scorer_name = name.partition(":")
        steer = kind == "target"  # target:SCORER steers SFE by the target; target:frontier-only
        scorer = (None if "frontier-only" in (name, scorer_name)
                  else STEERING_SCORERS[scorer_name](env, q, distance_m, glimpsed))
        method = with_leaves(config, explorer="frontier-only" if scorer is None else "sfe",
                         steering="target" if steer else "none", max_steps=budget)
        got: dict[str, list] = {k: [] for k in ("first_seen", "near", "coverage", "steps",
                                                "moves", "refused", "lost", "asked", "points",
                                                "off_floor", "uninformed", "explored", "idle")}
        for r in range(repeats):
            ep = explore_episode(env, with_leaves(method, seed=seed * 1000 + r), q.question,
                                 scorer=scorer, seen=seen, near=distance_m, coverage=True,
                                 to_budget=to_budget, reading=reading)
            got["first_seen"].append(ep.first_seen)
            # Seeing implies having got near enough.
            got["near"].append(ep.first_near or ep.first_seen or budget + 1)
            got["coverage"].append(ep.coverage[-1] if ep.coverage else 0.0)
            got["steps"].append(ep.steps)
            for k in ("moves", "refused", "lost", "asked", "points", "off_floor", "uninformed",
                      "explored"):
                got[k].append(getattr(ep, k))
            # steps whose pose and view are the step before's again (refused moves included)
            got["idle"].append(len(idle_steps([(p.x, p.y, p.yaw) for p in ep.poses])))
        row[name] = got
    return row


def _reference(env: SyntheticEnv, q: Question, policy: str, budget: int,
               distance_m: EvidenceDistance) -> dict:
    """One episode of a reference policy (deterministic), in the row format of the explorers'
    (lists of one) with its own counts beside."""
    ep = run_policy(env, q, policy, budget, near=distance_m, near_m=NEAR_M)
    return {"first_seen": [ep.first_seen],
            "near": [ep.first_near or ep.first_seen or budget + 1],
            "steps": [ep.steps], "moves": [ep.moves], "turns": [ep.turns],
            "refused": [ep.refused], "lost": [0], "approaches": [ep.approaches],
            "first_glimpse": [ep.first_glimpse], "metres": [round(ep.metres, 2)],
            "rooms_entered": [ep.rooms_entered], "doors_seen": [ep.doors_seen],
            "stop": [ep.stop], "trace": [ep.trace]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     epilog=__doc__.split("\n\n", 1)[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("job", choices=["cost", "coverage", "steering", "table"])
    parser.add_argument("files", nargs="*", help="table: steering.json files of earlier runs")
    parser.add_argument("--assets", default="sh3d", choices=["sh3d", "builtin"])
    parser.add_argument("--houses", type=int, default=10)
    parser.add_argument("--questions", type=int, default=30)
    parser.add_argument("--repeats", type=int, default=3, help="explorer seeds per question")
    parser.add_argument("--seeds", default="held-out",
                        help="steering houses: 'held-out' (2000-2999, never tuned on; report "
                             "these), 'training' (0-20, the development houses), or seeds such "
                             "as '0-9'")
    parser.add_argument("--split", type=int, default=0, metavar="N",
                        help="steering: the questions with evidence among the first N of the "
                             "synthetic split (the main table's: --split 48) instead of --seeds")
    parser.add_argument("--per-house", type=int, default=3,
                        help="steering: at most this many questions per house")
    parser.add_argument("--to-budget", action=argparse.BooleanOptionalAction, default=True,
                        help="steering: run every episode to its budget (floor coverage at the "
                             "budget), recording when the evidence was first in view")
    parser.add_argument("--methods", default="frontier-only,sfe:oracle",
                        help="steering: comma-separated; frontier-only comes first (unless "
                             "only reference policies are asked for), then sfe:SCORER with "
                             "SCORER one of " + ", ".join(STEERING_SCORERS) + ", and "
                             "reference:POLICY with POLICY one of "
                             + ", ".join(REFERENCE_POLICIES))
    parser.add_argument("--prompt", dest="prompts", default="default", choices=list(PROMPT_CONFIGS),
                        help="where prompt points may lie: default, or paper (DESIGN 3.3's: "
                             "2-10 m, 1 m apart); AgentConfig.prompts")
    parser.add_argument("--exploration", default="default", choices=list(EXPLORATIONS),
                        help="the frontier explorer's options beyond DESIGN 3.2: default, or "
                             "paper (every one off; with --stop-clearance 0 --refusal-retries 0 "
                             "--prompt paper: the paper preset)")
    parser.add_argument("--map-extent", default="start", choices=["start", "scene"],
                        help="the agent's map: around the start (what a robot can do) or over "
                        "the house's box (runs before run format 4)")
    parser.add_argument("--noise", default="none", help="a robot's imperfections: a noise "
                        "profile of envs/synthetic/noise.py (none, robot, robot-depth, ...)")
    parser.add_argument("--out", default="out/bench")
    parser.add_argument("--stop-clearance", type=float, default=None,
                        help="metres of map clearance the planner wants where a move ends "
                             "(default: the explorer's; 0: where the path is cut, as before)")
    parser.add_argument("--refusal-retries", type=int, default=None,
                        help="re-plans within a step after a refused move (default "
                             f"{REFUSAL_RETRIES}; 0: a refused move spends the step, as before)")
    args = parser.parse_args()
    jobs = {"cost": cmd_cost, "coverage": cmd_coverage, "steering": cmd_steering, "table": cmd_table}
    jobs[args.job](args)


if __name__ == "__main__":
    main()
