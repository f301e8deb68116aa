"""Where a run loses its questions, stage by stage, from its recorded episodes.

Usage: .venv/bin/python -m experiments.stages results/main-heldout/default
       results/main-heldout/pixels [...]

For each run folder (synthetic questions, whose episodes record when the evidence was first in
view and whether it was among the frames the answer read): how many episodes saw the evidence
(exploration), how many answered from frames that show it (stop and retrieval), how many of
those the rule judge grades right (the answer from what the perception said), and how many of
the others were right anyway (guesses: a "no", a common colour). Accuracy by question category
follows. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path


def stages(folder: Path) -> dict[str, object]:
    rows = [json.loads(line) for line in (folder / "episodes.jsonl").read_text().splitlines()]
    done = [r for r in rows if r.get("status") == "done"]

    def right(r: dict) -> bool:
        return (r.get("rule") or {}).get("score") == 5

    seen = [r for r in done if r.get("evidence_first_seen_step") is not None]
    read = [r for r in done if r.get("evidence_in_top_k")]
    others = [r for r in done if not r.get("evidence_in_top_k")]
    by_category: Counter[str] = Counter()
    per_category: Counter[str] = Counter()
    for r in done:
        per_category[r["category"]] += 1
        by_category[r["category"]] += right(r)
    return {"run": folder.name, "n": len(done), "seen": len(seen), "read": len(read),
            "right_read": sum(map(right, read)), "others": len(others),
            "right_others": sum(map(right, others)), "right": sum(map(right, done)),
            "categories": {c: f"{by_category[c]}/{n}" for c, n in sorted(per_category.items())}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", type=Path, nargs="+")
    args = parser.parse_args()
    results = [stages(f) for f in args.folders]
    print("| run | episodes | evidence seen | answered from frames showing it | right of those "
          "| right without it | right |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for s in results:
        print(f"| {s['run']} | {s['n']} | {s['seen']} | {s['read']} | {s['right_read']}/{s['read']}"
              f" | {s['right_others']}/{s['others']} | {s['right']} |")
    categories = sorted({c for s in results for c in s["categories"]})  # type: ignore[attr-defined]
    print("\n| run | " + " | ".join(categories) + " |")
    print("|---|" + "---:|" * len(categories))
    for s in results:
        cells = [s["categories"].get(c, "-") for c in categories]  # type: ignore[attr-defined]
        print(f"| {s['run']} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
