"""The targets of question reading, reaching the evidence and answering (DESIGN 9), in one command.

    python -m experiments.targets --run results/main-heldout/default
    python -m experiments.targets --seeds 2000-2009 --questions 30 --repeats 3 --run RUN --out DIR

Exploration (stop off; the agent's own loop, ``experiments.common.explore_episode``, each
episode ending at first sight): the default explorer (``target:direction-logit``: SFE with the
model-free direction scorer, steered by the question's target) on ``--questions`` questions of
the held-out houses ``--seeds`` (``--per-house`` each, as ``explore_bench steering``) x
``--repeats`` explorer seeds, beside the yardstick ``reference:named-room`` ("knows the named
room", reference_policies.py; one deterministic episode). Never seen counts as budget + 1.
Rows: first sight / oracle; on the questions that name a room, the default's against the
yardstick's on the same questions; never seen; location questions' first sight / oracle; idle
steps (the step before's pose and view again); explorer "explored" stops before step 5
(failures). Location questions are few among those, so the location row adds up to
``--location`` more of the same houses' location questions (the houses in order).

From an evaluation run folder (``--run``; its ``episodes.jsonl``): accuracy by the rule judge,
steps / oracle (questions with evidence), count questions' first sight -> stop (the episodes
that saw the evidence before they stopped, whatever stopped them: the budget too), "no"
existence questions answered "no", "explored" stops before step 5 (failures), relevancy
stops whose tested frame shows the evidence at 250 px and at 150 px where the rows record it
(``evidence_stop_pixels``), and, by walking its episodes again (``experiments.stop_audit``;
``--no-audit`` skips it), the same for runs recorded before that field, and idle steps in those
walks.

Back-ends: synthetic houses (sh3d), semantic-sensor perception, no language model for the
exploration rows (a stub answers); the run's rows are what its own back-ends recorded.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.agent import AgentConfig
from efficienteqa.config.knobs import with_leaves
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.questions import Question
from efficienteqa.models.backends import build_chat_model
from efficienteqa.reading.adjacency import RoomAdjacency
from efficienteqa.reading.target import TargetReading
from efficienteqa.records import code_version
from efficienteqa.scenes import synthetic_questions
from efficienteqa.stack import parse_vlm
from efficienteqa.stop.rules import env_step_budget
from experiments import explore_bench as bench
from experiments.common import seed_set
from experiments.reference_policies import named_rooms

DEFAULT = "target:direction-logit"  # the agent's default explorer, as the steering bench names it
YARDSTICK = "reference:named-room"


def explore_rows(args: argparse.Namespace) -> list[dict[str, Any]]:
    """The steering bench's rows of the default explorer and the yardstick, each marked with
    whether its question names a room."""
    ns = argparse.Namespace(split=0, seeds=args.seeds, assets="sh3d", per_house=args.per_house,
                            stop_clearance=None, refusal_retries=None, exploration="default",
                            prompts="default", map_extent="start", noise="none")
    rows: list[dict[str, Any]] = []
    for seed, env, budget, q in bench.steering_questions(ns):
        if len(rows) >= args.questions:
            break
        row = bench._steer(env, q, _config(ns, args), budget, seed, args.repeats, False,
                           (DEFAULT, YARDSTICK), args.reading)
        if not row["reachable"]:
            print(f"{q.id}: no view of the evidence is reachable from the start; left out")
            continue
        rows.append(_mark(row, q, env))
    return rows


def location_rows(args: argparse.Namespace, skip: set[str]) -> list[dict[str, Any]]:
    """Rows of the location questions ("Where is the X?": no room named) of the same houses,
    beyond those already run (``skip``): up to ``--location`` of them, the houses in order."""
    ns = argparse.Namespace(stop_clearance=None, refusal_retries=None, exploration="default",
                            prompts="default", map_extent="start")
    rows: list[dict[str, Any]] = []
    for seed in seed_set(args.seeds):
        if len(rows) >= args.location:
            break
        with SyntheticEnv.from_seed(seed, "sh3d") as env:
            for q in synthetic_questions(env):
                if q.category != "location" or not q.evidence or q.id in skip:
                    continue
                if len(rows) >= args.location:
                    break
                row = bench._steer(env, q, _config(ns, args), env_step_budget(env), seed,
                                   args.repeats, False, (DEFAULT, YARDSTICK), args.reading)
                if row["reachable"]:
                    rows.append(_mark(row, q, env))
    return rows


def _config(ns: argparse.Namespace, args: argparse.Namespace) -> AgentConfig:
    """The bench's agent configuration with the ``--target`` (steering) and ``--sfe``
    (frontier explorer) overrides."""
    config = bench.agent_config(ns)
    for section in ("target", "sfe"):
        overrides = {}
        for item in getattr(args, section):
            key, _, value = item.partition("=")
            try:
                overrides[key] = json.loads(value)
            except ValueError:
                overrides[key] = value
        if overrides:
            config = with_leaves(config, **{section: overrides})
    return config


def _reading(args: argparse.Namespace) -> TargetReading | None:
    """The rules' reading with the named room's neighbours from ``--vlm`` where the steering
    asks for them (``--target near_rooms=true``); None otherwise (no model)."""
    if not _config(argparse.Namespace(exploration="default", prompts="default",
                                      map_extent="start", stop_clearance=None,
                                      refusal_retries=None), args).explore.target_config().near_rooms:
        return None
    model = build_chat_model(parse_vlm(args.vlm, images=False))
    return TargetReading("rules", "words", adjacency=RoomAdjacency(model))


def _mark(row: dict[str, Any], q: Question, env: SyntheticEnv) -> dict[str, Any]:
    """The row marked with whether its question names a room, and printed."""
    row["names_room"] = bool(named_rooms(q.question, env.house.layout.rooms))
    print(f"{q.id} {q.category:14s} oracle {row['oracle']:2d}  "
          + "  ".join(f"{m} {np.mean(bench._steps(row, m)):5.1f}" for m in (DEFAULT, YARDSTICK))
          + f"  {q.question}", flush=True)
    return row


def explore_targets(rows: Sequence[dict[str, Any]], more_where: Sequence[dict[str, Any]] = ()
                    ) -> dict[str, Any]:
    """The exploration rows' figures; the location figure over ``rows``' location questions and
    ``more_where`` (more location questions of the same houses)."""
    def x(sub: Sequence[dict[str, Any]], m: str) -> float | None:
        return bench.method_summary(list(sub), m, False)["x_oracle"] if sub else None

    naming = [r for r in rows if r["names_room"]]
    where = [r for r in rows if r["category"] == "location"] + list(more_where)
    f = bench.method_summary(list(rows), DEFAULT, False)
    slower = sum(np.mean(bench._steps(r, DEFAULT)) > np.mean(bench._steps(r, YARDSTICK))
                 for r in naming)
    return {"questions": len(rows), "houses": sorted({r["house"] for r in rows}),
            "first_sight_x_oracle": f["x_oracle"],
            "yardstick_first_sight_x_oracle": x(rows, YARDSTICK),
            "naming_questions": len(naming),
            "naming_first_sight_x_oracle": x(naming, DEFAULT),
            "naming_yardstick_x_oracle": x(naming, YARDSTICK),
            "naming_slower_than_yardstick": int(slower),
            "never_seen": f["never"], "never_seen_n": f["never_n"], "episodes": f["episodes"],
            "location_questions": len(where),
            "location_first_sight_x_oracle": x(where, DEFAULT),
            "location_yardstick_x_oracle": x(where, YARDSTICK),
            "idle_steps": f["idle"], "idle_walks": f["idle_walks"],
            "explored_early": f["explored_early_n"],
            "by_category": {c: {"questions": len(sub), "first_sight_x_oracle": x(sub, DEFAULT),
                                "yardstick_x_oracle": x(sub, YARDSTICK)}
                            for c in sorted({r["category"] for r in rows})
                            for sub in [[r for r in rows if r["category"] == c]]}}


def run_targets(folder: Path) -> dict[str, Any]:
    """The eval run's rows (module docstring)."""
    rows = [json.loads(line) for line in (folder / "episodes.jsonl").read_text().splitlines()
            if line.strip()]
    rows = [r for r in rows if r.get("status") == "done"]

    def right(r: dict[str, Any]) -> bool:
        return (r.get("rule") or {}).get("score") == 5

    has = [r for r in rows if r.get("oracle_steps")]
    counts = [r["steps"] - r["evidence_first_seen_step"] for r in has
              if r["category"] == "count" and r.get("evidence_first_seen_step") is not None
              and r["evidence_first_seen_step"] <= r["steps"]]
    no = [r for r in rows if r["category"] == "existence" and r["reference"].lower() == "no"]
    early = [r["id"] for r in rows if r["stop_reason"] == "explored"
             and r["steps"] < bench.EXPLORED_EARLY_STEP]
    stops = [r for r in has if r["stop_reason"] == "relevancy"
             and r.get("evidence_stop_pixels") is not None]  # runs that record the stop's frame
    return {"run": str(folder), "episodes": len(rows),
            "recorded_stops": len(stops),
            **{f"recorded_stops_showing_{px}px": sum(r["evidence_stop_pixels"] >= px
                                                     for r in stops) for px in (250, 150)},
            "accuracy_rule": float(np.mean([right(r) for r in rows])),
            "right": sum(map(right, rows)),
            "steps_x_oracle": float(np.mean([r["steps"] for r in has])
                                    / np.mean([r["oracle_steps"] for r in has])),
            "count_sight_to_stop_mean": float(np.mean(counts)) if counts else None,
            "count_sight_to_stop_n": len(counts),
            "never_seen_before_stop": sum(r.get("evidence_first_seen_step") is None
                                          or r["evidence_first_seen_step"] > r["steps"]
                                          for r in has),
            "with_evidence": len(has),
            "no_answered_no": sum(map(right, no)), "no_questions": len(no),
            "explored_early": early}


def table(explore: dict[str, Any] | None, run: dict[str, Any] | None,
          audit: dict[str, Any] | None, args: argparse.Namespace) -> str:
    """The issue's target table with today's values."""
    def f(v: float | None, fmt: str = "{:.2f}x") -> str:
        return "n/a" if v is None else fmt.format(v)

    lines = ["| measure | now | target |", "|---|---|---|"]
    if explore:
        e = explore
        ratio = (e["naming_first_sight_x_oracle"] / e["naming_yardstick_x_oracle"]
                 if e["naming_questions"] else None)
        lines += [
            f"| first sight / oracle, {args.seeds}, stop off (never = budget + 1) | "
            f"{f(e['first_sight_x_oracle'])} (yardstick {f(e['yardstick_first_sight_x_oracle'])})"
            " | <= 2.0x |",
            f"| first sight / oracle on the {e['naming_questions']} questions naming a room, "
            f"against \"knows the named room\" | {f(e['naming_first_sight_x_oracle'])} vs "
            f"{f(e['naming_yardstick_x_oracle'])} (x{f(ratio, '{:.2f}')}; slower in "
            f"{e['naming_slower_than_yardstick']} of {e['naming_questions']}) | within 15% |",
            f"| never seen, {args.seeds}, stop off | {e['never_seen']:.1%} "
            f"({e['never_seen_n']}/{e['episodes']}) | 0 |",
            f"| location questions ({e['location_questions']}, {args.seeds}), first sight / "
            "oracle | "
            f"{f(e['location_first_sight_x_oracle'])} (yardstick "
            f"{f(e['location_yardstick_x_oracle'])}) | <= 2.0x |",
            f"| idle steps (same pose and view again), exploration walks to first sight | "
            f"{e['idle_steps']} in {e['idle_walks']} of {e['episodes']} walks | 0 |",
            f"| 'explored' before step {bench.EXPLORED_EARLY_STEP} (failures), exploration | "
            f"{e['explored_early']}/{e['episodes']} | 0 |"]
        lines += [f"| ... {c} questions ({v['questions']}), first sight / oracle | "
                  f"{f(v['first_sight_x_oracle'])} (yardstick {f(v['yardstick_x_oracle'])}) | - |"
                  for c, v in e.get("by_category", {}).items()]
    if run:
        r = run
        lines += [
            f"| main table accuracy, rule judge | {r['accuracy_rule']:.1%} "
            f"({r['right']}/{r['episodes']}) | >= 88% |",
            f"| main table steps / oracle | {r['steps_x_oracle']:.2f} | <= 2.5 |",
            f"| count questions, first sight -> stop, mean | "
            f"{f(r['count_sight_to_stop_mean'], '{:.1f}')} ({r['count_sight_to_stop_n']} "
            "episodes that saw it before the stop, any stop reason) | <= 2 |",
            f"| never seen before the stop (main table) | {r['never_seen_before_stop']}/"
            f"{r['with_evidence']} | - |",
            f"| \"no\" existence questions answered \"no\" (main table) | {r['no_answered_no']}/"
            f"{r['no_questions']} | all |",
            f"| 'explored' before step {bench.EXPLORED_EARLY_STEP} (failures), main table | "
            f"{len(r['explored_early'])} {' '.join(r['explored_early'])} | 0 |"]
        if r["recorded_stops"]:
            lines.append(
                "| relevancy stops whose frame shows the evidence (250 px; 150 px), as the run "
                f"recorded them | {r['recorded_stops_showing_250px']}/{r['recorded_stops']}; "
                f"{r['recorded_stops_showing_150px']}/{r['recorded_stops']} | >= 95% |")
    if audit:
        a = audit
        lines += [
            f"| relevancy stops whose frame shows the evidence (250 px rule; 150 px) | "
            f"{a['stops_showing_250px']}/{a['relevancy_stops']}; {a['stops_showing_150px']}/"
            f"{a['relevancy_stops']} (walks reproduced {a['reproduced']}/{a['walks']}) "
            "| >= 95% |",
            f"| idle steps, main table walks | {a['idle_steps']} in {a['walks_with_idle']} of "
            f"{a['walks']} walks | 0 |"]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="2000-2009", help="held-out exploration houses")
    ap.add_argument("--questions", type=int, default=30)
    ap.add_argument("--per-house", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=3, help="explorer seeds per question")
    ap.add_argument("--location", type=int, default=10,
                    help="location questions of the same houses beyond the --questions ones "
                         "(their first sight / oracle only)")
    ap.add_argument("--no-explore", action="store_true", help="skip the exploration rows")
    ap.add_argument("--run", type=Path, default=None, help="an evaluation run folder")
    ap.add_argument("--audit", action=argparse.BooleanOptionalAction, default=True,
                    help="walk the run's episodes again for the stop-frame rows")
    ap.add_argument("--out", type=Path, default=None, help="a folder for targets.json")
    ap.add_argument("--target", action="append", default=[], metavar="KEY=VALUE",
                    help="an override of the steering's constants (TargetConfig), e.g. "
                         "glance=true; repeatable")
    ap.add_argument("--sfe", action="append", default=[], metavar="KEY=VALUE",
                    help="an override of the frontier explorer's constants (SFEConfig), e.g. "
                         "stand_in_sight=false; repeatable")
    ap.add_argument("--vlm", default="local:qwen2.5-coder-1.5b",
                    help="the language model of the rooms next to the named one, where "
                         "--target near_rooms=true asks for them")
    args = ap.parse_args()
    from experiments import stop_audit

    args.reading = _reading(args)

    version = code_version()  # the code as the run starts
    rows = [] if args.no_explore else explore_rows(args)
    where = location_rows(args, {r["id"] for r in rows}) if rows and args.location else []
    explore = explore_targets(rows, where) if rows else None
    run = run_targets(args.run) if args.run else None
    walks = stop_audit.audit(args.run) if args.run and args.audit else []
    audit = stop_audit.summary(walks) if walks else None
    print(f"\ncode {version}; exploration: {args.questions} questions of houses "
          f"{args.seeds} ({args.per_house} per house) x {args.repeats} explorer seeds, stop off, "
          f"default = {DEFAULT}, yardstick = {YARDSTICK}; run: {args.run}\n")
    print(table(explore, run, audit, args))
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "targets.json").write_text(json.dumps(
            {"code_version": version,
             "args": {k: str(v) for k, v in vars(args).items()
                      if k not in ("out", "reading")},  # no machine path
             "explore": explore, "run": run, "audit": audit, "explore_rows": rows,
             "location_rows": where,
             "walks": walks}, indent=1))
        print(f"\n{args.out / 'targets.json'}")


if __name__ == "__main__":
    main()
