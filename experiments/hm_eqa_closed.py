"""HM-EQA closed-set, Blind LLM (results/hm-eqa/blind-closed/): letter accuracy against the majority-choice
prior, overall and per question category (HM-EQA's ``label`` column).

Reads a run of

    efficienteqa eval --method blind --dataset hm-eqa --closed-set --judge none --out RUN_DIR

and prints n, the letter accuracy with its 95% bootstrap interval (``eval.stats.mean_interval``:
``scipy.stats.bootstrap``, BCa, fixed seed), the majority-choice prior (always answering the
most frequent correct letter of the same questions; ties to the earlier letter) and, per
category, the accuracy against that category's own majority prior. A failed episode counts as
wrong, as in ``eval.summary``. Also which letters the model chose against the correct ones, and
how often it chose a filler ("(Do not choose this option)"). Writes ``RUN_DIR/closed_set.json``.

    python -m experiments.hm_eqa_closed results/hm-eqa/blind-closed

The majority prior knows the answers of the whole set; it is the floor a letter-biased guesser
reaches, not a method.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from efficienteqa.datasets.hm_eqa import FILLER
from efficienteqa.eval.records import read_run
from efficienteqa.eval.stats import mean, mean_interval
from efficienteqa.eval.summary import match_value


def majority(letters: Sequence[str]) -> tuple[str, float]:
    """The most frequent letter (ties: the earlier letter) and its share (%) of ``letters``."""
    if not letters:
        return "", float("nan")
    counts = Counter(letters)
    best = min(counts, key=lambda x: (-counts[x], x))
    return best, 100.0 * counts[best] / len(letters)


def figures(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The closed-set figures of a run's rows (each with its ``choice`` grade)."""
    graded = [r for r in rows if isinstance(r.get("choice"), Mapping)
              or r.get("status") != "done"]
    reference = [str((r.get("choice") or {}).get("reference_letter") or "") for r in graded]
    missing = [r["id"] for r, x in zip(graded, reference) if not x]
    if missing:  # a failed row has no grade, so no reference letter to count in the prior
        sys.exit(f"error: {len(missing)} episode(s) without a letter grade (e.g. {missing[0]}); "
                 "re-run the eval in the same folder to retry failed episodes")
    values = [match_value(r, "choice") for r in graded]
    chosen = [str((r.get("extra") or {}).get("letter") or "-") for r in graded]
    prior_letter, prior = majority(reference)
    low, high = mean_interval(values)
    categories: dict[str, list[int]] = {}
    for i, r in enumerate(graded):
        categories.setdefault(str(r.get("category") or "(none)"), []).append(i)
    by_category = {}
    for cat, idx in sorted(categories.items()):
        cat_letter, cat_prior = majority([reference[i] for i in idx])
        by_category[cat] = {"n": len(idx), "accuracy": mean(values[i] for i in idx),
                            "majority_letter": cat_letter, "majority_prior": cat_prior,
                            "overall_majority_prior": 100.0 * sum(reference[i] == prior_letter
                                                                  for i in idx) / len(idx)}
    return {"n": len(graded), "n_failed": sum(r.get("status") != "done" for r in graded),
            "accuracy": mean(values), "accuracy_ci": [low, high], "confidence": 0.95,
            "majority_letter": prior_letter, "majority_prior": prior,
            "reference_letters": dict(sorted(Counter(reference).items())),
            "chosen_letters": dict(sorted(Counter(chosen).items())),
            "filler_chosen": sum(r.get("answer") == FILLER for r in graded),
            "filler_reference": sum(r.get("reference") == FILLER for r in graded),
            "by_category": by_category}


def _pct(value: float) -> str:
    return f"{value:5.1f}"


def report(f: Mapping[str, Any]) -> str:
    low, high = f["accuracy_ci"]
    lines = [f"n={f['n']} (failed {f['n_failed']}; the reference is a filler in {f['filler_reference']})",
             f"blind letter accuracy {f['accuracy']:.1f}% [{low:.1f}, {high:.1f}] (95% bootstrap)",
             f"majority-choice prior {f['majority_prior']:.1f}% (always {f['majority_letter']})",
             f"correct letters {f['reference_letters']}; chosen {f['chosen_letters']}; "
             f"filler chosen {f['filler_chosen']} times",
             f"{'category':<16}{'n':>5}{'accuracy':>10}{'majority':>10}  letter{'overall-majority':>18}"]
    for cat, c in f["by_category"].items():
        lines.append(f"{cat:<16}{c['n']:>5}{_pct(c['accuracy']):>10}{_pct(c['majority_prior']):>10}"
                     f"  {c['majority_letter']:>6}{_pct(c['overall_majority_prior']):>18}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="the run folder (efficienteqa eval --closed-set --out)")
    parser.add_argument("--out", type=Path, default=None,
                        help="the JSON file (default RUN/closed_set.json)")
    args = parser.parse_args(argv)
    manifest, episodes = read_run(args.run)
    if not manifest.get("closed_set"):
        sys.exit(f"error: {args.run} is not a closed-set run (run.json closed_set is not true)")
    f = figures(episodes.rows())
    print(report(f))
    record = {"run": args.run.name, "method": manifest.get("method"), "dataset": manifest.get("dataset"),
              "vlm": (manifest.get("stack") or {}).get("vlm"), "code_version": manifest.get("code_version"),
              "planned": manifest.get("questions"),
              "bootstrap": "scipy.stats.bootstrap BCa, 9999 resamples, seed 0 (eval.summary)", **f}
    out = args.out or args.run / "closed_set.json"
    out.write_text(json.dumps(record, indent=2) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
