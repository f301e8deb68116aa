"""The measures of DESIGN 9 on an evaluation run: is the evidence seen, and does the robot stop on it?

Reads ``episodes.jsonl`` and, where the run folder still has them, each episode's
``episodes/*/episode.json`` (for the steps that showed the evidence); writes ``seek.json`` beside
them, so the figures stay readable once the heavy episode folders are gone.

    python -m experiments.seek_targets results/main-heldout/default [results/main-heldout/default-v1]

Measures (questions with evidence unless said otherwise; the oracle's step counts are the
synthetic split's): first sight / oracle (never seen counted as budget + 1), evidence never seen
before the stop, relevancy stops whose tested frame shows the evidence (the stop frame, or
under look-back the earlier frame it stopped for; runs recorded before ``tested_step`` existed
count the stop frame), first sight to stop (relevancy
stops that saw it), steps / oracle, and for "no" questions (nothing to see) their relevancy
stops and mean steps. The evidence is "seen" when every evidence object has at least 250 px.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np


def measures(run: Path) -> dict[str, Any]:
    rows = [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()
            if line.strip()]
    rows = [r for r in rows if r.get("status") == "done"]
    seen_steps: dict[str, list[int]] = {}
    tested: dict[str, int] = {}  # the frame the stop tested (look-back: maybe an earlier one)
    for r in rows:
        path = run / "episodes" / r["id"].replace("/", "__") / "episode.json"
        if path.is_file():
            ep = json.loads(path.read_text())
            seen_steps[r["id"]] = ep.get("evidence_seen_steps") or []
            tested[r["id"]] = ep["per_step"][-1].get("tested_step") or r["steps"]
    has = [r for r in rows if r.get("oracle_steps")]
    no = [r for r in rows if r["category"] == "existence" and not r.get("oracle_steps")]
    oracle = float(np.mean([r["oracle_steps"] for r in has]))
    first = [r["evidence_first_seen_step"] if r["evidence_first_seen_step"] is not None
             else r["budget"] + 1 for r in has]
    stops = [r for r in has if r["stop_reason"] == "relevancy"]
    known = [r for r in stops if r["id"] in seen_steps]
    waits = [r["steps"] - r["evidence_first_seen_step"] for r in stops
             if r["evidence_first_seen_step"] is not None
             and r["evidence_first_seen_step"] <= r["steps"]]
    right = [(r.get("rule") or {}).get("score") == 5 for r in rows]
    return {
        "run": str(run), "episodes": len(rows), "with_evidence": len(has),
        "accuracy_rule": float(np.mean(right)) if rows else None,
        "first_seen_x_oracle": float(np.mean(first)) / oracle,
        "never_seen_before_stop": sum(r["evidence_first_seen_step"] is None
                                      or r["evidence_first_seen_step"] > r["steps"] for r in has),
        "relevancy_stops": len(stops),
        "stops_showing_evidence": (sum(tested[r["id"]] in seen_steps[r["id"]] for r in known)
                                   if known else None),
        "stops_with_frames_known": len(known),
        "sight_to_stop_mean": float(np.mean(waits)) if waits else None,
        "sight_to_stop_median": float(np.median(waits)) if waits else None,
        "steps_x_oracle": float(np.mean([r["steps"] for r in has])) / oracle,
        "steps_mean": float(np.mean([r["steps"] for r in rows])),
        "stop_reasons": {k: sum(r["stop_reason"] == k for r in rows)
                         for k in ("relevancy", "budget", "explored", "searched")},
        "no_questions": len(no),
        "no_relevancy_stops": sum(r["stop_reason"] == "relevancy" for r in no),
        "no_steps_mean": float(np.mean([r["steps"] for r in no])) if no else None,
        "refused_moves_per_step": (sum(r.get("refused_moves") or 0 for r in rows)
                                   / max(sum(r["steps"] for r in rows), 1)),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", type=Path)
    args = ap.parse_args()
    for run in args.runs:
        m = measures(run)
        if m["stops_with_frames_known"]:  # written only where the episode folders were read
            (run / "seek.json").write_text(json.dumps(m, indent=1) + "\n")
        print(json.dumps(m))


if __name__ == "__main__":
    main()
