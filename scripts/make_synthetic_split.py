"""Build the fixed synthetic split (package data ``src/efficienteqa/datasets/synthetic_v1.jsonl``).

Opens every house of ``--seeds`` (about 5 s each), takes its generated questions with oracle step
counts, and selects ``--per-category`` questions of each category, spread over the houses
(``datasets.synthetic.select_split``). Deterministic: the same code gives the same file.

    .venv/bin/python scripts/make_synthetic_split.py            # seeds 100-129
    .venv/bin/python scripts/make_synthetic_split.py --check    # rebuild in memory, compare

A changed generator means a new split version (bump ``SPLIT_VERSION``), never a silent rewrite.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

from rich.progress import Progress

from efficienteqa.datasets import synthetic
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.questions import Question
from efficienteqa.scenes import synthetic_questions

OUT = Path(__file__).resolve().parents[1] / "src" / "efficienteqa" / "datasets" / synthetic.SPLIT_FILE


def scan(seeds: list[int]) -> tuple[list[Question], dict[int, dict[str, float]]]:
    """Every house's questions, and its size (the header records it: tests open the smallest)."""
    questions: list[Question] = []
    sizes: dict[int, dict[str, float]] = {}
    with Progress() as bar:
        task = bar.add_task("houses", total=len(seeds))
        for seed in seeds:
            with SyntheticEnv.from_seed(seed, synthetic.SPLIT_ASSETS) as env:
                questions += synthetic_questions(env)
                sizes[seed] = {"rooms": len(env.house.layout.rooms),
                               "objects": len(env.house.objects),
                               "floor_area_m2": round(env.floor_area_m2, 1)}
            bar.advance(task)
    return questions, sizes


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="100-129", help="house seeds, e.g. 100-129 (>= 100)")
    parser.add_argument("--per-category", type=int, default=17)
    parser.add_argument("--existence-no", type=int, default=4,
                        help="existence questions answered 'no' (no evidence, no oracle steps)")
    parser.add_argument("--max-per-house", type=int, default=5)
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--check", action="store_true", help="compare with --out, write nothing")
    args = parser.parse_args()

    seeds = synthetic.parse_seeds(args.seeds)
    if not all(s in synthetic.SPLIT_SEEDS for s in seeds):
        parser.error(f"split seeds must lie in {synthetic.SPLIT_SEEDS}")
    questions, sizes = scan(seeds)
    picks = synthetic.select_split(questions, args.per_category, args.existence_no,
                                   args.max_per_house)
    used = sorted({q.house_seed for q in picks})
    header = {"generator": {"version": synthetic.generator_version(),
                            "questions": "efficienteqa.scenes.synthetic_questions (2 per category)"},
              "seeds": used, "scanned_seeds": args.seeds,
              "house_sizes": {str(seed): sizes[seed] for seed in used},
              "selection": {"per_category": args.per_category, "existence_no": args.existence_no,
                            "max_per_house": args.max_per_house,
                            "rule": "categories in turn; each pick from the least-used house"}}
    target = args.out.with_suffix(".check") if args.check else args.out
    synthetic.write_split(picks, header, target)
    steps = [q.oracle_steps for q in picks if q.oracle_steps is not None]
    print(json.dumps(json.loads(target.read_text().splitlines()[0])["category_counts"]))
    print(f"{len(picks)} questions, {len({q.house_seed for q in picks})} houses, "
          f"oracle steps mean {statistics.mean(steps):.2f} over {len(steps)}")
    if args.check:
        same = target.read_text().splitlines()[1:] == args.out.read_text().splitlines()[1:]
        target.unlink()
        print("split unchanged" if same else "split differs: the generator changed")
        return 0 if same else 1
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
