"""Answer benchmark (DESIGN 8, results/answer/): the answer step alone, from oracle frames.

Questions come from synthetic houses. A question with evidence is answered from the frame at its
``oracle_pose`` (checked with ``evidence_visible``; a question whose oracle frame does not show
the evidence is left out and counted), described by the semantic perception exactly as the
agent's answer step reads it (``SemanticPerception.frame(obs)``). A "no" existence question (no
evidence) is answered from a frame of the room it names: from the room's centre (or the nearest
navigable cell in the room), turned to the heading of 8 that shows the most objects.
``--extra N`` adds N frames from random poses of the same house after the oracle frame, to
mimic a top-K with other views (default 0: the oracle frame alone).

Variants (``--variant``):

- ``paper``: DESIGN 3.5's answer, ``RagAnswerer`` with M=3 verbalized candidates, LLM grouping
  with MiniLM proposals, argmax of the grouped normalised confidences (``--answer paper``);
- ``first-guess``: the first candidate of the same reply (same prompt, so the response cache
  replays it), no grouping; its own verbalized confidence / 100;
- ``token``: ``RagAnswerer(confidence="token")``: one greedy answer to ``answer_token.txt``,
  confidence its token probability (the white-box baseline's answer);
- ``direct``: the agent's default answer (``--answer direct``): the same with a one-line hint
  for the question's form (``answer.prompting.question_hint``), reading the views cut to what the
  question names (``answer.views.focus_views``).

Graded by the rule judge. Per question a JSONL row is cached in ``--out`` (runs resume).

    python -m experiments.answer_bench run --seeds training --variant paper --per-category 4
    python -m experiments.answer_bench run --seeds held-out --variant token --per-category 6
    python -m experiments.answer_bench table out/answer_bench/held-out-direct.jsonl
    python -m experiments.answer_bench run --seeds held-out --perception pixels --out F.jsonl

Develop on the training houses (0-20); report the held-out houses (2000 and up).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import statistics
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M
from efficienteqa.envs.synthetic.questions import CATEGORIES, Question, evidence_visible
from efficienteqa.eval.llm_match_rules import MAX_SCORE
from efficienteqa.eval.synthetic_judge import rule_judgement
from efficienteqa.geometry import Pose2D
from efficienteqa.perception.pixels.backend import PixelPerception
from efficienteqa.perception.semantic import SemanticPerception
from efficienteqa.scenes import synthetic_questions
from experiments.common import auc, seed_set

VARIANTS = ("paper", "first-guess", "token", "direct")
HEADINGS = 8


# -- pure parts (tested) ----------------------------------------------------------------------
def category_table(rows: Sequence[dict], categories: Sequence[str] = CATEGORIES
                   ) -> dict[str, tuple[int, int]]:
    """category -> (right, asked), in ``categories`` order (absent ones left out), and "all"."""
    out: dict[str, tuple[int, int]] = {}
    for cat in categories:
        mine = [r for r in rows if r["category"] == cat]
        if mine:
            out[cat] = (sum(1 for r in mine if r["right"]), len(mine))
    out["all"] = (sum(1 for r in rows if r["right"]), len(rows))
    return out


def format_table(label: str, rows: Sequence[dict]) -> str:
    table = category_table(rows)
    head = "| variant | " + " | ".join(table) + " | AUC | median s |"
    sep = "|" + "---|" * (len(table) + 3)
    cells = [f"{r}/{n}" for r, n in table.values()]
    right, n = table["all"]
    cells[-1] = f"{right}/{n} ({100 * right / n:.0f}%)" if n else "0/0"
    a = auc([r["confidence"] for r in rows], [r["right"] for r in rows])
    secs = [r["seconds"] for r in rows if r.get("seconds") is not None]
    med = f"{statistics.median(secs):.1f}" if secs else "-"
    line = f"| {label} | " + " | ".join(cells) + f" | {'-' if a is None else f'{a:.2f}'} | {med} |"
    return "\n".join([head, sep, line])


# -- frames --------------------------------------------------------------------------------
def _room_frame(env: SyntheticEnv, perception: SemanticPerception, q: Question
                ) -> tuple[Pose2D, str] | None:
    """A frame of the room a "no" question names: the heading of ``HEADINGS`` from the room's
    centre (or its nearest navigable cell) that shows the most objects."""
    text = q.question.lower()
    rooms = sorted(env.house.layout.rooms, key=lambda r: -len(r.name))
    room = next((r for r in rooms if re.search(rf"\bthe {re.escape(r.name.lower())}\b", text)),
                None)
    if room is None:
        return None
    cx, cy = (room.x0 + room.x1) / 2, (room.y0 + room.y1) / 2
    best: tuple[float, float] | None = None
    if env.is_navigable(cx, cy):
        best = (cx, cy)
    else:
        step = 0.1
        cands = [(cx + dx * step, cy + dy * step) for dx in range(-40, 41) for dy in range(-40, 41)]
        cands = [(x, y) for x, y in cands if room.x0 < x < room.x1 and room.y0 < y < room.y1
                 and env.is_navigable(x, y)]
        if cands:
            best = min(cands, key=lambda p: math.hypot(p[0] - cx, p[1] - cy))
    if best is None:
        return None
    views = []
    for k in range(HEADINGS):
        pose = Pose2D(best[0], best[1], -math.pi + 2 * math.pi * k / HEADINGS)
        obs = env.observe(pose)
        views.append((len(perception.describe(obs).objects), k, pose, perception.frame(obs)))
    n, _, pose, desc = max(views, key=lambda v: (v[0], -v[1]))
    return pose, desc


def evidence_frames(env: SyntheticEnv, perception: SemanticPerception, q: Question, extra: int,
                    rng: np.random.Generator) -> tuple[list[str], str] | None:
    """The descriptions the model reads (the oracle or room frame first), and how the first was
    chosen; None when the question cannot be given a frame that shows its evidence."""
    if q.evidence:
        if q.oracle_pose is None:
            return None
        obs = env.observe(Pose2D(*q.oracle_pose))
        if not evidence_visible(obs.instance, q.evidence):
            return None
        frames, how = [perception.frame(obs)], "oracle"
    else:
        got = _room_frame(env, perception, q)
        if got is None:
            return None
        frames, how = [got[1]], "room"
    cells = np.argwhere(env.grid.navigable(ROBOT_RADIUS_M)) if extra else np.empty((0, 2))
    tries = 0
    while len(frames) < 1 + extra and tries < 50 * (extra + 1):
        tries += 1
        x, y = env.grid.spec.cell_to_world(cells[rng.integers(len(cells))])
        obs = env.observe(Pose2D(float(x), float(y), float(rng.uniform(-math.pi, math.pi))))
        desc = perception.frame(obs)
        if desc not in frames:
            frames.append(desc)
    return frames, how


def questions(seeds: Sequence[int], per_category: int, assets: str
              ) -> Iterator[tuple[SyntheticEnv, Question]]:
    """Up to ``per_category`` questions of each category, houses in order."""
    taken = dict.fromkeys(CATEGORIES, 0)
    for seed in seeds:
        if all(v >= per_category for v in taken.values()):
            return
        with SyntheticEnv.from_seed(seed, assets) as env:
            for q in synthetic_questions(env):
                if taken.get(q.category, per_category) >= per_category:
                    continue
                taken[q.category] += 1
                yield env, q


# -- answering -----------------------------------------------------------------------------
def build_answerer(variant: str):  # noqa: ANN201 (RagAnswerer and its model)
    from efficienteqa.answer.rag import RagAnswerer
    from efficienteqa.models.backends import build_chat_model
    from efficienteqa.stack import Stack, build_grouper, build_relevancy, parse_vlm
    from efficienteqa.vc.parse import M

    stack = Stack()
    model = build_chat_model(parse_vlm(stack.vlm, images=False, cache=stack.cache))
    if variant in ("token", "direct"):
        return RagAnswerer(model, build_grouper("rules", model, None), m=M, confidence="token",
                           direct=variant == "direct"), stack
    grouper = build_grouper(stack.grouping, model, build_relevancy(stack.relevancy))
    return RagAnswerer(model, grouper, m=M), stack


def answer_row(answerer, variant: str, q: Question, frames: list[str]) -> dict:  # noqa: ANN001
    from efficienteqa.vc.parse import M, parse_candidates

    t0 = time.perf_counter()
    res = answerer.answer(q.question, frames)
    seconds = time.perf_counter() - t0
    answer, confidence = res.answer, float(res.confidence)
    if variant == "first-guess":
        cands = parse_candidates(res.raw, M).candidates
        answer = cands[0].text if cands else ""
        confidence = min(max(cands[0].confidence / 100.0, 0.0), 1.0) if cands else 0.0
    grade = rule_judgement(q.question, q.category, q.accepted, answer)
    return {"house": q.house_seed, "id": q.id, "category": q.category, "question": q.question,
            "accepted": q.accepted, "answer": answer, "confidence": round(confidence, 4),
            "right": grade.score == MAX_SCORE, "raw": res.raw, "frames": frames,
            "seconds": round(seconds, 2), "variant": variant, "grade": grade.raw}


def cmd_run(args: argparse.Namespace) -> None:
    out = Path(args.out or f"out/answer_bench/{args.seeds}-{args.variant}"
               f"{'-x' + str(args.extra) if args.extra else ''}.jsonl")
    out.parent.mkdir(parents=True, exist_ok=True)
    done = {r["id"]: r for r in map(json.loads, out.open())} if out.exists() else {}
    answerer, _ = build_answerer(args.variant)
    pixels = PixelPerception.load() if args.perception == "pixels" else None
    rows, left_out = [], []
    with out.open("a") as fh:
        for env, q in questions(seed_set(args.seeds), args.per_category, args.assets):
            if q.id in done:
                rows.append(done[q.id])
                continue
            rng = np.random.default_rng(q.house_seed * 100 + int(q.id.rsplit("-", 1)[1]))
            perception = pixels or SemanticPerception(env.scene_labels())
            got = evidence_frames(env, perception, q, args.extra, rng)
            if got is None:
                left_out.append(q.id)
                continue
            row = answer_row(answerer, args.variant, q, got[0])
            row["frame_from"] = got[1]
            fh.write(json.dumps(row) + "\n")
            fh.flush()
            rows.append(row)
            print(f"{q.id} {q.category:14s} {'ok ' if row['right'] else 'BAD'} "
                  f"{row['confidence']:.2f} {row['seconds']:.1f}s  {q.question} -> "
                  f"{row['answer']!r} (want {q.answer!r})", flush=True)
    houses = sorted({r["house"] for r in rows})
    print(f"\nseeds {args.seeds} (houses {houses[0]}-{houses[-1]} used), {len(rows)} questions; "
          f"left out (oracle frame without the evidence, or no room frame): {left_out or 'none'}")
    print(format_table(args.variant, rows))


def cmd_table(args: argparse.Namespace) -> None:
    for path in args.files:
        rows = [json.loads(line) for line in Path(path).read_text().splitlines()]
        print(f"{path}: houses {sorted({r['house'] for r in rows})}")
        print(format_table(rows[0]["variant"] if rows else path, rows) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    run = sub.add_parser("run")
    run.add_argument("--seeds", default="training")
    run.add_argument("--variant", choices=VARIANTS, default="direct")
    run.add_argument("--per-category", type=int, default=6)
    run.add_argument("--extra", type=int, default=0, help="other frames of the house")
    run.add_argument("--assets", default="sh3d")
    run.add_argument("--perception", choices=("semantic", "pixels"), default="semantic",
                     help="what describes the frames: the labels, or the pixel network")
    run.add_argument("--out", default=None)
    run.set_defaults(func=cmd_run)
    table = sub.add_parser("table")
    table.add_argument("files", nargs="+")
    table.set_defaults(func=cmd_table)
    args = ap.parse_args()
    args.func(args)


if __name__ == "__main__":
    main()
