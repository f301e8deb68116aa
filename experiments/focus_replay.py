"""Answer the recorded top-K views of finished episodes again with today's direct answer.

The answer step alone, on real retrieval: for each episode of an evaluation run folder (written
by ``efficienteqa eval --out RUN``, with its ``episodes/`` folders), the views of the recorded
answer prompt are answered again by ``answer_token_probability(hinted=True)`` (the agent's
direct answer, which reads them through ``focus_views``), graded by the rule judge, and set
beside the run's own answer. Only the answer call reaches the model (the local default).

    python -m experiments.focus_replay out/e2e/default out/focus/default-focus.jsonl

Rows are appended to the output JSONL (a re-run skips the episodes it holds).
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

from efficienteqa.answer.calls import answer_token_probability
from efficienteqa.eval.llm_match_rules import MAX_SCORE
from efficienteqa.eval.synthetic_judge import rule_judgement
from efficienteqa.models.backends import build_chat_model
from efficienteqa.stack import Stack, parse_vlm


def recorded_views(episode: dict) -> list[str]:
    """The views of an episode's answer prompt ("view N: ..." lines), best first."""
    exchange = next(e for e in episode["model"]["exchanges"] if e["phase"] == "answer")
    return re.findall(r"^view \d+: (.*)$", exchange["prompt"], re.M)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("out", type=Path)
    args = ap.parse_args()
    stack = Stack()
    model = build_chat_model(parse_vlm(stack.vlm, images=False, cache=stack.cache))
    done = {json.loads(line)["id"] for line in args.out.open()} if args.out.exists() else set()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with args.out.open("a") as fh:
        for line in (args.run / "episodes.jsonl").open():
            r = json.loads(line)
            if r["id"] in done:
                continue
            folder = args.run / "episodes" / r["id"].replace("/", "__")
            episode = json.loads((folder / "episode.json").read_text())
            res = answer_token_probability(model, r["question"], recorded_views(episode), hinted=True)
            grade = rule_judgement(r["question"], r["category"], r["accepted"], res.answer)
            row = {"id": r["id"], "category": r["category"], "question": r["question"],
                   "before": r["answer"], "before_right": r["rule"]["score"] == MAX_SCORE,
                   "after": res.answer, "after_right": grade.score == MAX_SCORE,
                   "confidence": res.confidence}
            fh.write(json.dumps(row) + "\n")
            fh.flush()
            print(row["id"], row["before_right"], row["after_right"], row["before"], "->",
                  row["after"], flush=True)
    rows = [json.loads(line) for line in args.out.open()]
    print(f"{len(rows)} episodes: right before {sum(r['before_right'] for r in rows)}, "
          f"now {sum(r['after_right'] for r in rows)}")


if __name__ == "__main__":
    main()
