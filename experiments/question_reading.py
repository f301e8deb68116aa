"""The question's target as the rules and as the model read it (DESIGN 9, the user's words).

    python -m experiments.question_reading --hm-eqa ../shared/datasets/hm-eqa/questions.csv \
        [--model-sample 60 --seed 1] [--training 0-20 --training-sample 40]
        [--out out/reading.jsonl]

- rules: the share of HM-EQA's questions with a non-empty target (an object or a support), all
  of them; the hand check of 60 of them (seeded sample ``random.Random(0).sample(range(500),
  60)``; verdicts by question row in experiments/question_check_hm_eqa.csv, no question text;
  ``model_verdict`` for the rows the model read, judged the same way: object, support, rooms
  and a kind that does not change what the robot must see);
- model (``--model-sample``): the same share over the 60 hand-checked rows and then rows drawn
  with ``--seed`` up to the sample's size, how often its fields fell back to the rules', how
  often it gave likely rooms where none is named, and where it agrees with the rules;
- training (``--training``): the generator's distinct questions of those houses (synthetic
  seeds; ``--training-sample`` of them drawn with ``--seed``), where
  the rules' target is the generator's own, so agreement with them is the model's accuracy.

The model is the default stack's (``Stack().vlm``, the local Qwen2.5-Coder-1.5B), through its
response cache. ``--out`` writes one line per question read by the model (row or question id,
both targets): keep it outside the repository, HM-EQA's words are not ours to commit.
"""

from __future__ import annotations

import argparse
import csv
import json
import random
import time
from collections import Counter
from pathlib import Path
from typing import Any

from efficienteqa.question import Target, parse_question
from efficienteqa.reading.reader import ModelReader

CHECK = Path(__file__).with_name("question_check_hm_eqa.csv")


def _fields(t: Target) -> tuple[Any, ...]:
    return (t.kind, t.object, t.support)


def _read(reader: ModelReader, items: list[tuple[str, str]], out: Any) -> dict[str, Any]:
    counts: Counter[str] = Counter()
    for key, question in items:
        rules = parse_question(question)
        said = len(reader.problems)
        t0 = time.perf_counter()
        model = reader.read(question)
        counts["questions"] += 1
        counts["non_empty"] += bool(model.things)
        counts["fallbacks"] += len(reader.problems) > said
        counts["same_target"] += _fields(model) == _fields(rules)
        counts["same_things"] += (model.object, model.support) == (rules.object, rules.support)
        counts["no_room_named"] += not rules.rooms
        counts["likely_rooms"] += bool(model.likely_rooms)
        if out is not None:
            out.write(json.dumps({"key": key, "rules": rules.as_dict(), "model": model.as_dict(),
                                  "s": round(time.perf_counter() - t0, 1)}) + "\n")
            out.flush()
    return dict(counts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hm-eqa", type=Path, required=True)
    ap.add_argument("--model-sample", type=int, default=0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--training", default=None, help="synthetic house seeds, e.g. 0-20")
    ap.add_argument("--training-sample", type=int, default=0, help="distinct questions drawn")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    with args.hm_eqa.open(newline="") as f:
        rows = list(csv.DictReader(f))
    targets = [parse_question(r["question"]) for r in rows]
    print(f"rules: {sum(bool(t.things) for t in targets)}/{len(rows)} non-empty targets; "
          f"kinds {dict(Counter(t.kind for t in targets))}")
    with CHECK.open(newline="") as f:
        verdicts = list(csv.DictReader(f))
    print(f"rules, hand check: {sum(v['verdict'] == 'right' for v in verdicts)}/{len(verdicts)} right")
    judged = [v for v in verdicts if v.get("model_verdict")]
    print(f"model, hand check of the rows it read: "
          f"{sum(v['model_verdict'] == 'right' for v in judged)}/{len(judged)} right (rules on "
          f"those rows: {sum(v['verdict'] == 'right' for v in judged)}/{len(judged)})")
    if not args.model_sample and not args.training:
        return
    from efficienteqa.models.backends import build_chat_model
    from efficienteqa.stack import Stack, parse_vlm

    reader = ModelReader(build_chat_model(parse_vlm(Stack().vlm, images=False)))
    out = args.out.open("a") if args.out else None
    if args.model_sample:
        checked = [int(v["row"]) for v in verdicts]
        rest = [i for i in range(len(rows)) if i not in checked]
        more = random.Random(args.seed).sample(rest, max(0, args.model_sample - len(checked)))
        sample = (checked + more)[:args.model_sample]
        print(f"model, HM-EQA rows (the {len(checked)} hand-checked, then seed {args.seed}):",
              _read(reader, [(str(i), rows[i]["question"]) for i in sample], out))
    if args.training:
        from efficienteqa.datasets.synthetic import load_seeds, parse_seeds

        unique = {q.question: q.id for q in load_seeds(parse_seeds(args.training))}
        items = [(k, q) for q, k in unique.items()]
        if args.training_sample:
            items = random.Random(args.seed).sample(items, min(args.training_sample, len(items)))
        print(f"model, training houses {args.training} ({len(items)} of {len(unique)} distinct "
              f"questions, seed {args.seed}):", _read(reader, items, out))

if __name__ == "__main__":
    main()
