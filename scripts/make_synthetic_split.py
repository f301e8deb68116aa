"""Build a frozen synthetic split (package data under ``src/efficienteqa/datasets/``) and its manifest.

Opens every house of ``--seeds`` (about 5 s each), takes its generated questions with oracle step
counts, and selects ``--per-category`` questions of each category, spread over the houses
(``datasets.synthetic.select_split``), then writes the split's checksummed manifest
(``datasets/manifests/SPLIT.json``, ``datasets.manifest``). Deterministic: the same code gives
the same files.

    .venv/bin/python scripts/make_synthetic_split.py                              # synthetic-v1
    .venv/bin/python scripts/make_synthetic_split.py --split synthetic-test-v1    # held out
    .venv/bin/python scripts/make_synthetic_split.py --check    # rebuild in memory, compare
    .venv/bin/python scripts/make_synthetic_split.py --manifest-only  # the manifest of the file

A changed generator means a new split version (``synthetic-v2``, ``synthetic-test-v2``: a new
file, a new manifest and its digest in ``datasets.splits``), never a rewrite of a frozen one.
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

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "efficienteqa" / "datasets"
# Each split's file, seeds (the range they must lie in) and selection.
SPLITS = {
    synthetic.SPLIT_DATASET: dict(file=synthetic.SPLIT_FILE, seeds="100-129",
                                  allowed=synthetic.SPLIT_SEEDS, per_category=17, existence_no=4),
    synthetic.TEST_DATASET: dict(file=synthetic.TEST_FILE, seeds="5000-5039",
                                 allowed=synthetic.TEST_SEEDS, per_category=20, existence_no=5),
}


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
    parser.add_argument("--split", choices=sorted(SPLITS), default=synthetic.SPLIT_DATASET)
    parser.add_argument("--seeds", help="house seeds, e.g. 100-129 (default: the split's)")
    parser.add_argument("--per-category", type=int, help="default: the split's (17; test 20)")
    parser.add_argument("--existence-no", type=int, help="existence questions answered 'no' "
                        "(no evidence, no oracle steps; default: the split's, 4; test 5)")
    parser.add_argument("--max-per-house", type=int, default=5)
    parser.add_argument("--out", type=Path, help="default: the split's package file")
    parser.add_argument("--check", action="store_true", help="compare with --out, write nothing")
    parser.add_argument("--manifest-only", action="store_true",
                        help="write the manifest of the split file as it stands (opens its houses)")
    args = parser.parse_args()
    split = SPLITS[args.split]
    args.seeds = args.seeds or split["seeds"]
    args.per_category = args.per_category or split["per_category"]
    args.existence_no = split["existence_no"] if args.existence_no is None else args.existence_no
    args.out = args.out or PACKAGE / split["file"]
    if args.manifest_only:
        return write_manifest(args.split, args.out)

    seeds = synthetic.parse_seeds(args.seeds)
    if not all(s in split["allowed"] for s in seeds):
        parser.error(f"{args.split} seeds must lie in {split['allowed']}")
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
    synthetic.write_split(picks, header, target, args.split)
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
    return write_manifest(args.split, target)


def write_manifest(split: str, path: Path) -> int:
    """The manifest of the split file ``path`` (its houses opened again for their digests)."""
    from efficienteqa.datasets import manifest
    from efficienteqa.datasets.base import EvalQuestion

    questions = [EvalQuestion.from_dict(json.loads(line))
                 for line in path.read_text().splitlines()[1:] if line.strip()]
    seeds = sorted({synthetic.house_of(q) for q in questions})
    with Progress() as bar:
        task = bar.add_task("manifest", total=len(seeds))
        body = manifest.build_manifest(split, path.name, questions,
                                       progress=lambda n: bar.update(task, completed=n))
    out = manifest.write_manifest(body, PACKAGE / manifest.MANIFEST_DIR)
    print(f"wrote {out}: sha256 {body['sha256']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
