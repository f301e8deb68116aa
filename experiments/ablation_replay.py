"""The paper's Z_th and K ablations (Fig. 5/6), replayed from one run explored to the budget.

DESIGN 3.6. Exploration does not depend on the stop rule or on K, so one run of

    efficienteqa eval --no-early-stop --out RUN_DIR [--method ... --dataset ...]

records every frame's relevancy (``episode.json``'s ``per_step``), and this script replays:

- the stop of each ``--z-th`` (and ``--rule``, default the run's rule) with no model: the stop
  module's own ``RelevancyStopper`` over the recorded Sims (``eval.replay.replay_stop``);
- the answer for each ``--k``, from the episode at its budget and at each replayed stop: the
  top-K frames by ``answer.rag.TopK`` as the agent keeps them, re-observed at their recorded
  poses in the synthetic simulator and described by the stack's perception
  (``eval.replay.reobserve``), then the stack's answerer (``Agent.answerer``, as built by
  ``stack.build_agent``). Only this answer call reaches the model; a setting whose retrieved
  frames equal another's of the same episode reuses its answer.

Every answer is graded by the rule judge (``eval.synthetic_judge``; an episode without a rule grade
or whose answer failed counts as wrong, as in ``eval.summary``). Before answering, each
episode's re-observed frames are checked against its stored answer prompt
(``eval.replay.answer_prompt_matches``); a mismatch is reported.

Files, next to the run (``--out``, default ``RUN_DIR/ablation_replay.json``):

- ``ablation_replay.jsonl``: one line per (episode, setting), appended as each is done; a
  re-run skips the lines already there and retries failed ones (resumable);
- ``ablation_replay.json``: the settings, the tables and the prompt check.

    python -m experiments.ablation_replay RUN_DIR --z-th 1,2,3,4 --k 1,3,5,10

Tables: Z_th -> accuracy, mean steps, share stopped by relevancy (at ``--stop-k``, default the
run's K); K -> accuracy at the budget and at each Z_th's stop. The paper's numbers (HM-EQA,
GPT-4o, its own set-up; DESIGN 3.6) are printed beside them for the shape only.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from efficienteqa.agent import AgentConfig
from efficienteqa.config.knobs import build, with_leaves
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.eval.records import append_episode, nest_config, read_episodes, read_run
from efficienteqa.eval.replay import (
    Frame,
    answer_prompt_matches,
    recorded_frames,
    reobserve,
    replay_episode_stop,
    retrieve,
    stop_config_for,
)
from efficienteqa.eval.runner import episode_folder
from efficienteqa.eval.synthetic_judge import RULE_CATEGORIES, rule_judgement
from efficienteqa.records import code_version, plain, write_json
from efficienteqa.scenes import open_scene
from efficienteqa.stack import Stack, build_agent, parse_vlm
from efficienteqa.stop.rules import StopConfig

# The paper's Fig. 5/6 (HM-EQA, 100 questions, GPT-4o; DESIGN 3.6): LLM-Match on its own set-up.
PAPER_Z = {1.0: (28.94, 47.75), 2.0: (28.70, 53.50), 3.0: (30.16, 54.25)}  # steps, LLM-Match
PAPER_K = {10: 53.50, 5: 54.25, 3: 52.00, 1: 51.25}
BUDGET = "budget"  # the setting without early stop: the episode as recorded


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split(",") if v.strip()]


def _ints(text: str) -> list[int]:
    return [int(v) for v in text.split(",") if v.strip()]


def acting_threshold(per_step: Sequence[dict[str, Any]]) -> str:
    """Which threshold the Z_th rows vary in an episode: "z_gated" where its gate judged every
    frame (verdicts recorded on the steps: the default's rules gate, where Z_th decides
    nothing), else "z_th"."""
    gated = any(f.eligible is not None for f in recorded_frames(per_step))
    return "z_gated" if gated else "z_th"


def stop_name(rule: str | None, z_th: float | None) -> str:
    return BUDGET if rule is None else f"{rule}@z={z_th:g}"


def setting_id(episode: str, stop: str, k: int) -> str:
    return f"{episode}|{stop}|k={k}"


def _graded(row: dict[str, Any], answer: str | None) -> dict[str, Any] | None:
    if not row.get("accepted") or row.get("category") not in RULE_CATEGORIES:
        return None
    return rule_judgement(row["question"], row["category"], row["accepted"], answer).to_dict()


class Answerer:
    """The stack's answer call, built per scene (the perception reads the scene's labels) over
    one chat model for the whole replay."""

    def __init__(self, stack: Stack, vlm: str | None) -> None:
        from efficienteqa.models.backends import build_chat_model

        self.stack = replace(stack, vlm=vlm) if vlm else stack
        images = self.stack.perception != "semantic"
        self.model = build_chat_model(parse_vlm(self.stack.vlm, images=images,
                                                cache=self.stack.cache,
                                                temperature=self.stack.temperature))

    def build(self, env: Any, config: AgentConfig, backend: str) -> Any:
        return build_agent(env, self.stack, config, backend, model=self.model)


def _config(record: dict[str, Any]) -> AgentConfig:
    config = build(AgentConfig, nest_config(record["config"]))
    # The RAG answer from the retrieved frames, whatever the recorded method answered with.
    return with_leaves(config, answer_at="retrieval")


def replay_episode(row: dict[str, Any], record: dict[str, Any], manifest: dict[str, Any],
                   stops: Sequence[tuple[str | None, float | None]], ks: Sequence[int],
                   done: set[str], answerer: Answerer | None, out_jsonl: Path) -> int:
    """Every (stop, k) setting of one episode not in ``done``: its line appended to
    ``out_jsonl``. Returns the answer calls made."""
    todo = [(rule, z, k) for rule, z in stops for k in ks
            if setting_id(row["id"], stop_name(rule, z), k) not in done]
    if not todo:
        return 0
    config = _config(record)
    gated = acting_threshold(record["per_step"]) == "z_gated"
    stopped = {(rule, z): replay_episode_stop(
        record["per_step"], record["stop_reason"],
        stop_config_for(record["config"]["stop"], z_th=z, rule=rule, gated=gated))
        if rule is not None
        else replay_episode_stop(record["per_step"], record["stop_reason"],
                                 StopConfig(enabled=False))
        for rule, z in stops}
    frames: list[Frame[Any]] = []
    agent = None
    prompt_match: bool | None = None  # re-observed frames = the stored answer prompt's
    if answerer is not None:
        scene = open_scene(row["scene"], manifest.get("assets", "sh3d"),
                           env=manifest.get("env", "synthetic"), oracle=False)
        try:
            if not isinstance(scene.env, SyntheticEnv):
                raise SystemExit(f"{row['scene']}: frames are re-observed in the synthetic "
                                 "simulator only (use --no-answer for the stops)")
            agent = answerer.build(scene.env, config, scene.backend).agent
            frames = reobserve(scene.env.observe, agent.perception.frame,
                               recorded_frames(record["per_step"]))
        finally:
            scene.env.close()
        prompt = next((e["prompt"] for e in record["model"]["exchanges"]
                       if e["phase"] == "answer"), None)
        if agent.perception.modality == "text" and prompt is not None and record["retrieved"]:
            prompt_match = answer_prompt_matches(frames, record["retrieved"], prompt,
                                                 record["question"])
            if not prompt_match:
                print(f"  warning: {row['id']}: re-observed frames differ from the stored "
                      "answer prompt", file=sys.stderr)
    else:
        frames = [Frame(f.step, f.sim, f.pose, None) for f in recorded_frames(record["per_step"])]
    answers: dict[tuple[int, ...], dict[str, Any]] = {}  # retrieved steps -> answer
    calls = 0
    for rule, z, k in todo:
        s = stopped[(rule, z)]
        best = retrieve(frames, k, upto=s.step, distinct_views=config.answer.distinct_views)
        key = tuple(r.step for r in best)
        line: dict[str, Any] = {
            "id": setting_id(row["id"], stop_name(rule, z), k), "episode": row["id"],
            "stop": stop_name(rule, z), "rule": rule, "z_th": z, "k": k,
            "stop_step": s.step, "steps": s.steps, "stop_reason": s.reason,
            "budget": record["budget"],
            # Without the frames' descriptions (--no-answer) views differ by pose only.
            "retrieved": [[r.step, r.sim] for r in best] if agent is not None else None,
            "prompt_match": prompt_match}
        if agent is not None:
            if key not in answers:
                t0 = time.perf_counter()
                try:
                    result = agent.answerer.answer(record["question"], [r.item for r in best])
                    answers[key] = {"status": "done", "answer": result.answer,
                                    "confidence": result.confidence,
                                    "answer_s": round(time.perf_counter() - t0, 3)}
                except Exception as exc:  # noqa: BLE001 - one failed call must not end the replay
                    answers[key] = {"status": "failed", "answer": None,
                                    "error": f"{type(exc).__name__}: {exc}"[:300]}
                calls += 1
            line.update(answers[key])
            line["judge"] = _graded(row, line["answer"])
        else:
            line["status"] = "done"
        append_episode(out_jsonl, plain(line))
    return calls


def _mean(values: Sequence[float]) -> float:
    return sum(values) / len(values) if values else math.nan


def _right(line: dict[str, Any]) -> float:
    judge = line.get("judge")
    return 100.0 if line.get("status") == "done" and judge and judge.get("score") == 5 else 0.0


def tables(lines: Sequence[dict[str, Any]], episodes: Sequence[str],
           stops: Sequence[tuple[str | None, float | None]], ks: Sequence[int], stop_k: int,
           answered: bool) -> dict[str, Any]:
    """The Z_th table (at ``stop_k``) and the K table (at the budget and each stop)."""
    by = {(ln["episode"], ln["stop"], ln["k"]): ln for ln in lines}

    def cell(stop: str, k: int) -> dict[str, Any]:
        rows = [by[(e, stop, k)] for e in episodes if (e, stop, k) in by]
        return {"n": len(rows),
                "accuracy": _mean([_right(r) for r in rows]) if answered else None,
                "mean_steps": _mean([r["steps"] for r in rows]),
                "steps_per_budget": _mean([r["steps"] / r["budget"] for r in rows if r["budget"]]),
                "relevancy_stop_share": _mean([100.0 * (r["stop_reason"] == "relevancy")
                                               for r in rows])}

    z_rows = [{"stop": stop_name(rule, z), "rule": rule, "z_th": z, "k": stop_k,
               **cell(stop_name(rule, z), stop_k)} for rule, z in stops]
    k_rows = [{"k": k, **{stop_name(rule, z): cell(stop_name(rule, z), k)["accuracy"]
                          for rule, z in stops}} for k in ks]
    return {"z_th": z_rows, "k": k_rows}


def _fmt(v: float | None, digits: int = 1) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}"


def print_tables(result: dict[str, Any], stops: Sequence[tuple[str | None, float | None]]) -> None:
    print(f"\nZ_th (stop replayed; answer at K={result['z_th'][0]['k']}; the threshold varied: "
          f"{result.get('threshold', 'z_th')})")
    print(f"{'stop':<40} {'n':>3} {'acc %':>6} {'steps':>6} {'st/bud':>6} {'relev %':>7}"
          f"   paper steps / LLM-Match")
    for r in result["z_th"]:
        paper = PAPER_Z.get(r["z_th"]) if r["rule"] is not None else None
        ref = f"{paper[0]:.2f} / {paper[1]:.2f}" if paper else ""
        print(f"{r['stop']:<40} {r['n']:>3} {_fmt(r['accuracy']):>6} {_fmt(r['mean_steps']):>6} "
              f"{_fmt(r['steps_per_budget'], 2):>6} {_fmt(r['relevancy_stop_share']):>7}   {ref}")
    names = [stop_name(rule, z) for rule, z in stops]
    one_rule = len({rule for rule, _ in stops if rule is not None}) == 1
    labels = [n if rule is None or not one_rule else f"z={z:g}" for n, (rule, z) in zip(names, stops)]
    width = max(8, *(len(x) for x in labels))
    print("\nK (accuracy %, rule judge; at the budget and at each replayed stop"
          + (f" of {stops[-1][0]}" if one_rule else "") + ")")
    print(f"{'K':>3} " + " ".join(f"{x:>{width}}" for x in labels) + "   paper (K, LLM-Match)")
    for r in result["k"]:
        paper_k = PAPER_K.get(r["k"])
        print(f"{r['k']:>3} " + " ".join(f"{_fmt(r[n]):>{width}}" for n in names)
              + (f"   {paper_k:.2f}" if paper_k else ""))


def markdown_tables(result: dict[str, Any]) -> str:
    """The Z_th and K tables of an ``ablation_replay.json`` as docs/RESULTS.md holds them (a test
    checks the two agree): ``python -m experiments.ablation_replay --markdown FILE``."""
    threshold = result.get("threshold", "z_th")
    symbol = {"z_th": "Z_th", "z_gated": "z_gated"}.get(threshold, threshold)
    z_rows = [r for r in result["z_th"]]
    lines = [f"| stop (answer at K = {z_rows[0]['k']}) | accuracy % | steps | steps / budget | "
             "relevancy stops % | paper: steps / LLM-Match |", "|---|---|---|---|---|---|"]
    for r in z_rows:
        paper = PAPER_Z.get(r["z_th"]) if r["rule"] is not None else None
        name = "none (the budget)" if r["rule"] is None else f"{symbol} = {r['z_th']:g}"
        lines.append(f"| {name} | {_fmt(r['accuracy'])} | {_fmt(r['mean_steps'])} | "
                     f"{_fmt(r['steps_per_budget'], 2)} | {_fmt(r['relevancy_stop_share'], 0)} | "
                     + (f"{paper[0]:.2f} / {paper[1]:.2f} |" if paper else "|"))
    stops = [r["stop"] for r in z_rows]
    heads = ["at the budget" if r["rule"] is None else f"{symbol} = {r['z_th']:g}" for r in z_rows]
    lines += ["", "| K | " + " | ".join(heads) + " | paper (LLM-Match) |",
              "|---" * (len(heads) + 2) + "|"]
    for r in result["k"]:
        paper_k = PAPER_K.get(r["k"])
        lines.append(f"| {r['k']} | " + " | ".join(_fmt(r[s]) for s in stops)
                     + (f" | {paper_k:.2f} |" if paper_k else " | |"))
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> None:
    if argv is None:
        argv = sys.argv[1:]
    if argv[:1] == ["--markdown"]:
        sys.stdout.write(markdown_tables(json.loads(Path(argv[1]).read_text())))
        return
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", type=Path, help="a run of `efficienteqa eval --no-early-stop`")
    ap.add_argument("--z-th", type=_floats, default=[1.0, 2.0, 3.0, 4.0])
    ap.add_argument("--k", type=_ints, default=[1, 3, 5, 10])
    ap.add_argument("--rule", default=None,
                    help="stop rules, comma-separated (default: the run's stop rule)")
    ap.add_argument("--stop-k", type=int, default=None,
                    help="K of the Z_th table (default: the run's top_k)")
    ap.add_argument("--vlm", default=None, help="answer with this VLM (default: the run's)")
    ap.add_argument("--limit", type=int, default=None, help="only the first N episodes")
    ap.add_argument("--no-answer", action="store_true",
                    help="replay the stops only: no simulator, no model")
    ap.add_argument("--out", type=Path, default=None,
                    help="summary JSON (default RUN_DIR/ablation_replay.json; lines beside it)")
    args = ap.parse_args(argv)

    manifest, run_episodes = read_run(args.run_dir)
    out_json = args.out or args.run_dir / "ablation_replay.json"
    out_jsonl = out_json.with_suffix(".jsonl")
    rows = [r for r in run_episodes.rows() if r.get("status") == "done"][:args.limit]
    records: dict[str, dict[str, Any]] = {}
    skipped: dict[str, str] = {}
    for row in rows:
        path = episode_folder(args.run_dir, row["id"]) / "episode.json"
        if not path.exists():
            skipped[row["id"]] = "no episode.json (blind?)"
            continue
        record = json.loads(path.read_text())
        if record["stop_reason"] == "relevancy":
            skipped[row["id"]] = "stopped early: run with --no-early-stop"
            continue
        records[row["id"]] = record
    if not records:
        sys.exit(f"nothing to replay in {args.run_dir}: {skipped or 'no finished episodes'}")
    first = next(iter(records.values()))
    first_config = nest_config(first["config"])
    rules = args.rule.split(",") if args.rule else [first_config["stop"]["rule"]]
    stop_k = args.stop_k or int(first_config["answer"]["top_k"])
    ks = sorted(set(args.k) | {stop_k})
    stops: list[tuple[str | None, float | None]] = [(None, None)] + [
        (rule, z) for rule in rules for z in args.z_th]
    stack = Stack(**manifest["stack"])
    # What must be equal for a resumed replay to continue an earlier one (the run is the folder).
    identity = {"vlm": args.vlm or stack.vlm, "answered": not args.no_answer}
    if out_json.exists() and out_jsonl.exists():
        earlier = json.loads(out_json.read_text()).get("identity")
        if earlier is not None and earlier != identity:
            sys.exit(f"{out_json} holds a replay with {earlier}, not {identity}: use --out")

    done = read_episodes(out_jsonl).done
    answerer = None if args.no_answer else Answerer(stack, args.vlm)
    t0, calls = time.perf_counter(), 0
    for i, row in enumerate(r for r in rows if r["id"] in records):
        n = replay_episode(row, records[row["id"]], manifest, stops, ks, done, answerer,
                           out_jsonl)
        calls += n
        print(f"[{i + 1}/{len(records)}] {row['id']}: {n} answer calls", file=sys.stderr)
    lines = [ln for ln in read_episodes(out_jsonl).rows() if ln["episode"] in records]
    result = tables(lines, list(records), stops, ks, stop_k, not args.no_answer)
    acting = {acting_threshold(r["per_step"]) for r in records.values()}
    threshold = "/".join(sorted(acting)) or "z_th"
    result["threshold"] = threshold
    checked = {ln["episode"]: ln["prompt_match"] for ln in lines
               if ln.get("prompt_match") is not None}
    check = {"checked": len(checked), "matched": sum(checked.values()),
             "mismatched": sorted(e for e, ok in checked.items() if not ok)}
    summary = {"identity": identity, "run": args.run_dir.name, "method": manifest.get("method"),
               "dataset": manifest.get("dataset"), "stack": asdict(answerer.stack) if answerer
               else manifest["stack"], "episodes": len(records), "skipped": skipped,
               "rules": rules, "z_th": args.z_th, "k": ks, "stop_k": stop_k,
               "threshold": threshold,
               "failed": sum(ln.get("status") == "failed" for ln in lines),
               "answer_calls_this_run": calls,  # response-cache hits included
               "wall_s": round(time.perf_counter() - t0, 1),
               "prompt_check": check, "code_version": code_version(), **result,
               "paper": {"z_th": {str(z): {"steps": s, "llm_match": m}
                                  for z, (s, m) in PAPER_Z.items()},
                         "k": {str(k): v for k, v in PAPER_K.items()},
                         "note": "HM-EQA, GPT-4o, LLM-Match: the paper's own set-up"}}
    write_json(out_json, plain(summary))
    print_tables(result, stops)
    print(f"\n{len(records)} episodes ({len(skipped)} skipped), {calls} answer calls now; "
          f"prompt check {check['matched']}/{check['checked']} matched; written {out_json}")


if __name__ == "__main__":
    main()
