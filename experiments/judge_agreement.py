"""How an LLM-Match judge agrees with hand grades (DESIGN 8): mean absolute error, Spearman
correlation and the mean grade it gives to answers graded 1, per judge and mode.

The default data is the shared hand-graded set (HM-EQA questions; 120 constructed responses and
40 real answers of a blind small model, graded 1-5 by hand; see its README.md). Any file in the
same format works (one JSON object per line with ``question``, ``reference``, ``response``,
``grade`` and optionally ``origin``, ``kind``, ``id``). The figures are printed for all items,
then separately for the constructed and for the model answers (``origin``), with per-kind means;
each judge ends with one line

    judge=<spec>:<mode> n=<n> mae=<x> spearman=<x> wrong_mean=<x>

    .venv/bin/python -m experiments.judge_agreement                      # the default local judge
    .venv/bin/python -m experiments.judge_agreement --judge-mode grade --judge-mode yes-prob
    .venv/bin/python -m experiments.judge_agreement --judge openai:gpt-4o --judge-mode grade

``--judge`` and ``--judge-mode`` take what ``efficienteqa eval`` takes (both may be repeated:
every judge is run in every mode). Grades come from the judge's sqlite cache when the same
judge, prompt and item were graded before; ``--fresh`` uses a cache of its own for this run.
``--out FILE`` also writes the figures as JSON (a published result, e.g. results/judge/):

    python -m experiments.judge_agreement --judge-mode yes-prob --out results/judge/local-yes-prob.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import tempfile
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from scipy.stats import spearmanr

from efficienteqa.eval.judge_prompts import DEFAULT_JUDGE, JUDGE_MODES, judge_mode

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DATA = REPO.parent / "shared" / "datasets" / "judge-agreement" / "dev.jsonl"
WRONG = 1  # the hand grade of a wrong answer


@dataclass(frozen=True)
class Item:
    id: str
    question: str
    reference: str
    response: str
    grade: int
    kind: str
    origin: str


def load_items(path: Path) -> list[Item]:
    if not path.is_file():
        sys.exit(f"error: no judge-agreement data at {path} (the shared set lives in "
                 "../shared/datasets/judge-agreement/ beside the repository); pass --data FILE")
    items = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
            items.append(Item(str(row.get("id", n)), row["question"], row["reference"],
                              row["response"], int(row["grade"]), str(row.get("kind", "-")),
                              str(row.get("origin", "-"))))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as error:
            sys.exit(f"error: {path}:{n} is not a graded item ({error})")
    if not items:
        sys.exit(f"error: {path} holds no items")
    return items


def resolve_mode(mode: str, judge: str) -> str:
    """``auto`` as ``efficienteqa eval`` reads it: yes-prob for local models, grade otherwise."""
    return judge_mode(mode, judge)


@dataclass(frozen=True)
class Scores:
    n: int
    mae: float
    spearman: float
    wrong_mean: float
    n_wrong: int
    match: float  # LLM-Match of the judge's grades, 0-100
    hand_match: float  # LLM-Match of the hand grades


def _llm_match(grades: Sequence[int]) -> float:
    return 100.0 * statistics.fmean((g - 1) / 4 for g in grades)


def scores(hand: Sequence[int], judged: Sequence[int]) -> Scores:
    wrong = [j for h, j in zip(hand, judged, strict=True) if h == WRONG]
    rho = spearmanr(hand, judged).statistic if len(set(hand)) > 1 and len(set(judged)) > 1 else math.nan
    return Scores(len(hand), statistics.fmean(abs(h - j) for h, j in zip(hand, judged, strict=True)),
                  float(rho), statistics.fmean(wrong) if wrong else math.nan, len(wrong),
                  _llm_match(judged), _llm_match(hand))


def grade_all(items: Sequence[Item], judge_spec: str, mode: str, cache: Path | None
              ) -> tuple[list[int], list[dict[str, Any]]]:
    """The judge's grade of every item (a missing grade counts as 1), and each judgement."""
    from rich.progress import Progress

    from efficienteqa.eval.judge import LLMMatchJudge
    from efficienteqa.models.backends import build_chat_model
    from efficienteqa.stack import parse_vlm

    judge = LLMMatchJudge(build_chat_model(parse_vlm(judge_spec, images=False)),
                          cache_path=cache, mode=mode)
    grades, records = [], []
    with Progress(transient=True) as bar:
        task = bar.add_task(f"{judge_spec}:{mode}", total=len(items))
        for item in items:
            verdict = judge.judge(item.question, item.reference, item.response)
            grades.append(verdict.score if verdict.score is not None else WRONG)
            records.append({"id": item.id, **verdict.to_dict()})
            bar.advance(task)
    return grades, records


def _f(value: float, digits: int = 2) -> str:
    return "nan" if math.isnan(value) else f"{value:.{digits}f}"


def _groups(items: Sequence[Item]) -> list[tuple[str, list[int]]]:
    """All items, then the items of each ``origin``."""
    groups = [("all", list(range(len(items))))]
    for origin in sorted({i.origin for i in items}):
        groups.append((origin, [k for k, i in enumerate(items) if i.origin == origin]))
    return groups


def _by_kind(items: Sequence[Item], grades: Sequence[int]) -> dict[str, list[tuple[int, int]]]:
    by_kind: dict[str, list[tuple[int, int]]] = defaultdict(list)
    for item, g in zip(items, grades, strict=True):
        by_kind[item.kind].append((item.grade, g))
    return dict(sorted(by_kind.items()))


def _json_float(value: float, digits: int = 4) -> float | None:
    return None if math.isnan(value) else round(value, digits)


def record(items: Sequence[Item], grades: Sequence[int], judge: str, mode: str) -> dict[str, Any]:
    """The figures of one judge and mode as JSON: all items, per origin, per kind."""
    def figures(s: Scores) -> dict[str, Any]:
        return {"n": s.n, "mae": _json_float(s.mae), "spearman": _json_float(s.spearman),
                "wrong_mean": _json_float(s.wrong_mean), "n_wrong": s.n_wrong,
                "llm_match": _json_float(s.match, 2), "hand_llm_match": _json_float(s.hand_match, 2)}

    from efficienteqa.eval.judge_prompts import prompt_version

    groups = {label: figures(scores([items[k].grade for k in idx], [grades[k] for k in idx]))
              for label, idx in _groups(items)}
    return {"judge": judge, "mode": mode, "prompt_version": prompt_version(mode),
            **groups.pop("all"), "by_origin": groups,
            "by_kind": {kind: {"n": len(pairs), "hand_mean": round(statistics.fmean(h for h, _ in pairs), 4),
                               "judge_mean": round(statistics.fmean(g for _, g in pairs), 4)}
                        for kind, pairs in _by_kind(items, grades).items()}}


def report(items: Sequence[Item], grades: Sequence[int], name: str) -> str:
    """The tables for one judge and mode; the last line is the machine-readable summary."""
    lines = [f"== {name}", f"{'items':<13}{'n':>4}{'mae':>7}{'spearman':>10}{'wrong_mean':>12}"
             f"{'n_wrong':>9}{'LLM-Match':>11}{'by hand':>9}"]
    overall = None
    for label, idx in _groups(items):
        s = scores([items[k].grade for k in idx], [grades[k] for k in idx])
        overall = overall or s
        lines.append(f"{label:<13}{s.n:>4}{_f(s.mae):>7}{_f(s.spearman):>10}{_f(s.wrong_mean):>12}"
                     f"{s.n_wrong:>9}{_f(s.match, 1):>11}{_f(s.hand_match, 1):>9}")
    lines.append("per kind (mean hand grade -> mean judge grade): " + "; ".join(
        f"{kind} {statistics.fmean(h for h, _ in pairs):.2f}->{statistics.fmean(g for _, g in pairs):.2f}"
        f" (n={len(pairs)})" for kind, pairs in _by_kind(items, grades).items()))
    assert overall is not None
    lines.append(f"judge={name} n={overall.n} mae={_f(overall.mae, 3)} "
                 f"spearman={_f(overall.spearman, 3)} wrong_mean={_f(overall.wrong_mean, 3)}")
    return "\n".join(lines)


def write_figures(out: Path, data: Path, items: Sequence[Item], records: Sequence[dict[str, Any]]
                  ) -> None:
    """``--out``: the data set (its path relative to the repository where it can be, and its
    sha256), the code version and each judge's figures."""
    import hashlib

    from efficienteqa.records import code_version

    where = Path(os.path.relpath(data.resolve(), REPO))
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({
        "data": str(where), "data_sha256": hashlib.sha256(data.read_bytes()).hexdigest(),
        "items": len(items), "wrong_grade": WRONG, "code_version": code_version(),
        "judges": list(records)}, indent=2) + "\n")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA,
                        help="graded items, one JSON object per line (default: the shared set)")
    parser.add_argument("--judge", action="append", help=f"a VLM spec (default {DEFAULT_JUDGE}); repeatable")
    parser.add_argument("--judge-mode", action="append", choices=(*JUDGE_MODES, "auto"),
                        help=f"{' | '.join(JUDGE_MODES)} | auto (default auto); repeatable")
    parser.add_argument("--limit", type=int, default=None, help="only the first N items")
    parser.add_argument("--fresh", action="store_true", help="ignore earlier cached grades")
    parser.add_argument("--dump", type=Path, default=None,
                        help="also write every judgement as JSON lines to this file")
    parser.add_argument("--out", type=Path, default=None,
                        help="also write the figures of every judge and mode as JSON to this file")
    args = parser.parse_args(argv)

    items = load_items(args.data)[:args.limit]
    judges = args.judge or [DEFAULT_JUDGE]
    modes = args.judge_mode or ["auto"]
    scratch = tempfile.TemporaryDirectory() if args.fresh else None
    dump: list[dict[str, Any]] = []
    finals: list[str] = []
    records: list[dict[str, Any]] = []
    try:
        for spec in judges:
            for mode in dict.fromkeys(resolve_mode(m, spec) for m in modes):
                cache = Path(scratch.name) / f"{len(finals)}.sqlite" if scratch else None
                grades, judgements = grade_all(items, spec, mode, cache)
                text = report(items, grades, f"{spec}:{mode}")
                print(text + "\n", flush=True)
                finals.append(text.splitlines()[-1])
                records.append(record(items, grades, spec, mode))
                dump += [{"judge": spec, "mode": mode, **r} for r in judgements]
    finally:
        if scratch is not None:
            scratch.cleanup()
    if args.dump is not None:
        args.dump.write_text("".join(json.dumps(r) + "\n" for r in dump))
    if args.out is not None:
        write_figures(args.out, args.data, items, records)
    if len(finals) > 1:
        print("\n".join(finals))
    return 0


if __name__ == "__main__":
    sys.exit(main())
