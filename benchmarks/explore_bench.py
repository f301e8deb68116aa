"""Exploration benchmarks (DESIGN 3.2, 8; results/explore/): per-step cost, coverage, and semantic steering.

Back-ends: synthetic environment (Sweet Home 3D CC0 furniture, or --assets builtin), depth and
instance buffers rendered with moderngl/EGL on the CPU; no model: semantic values are either
absent (frontier-only, random) or the ground-truth oracle (explore/oracle.py).

    python benchmarks/explore_bench.py cost      # ms per step in a 6-room house
    python benchmarks/explore_bench.py coverage  # explored floor vs step, frontier-only vs random
    python benchmarks/explore_bench.py steering  # steps to see the evidence, oracle SFE vs frontier-only
    python benchmarks/explore_bench.py steering --methods reference:target-room,reference:room-by-room
                                                 # the reference policies (reference_policies.py)

House seeds: the development houses 0-20 (``--seeds training``) are the ones every earlier
choice of the explorer was tuned on; the held-out houses 2000-2999 (``--seeds held-out``, the
default of ``steering``) were never used for tuning and are disjoint from the synthetic split
(100-999, ``datasets/synthetic.py``) and the relevancy calibration (1000-1019). Report targets
on held-out houses only.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from efficienteqa.agent import mapper_for
from efficienteqa.datasets.synthetic import parse_seeds
from efficienteqa.envs.synthetic.env import SyntheticEnv, catalog_for
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M, generate_house
from efficienteqa.envs.synthetic.questions import Question, evidence_visible
from efficienteqa.explore.module import REFUSAL_RETRIES as module_retries
from efficienteqa.explore.module import ExploreModule, SemanticScorer, move
from efficienteqa.explore.oracle import EvidenceDistance, OracleScorer, evidence_distance_field
from efficienteqa.explore.prompting import PAPER_PROMPTS, PromptConfig
from efficienteqa.explore.registry import EXPLORATIONS, exploration_options, make_explorer
from efficienteqa.explore.sfe import FrontierExplorer
from efficienteqa.explore.target import TargetExplorer
from efficienteqa.mapping.maps2d import Mapper
from efficienteqa.perception.semantic import SemanticPerception
from efficienteqa.question import parse_question
from efficienteqa.records import code_version
from efficienteqa.scenes import synthetic_questions

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reference_policies import POLICIES as REFERENCE_POLICIES  # noqa: E402
from reference_policies import run_policy  # noqa: E402

TRAINING_SEEDS = range(0, 21)  # development houses: tuned on
HELD_OUT_SEEDS = range(2000, 3000)  # never used for tuning


def seed_set(spec: str) -> list[int]:
    """"training" (0-20), "held-out" (2000-2999), or explicit seeds ("0-9", "3,5")."""
    named = {"training": TRAINING_SEEDS, "held-out": HELD_OUT_SEEDS}
    return list(named[spec]) if spec in named else parse_seeds(spec)


def step_budget(env: SyntheticEnv) -> int:
    return int(math.sqrt(env.floor_area_m2) * 3)


WINDOW: tuple[float, float, float, float] | None = None  # --window: explored window override
EXPLORED_DEPTH: float | None = None  # --explored-depth override
STOP_CLEARANCE: float | None = None  # --stop-clearance override
REFUSAL_RETRIES = module_retries  # --refusal-retries override
EXPLORER_CONFIG: dict = {}  # --set FIELD=VALUE overrides of the explorer's config
EXPLORATION = "default"  # --exploration: a key of explore.registry.EXPLORATIONS
PROMPTS = PromptConfig()  # --prompt FIELD=VALUE overrides; --prompt paper: DESIGN 3.3's

# Semantic scorers for steering: name -> factory(env, question, evidence distance, glimpsed).
# "oracle" is the ground truth; others (model-free text scorers, model elicitations) register
# here. A steering method is "frontier-only" or "sfe:SCORER" ("sfe" alone is "sfe:oracle").
ScorerFactory = Callable[[SyntheticEnv, Question, EvidenceDistance, Callable[[np.ndarray], bool]],
                         SemanticScorer]
STEERING_SCORERS: dict[str, ScorerFactory] = {
    "oracle": lambda env, q, distance_m, glimpsed: OracleScorer(distance_m, glimpsed),
}


def _text_scorer(name: str) -> ScorerFactory:
    """A model-free direction scorer of the offline stack (stack.EXPLORE_SCORERS) over the
    semantic perception's direction texts (DESIGN 8)."""
    def factory(env: SyntheticEnv, q: Question, distance_m: EvidenceDistance,
                glimpsed: Callable[[np.ndarray], bool]) -> SemanticScorer:
        from efficienteqa.perception.semantic import SemanticPerception
        from efficienteqa.stack import EXPLORE_SCORERS

        return EXPLORE_SCORERS.build(name, perception=SemanticPerception(env.scene_labels()))
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


def make_mapper(env: SyntheticEnv) -> Mapper:
    extra: dict = {"explored_window": WINDOW} if WINDOW else {}
    if EXPLORED_DEPTH is not None:
        extra["explored_depth_m"] = EXPLORED_DEPTH
    return mapper_for(env, (env.house.start.x, env.house.start.y), **extra)


def truth_floor(env: SyntheticEnv, mapper: Mapper) -> np.ndarray:
    """Ground-truth free floor sampled at the map's cell centres."""
    xs, ys = mapper.spec.centres()
    i, j = env.grid.spec.world_to_cell(np.stack([xs, ys], axis=-1))
    ok = env.grid.spec.contains((i, j))
    out = np.zeros(xs.shape, bool)
    out[ok] = env.grid.free[i[ok], j[ok]]
    return out


@dataclass
class Episode:
    coverage: list[float] = field(default_factory=list)
    first_seen: int | None = None
    first_near: int | None = None  # first step within NEAR_M (path) of the evidence
    steps: int = 0
    step_ms: list[float] = field(default_factory=list)
    moves: int = 0  # moves asked of the environment (re-planned tries included)
    refused: int = 0  # of which the environment refused
    lost: int = 0  # steps whose every try was refused: the robot stayed
    asked: int = 0  # steps that offered lettered directions to the scorer
    points: int = 0  # prompted points
    off_floor: int = 0  # of which not navigable on the true grid
    uninformed: int = 0  # asked steps where no point had a finite oracle distance
    explored: int | None = None  # the step at which the explorer found no frontier left


NEAR_M = 2.0


def run(env: SyntheticEnv, explorer: str, budget: int, seed: int,
        scorer: SemanticScorer | None = None, seen: Callable[[np.ndarray], bool] | None = None,
        coverage: bool = False, distance_m: Callable[[tuple[float, float]], float] | None = None,
        to_budget: bool = False, question: str = "", steer: bool = False) -> Episode:
    """One episode of ``budget`` steps at most. It ends when ``seen`` first holds, unless
    ``to_budget`` (then it goes on, for the coverage at the budget). ``steer``: the frontier
    explorer steered by the question's target (explore/target.py), reading the semantic
    perception's sightings."""
    mapper = make_mapper(env)
    extra = {**exploration_options(explorer, EXPLORATION), **EXPLORER_CONFIG}
    if STOP_CLEARANCE is not None:
        extra["stop_clearance_m"] = STOP_CLEARANCE
    chosen = make_explorer(explorer, **extra)
    target = parse_question(question) if steer else None
    perception = SemanticPerception(env.scene_labels()) if steer else None
    if steer and isinstance(chosen, FrontierExplorer):
        chosen = TargetExplorer(chosen)
    module = ExploreModule(mapper, chosen, scorer, seed=seed, prompts=PROMPTS, target=target)
    floor = truth_floor(env, mapper) if coverage else None
    obs, _ = env.reset()
    ep = Episode()
    for step in range(1, budget + 1):
        ep.steps = step
        if (ep.first_near is None and distance_m is not None
                and distance_m((obs.pose.x, obs.pose.y)) <= NEAR_M):
            ep.first_near = step
        if ep.first_seen is None and seen is not None and seen(obs.instance):
            ep.first_seen = step
            if not to_budget:
                break
        start = time.perf_counter()
        sightings = (perception.sightings(obs, target)
                     if perception is not None and target is not None else None)
        out = module.step(obs, step, question, sightings)
        ep.step_ms.append(1e3 * (time.perf_counter() - start))
        if out.prompts:
            ep.asked += 1
            ep.points += len(out.prompts)
            ep.off_floor += sum(not env.is_navigable(*p.xy) for p in out.prompts)
            ep.uninformed += bool(out.score and "unreachable" in out.score.info)
        if floor is not None:
            ep.coverage.append(out.state.explored_floor_share(floor))
        if out.decision.done:
            ep.explored = step
            break
        moved = move(env, module, obs.pose, out.decision, step, REFUSAL_RETRIES)
        obs = moved.obs
        ep.moves += moved.refused + (not moved.blocked)
        ep.refused += moved.refused
        ep.lost += moved.blocked
        if moved.decision.done:
            ep.explored = step
            break
    if floor is not None and ep.steps > len(ep.coverage):  # the last frame, fused but not planned on
        mapper.update(obs)
        ep.coverage.append(mapper.state((obs.pose.x, obs.pose.y)).explored_floor_share(floor))
    return ep


def houses(n: int, assets: str, rooms: int | None = None) -> list[int]:
    catalog = catalog_for(assets)
    seeds = [s for s in range(1000)
             if rooms is None or len(generate_house(s, catalog, assets).layout.rooms) == rooms]
    return seeds[:n]


def cmd_cost(args: argparse.Namespace) -> None:
    seed = houses(1, args.assets, rooms=6)[0]
    with SyntheticEnv.from_seed(seed, args.assets) as env:
        run(env, "frontier-only", 5, seed=0)  # warm-up (numba compilation)
        for explorer_seed in range(10):  # an episode long enough to show the cost is flat
            ep = run(env, "frontier-only", 40, seed=explorer_seed)
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
            budget = step_budget(env)
            for name in curves:
                ep = run(env, name, budget, seed=seed, coverage=True)
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
                    yield seed, env, step_budget(env), q
        return
    for seed in seed_set(args.seeds):
        with SyntheticEnv.from_seed(seed, args.assets) as env:
            asked = [q for q in synthetic_questions(env) if q.evidence]
            # A few questions per house, their order turned by the seed: many houses, every kind.
            turn = seed % len(asked) if asked else 0
            for q in (asked[turn:] + asked[:turn])[:args.per_house]:
                yield seed, env, step_budget(env), q


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
        row = _steer(env, q, budget, seed, args.repeats, args.to_budget, methods)
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
              + (f" (questions {', '.join(f['explored_ids'])})" if f["explored_ids"] else ""))
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
    run, before the budget at all)."""
    steps = np.concatenate([_steps(r, method) for r in rows])
    taken = max(sum(sum(r[method]["steps"]) for r in rows), 1)
    cover = [c for r in rows for c in r[method].get("coverage", [])]
    never = [s is None for r in rows for s in r[method]["first_seen"]]
    explored_ids = []
    explored_n = 0
    for r in rows:
        got = r[method]
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
            "explored_n": explored_n, "explored_ids": explored_ids}


def cmd_table(args: argparse.Namespace) -> None:
    """A markdown table of steering runs (their steering.json files): one line per run and
    method, with the share of steps fewer than the run's frontier-only."""
    print("| run | method | steps to the evidence (x oracle) | never seen | floor explored | "
          "fewer steps than frontier-only | steps offering directions | refused moves / step | "
          "first sight / oracle, per question | 'explored' stops |")
    print("|---|---|---|---|---|---|---|---|---|---|")
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
            print(f"| {label} | {m} | {f['steps']:.2f} (x{f['x_oracle']:.2f}) | {f['never']:.1%} "
                  f"| {cover} | {fewer} | {asked} | {f['refused']:.1%} | x{f['x_oracle_q']:.2f} "
                  f"| {explored} |")
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


def evidence_centre(env: SyntheticEnv, q: Question) -> np.ndarray:
    """The mean (x, y) of the question's evidence objects, metres."""
    return np.mean([[o.x, o.y] for o in (env.house.object(e) for e in q.evidence)], axis=0)


def evidence_distance(env: SyntheticEnv, q: Question) -> EvidenceDistance:
    """Path distance to the evidence's views reachable from the start: the floor near it in its
    own room(s) (a plain snap to the nearest floor cell can land behind a wall) and the oracle's
    pose; a point off the navigable floor counts from the nearest navigable cell (see
    explore/oracle.py). ``reachable`` is False when no view is reachable from the start."""
    objects = [env.house.object(e) for e in q.evidence]
    rooms = {(r.x0, r.y0, r.x1, r.y1) for r in (env.house.room(o.room_id) for o in objects)}
    start = (env.house.start.x, env.house.start.y)
    views = [q.oracle_pose[:2]] if q.oracle_pose else []
    field_m = evidence_distance_field(env.grid, evidence_centre(env, q), ROBOT_RADIUS_M,
                                      sorted(rooms), 2.0, start_xy=start, views=views)
    return EvidenceDistance(env.grid, field_m, ROBOT_RADIUS_M)


def _steer(env: SyntheticEnv, q: Question, budget: int, seed: int, repeats: int,
           to_budget: bool, methods: tuple[str, ...] = ("frontier-only", "sfe:oracle")) -> dict:
    """Each method's episodes over ``repeats`` explorer seeds (SFE samples frontiers)."""
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
        explorer = "frontier-only" if scorer is None else "sfe"
        got: dict[str, list] = {k: [] for k in ("first_seen", "near", "coverage", "steps",
                                                "moves", "refused", "lost", "asked", "points",
                                                "off_floor", "uninformed", "explored")}
        for r in range(repeats):
            ep = run(env, explorer, budget, seed=seed * 1000 + r, scorer=scorer, seen=seen,
                     coverage=True, distance_m=distance_m, to_budget=to_budget,
                     question=q.question, steer=steer)
            got["first_seen"].append(ep.first_seen)
            # Seeing implies having got near enough.
            got["near"].append(ep.first_near or ep.first_seen or budget + 1)
            got["coverage"].append(ep.coverage[-1] if ep.coverage else 0.0)
            got["steps"].append(ep.steps)
            for k in ("moves", "refused", "lost", "asked", "points", "off_floor", "uninformed",
                      "explored"):
                got[k].append(getattr(ep, k))
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
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                        help="override a field of the explorer's config (repeatable), e.g. "
                             "--set backoff_m=1.0")
    parser.add_argument("--prompt", action="append", default=[], metavar="FIELD=VALUE",
                        help="override a field of the prompt points' PromptConfig (repeatable); "
                             "'--prompt paper' starts from DESIGN 3.3's (2-10 m, 1 m apart)")
    parser.add_argument("--exploration", default="default", choices=list(EXPLORATIONS),
                        help="the frontier explorer's options beyond DESIGN 3.2: default, or "
                             "paper (every one off; with --stop-clearance 0 --refusal-retries 0 "
                             "--prompt paper: the paper preset)")
    parser.add_argument("--out", default="out/bench")
    parser.add_argument("--explored-depth", type=float, default=None,
                        help="metres along the optical axis within which floor counts as explored")
    parser.add_argument("--stop-clearance", type=float, default=None,
                        help="metres of map clearance the planner wants where a move ends "
                             "(default: the explorer's; 0: where the path is cut, as before)")
    parser.add_argument("--refusal-retries", type=int, default=None,
                        help="re-plans within a step after a refused move (default "
                             f"{module_retries}; 0: a refused move spends the step, as before)")
    parser.add_argument("--window", type=float, nargs=4, default=None,
                        metavar=("U0", "U1", "V0", "V1"),
                        help="explored window as image fractions (default: the Mapper's)")
    args = parser.parse_args()
    global WINDOW, EXPLORED_DEPTH, STOP_CLEARANCE, REFUSAL_RETRIES, PROMPTS, EXPLORATION
    EXPLORATION = args.exploration
    prompt: dict = {}
    for item in args.prompt:
        if item == "paper":
            PROMPTS = PAPER_PROMPTS
            continue
        key, _, value = item.partition("=")
        prompt[key] = json.loads(value)
    PROMPTS = replace(PROMPTS, **prompt)
    for item in args.set:
        key, _, value = item.partition("=")
        EXPLORER_CONFIG[key] = json.loads(value)
    WINDOW = tuple(args.window) if args.window else None
    EXPLORED_DEPTH = args.explored_depth
    STOP_CLEARANCE = args.stop_clearance
    if args.refusal_retries is not None:
        REFUSAL_RETRIES = args.refusal_retries
    jobs = {"cost": cmd_cost, "coverage": cmd_coverage, "steering": cmd_steering, "table": cmd_table}
    jobs[args.job](args)


if __name__ == "__main__":
    main()
