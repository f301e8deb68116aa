"""Count bench (DESIGN 9, defect 4 of the walks): how long count questions wait after first sight, and the
count the direct answer is told, without a language model.

Each count question of the given houses is walked by the default agent with a stub answer
model (no model call is made for the walk); the answer prompt it would send is read back: the
count its note states ("... the answer is N.", ``answer.views.count_note``: the one focused
view's, or the instance map's where they differ) and the count of the question's object in its
one focused view (``answer.views.parse_entry``), each compared with the reference. First sight
is ``evidence_first_seen_step`` (every chair of the group in view, the oracle's rule).

    python -m experiments.count_bench --seeds training
    python -m experiments.count_bench --seeds training --no-gate-final   # the outlier alone
    python -m experiments.count_bench --seeds 3900-3909 --perception pixels

Develop on the training houses (0-99); check on validation houses (2000-2009, and the
perception's 3900-3909); never the held-out houses 100-129.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import tempfile
from pathlib import Path

from efficienteqa.agent import AgentConfig
from efficienteqa.answer.views import parse_entry
from efficienteqa.ask import ask
from efficienteqa.eval.synthetic_judge import rule_judgement
from efficienteqa.models.backends import build_chat_model
from efficienteqa.models.recording import RecordingChatModel
from efficienteqa.models.stub import StubChatModel
from efficienteqa.question import parse_question
from efficienteqa.scenes import open_scene
from efficienteqa.stack import Stack, parse_vlm
from experiments.common import seed_set


def stated_count(question: str, prompt: str) -> int:
    """The largest count of the question's object in one view of an answer prompt."""
    target = parse_question(question)
    counts = [0]
    for view in re.findall(r"^view \d+: (.*)$", prompt, re.M):
        listed = view.partition(". ")[2].removeprefix("Seen: ").removeprefix("Visible: ")
        entries = map(parse_entry, listed.split(". ")[0].split("; "))
        counts.append(sum(e.count for e in entries if target.is_a(target.object, e.noun)))
    return max(counts)


def told_count(prompt: str) -> int | None:
    """The count the answer prompt's note tells the model ("... the answer is N."), if any."""
    said = re.search(r"the answer is (\d+)\.", prompt)
    return int(said.group(1)) if said else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="training")
    ap.add_argument("--no-gate-final", action="store_true")
    ap.add_argument("--perception", default="semantic", choices=("semantic", "pixels"))
    ap.add_argument("--out", type=Path, help="a JSON line per question")
    ap.add_argument("--model", action="store_true",
                    help="answer with the stack's chat model (Qwen2.5-Coder-1.5B on llama.cpp by "
                         "default), graded by the rule judge; default: a stub, no model call")
    args = ap.parse_args()
    config = AgentConfig.of(gate_final=not args.no_gate_final)
    stack = Stack(perception=args.perception)
    waits, right, told_right, judged_right, n, rows = [], 0, 0, 0, 0, []
    for seed in seed_set(args.seeds):
        scene = open_scene(f"synthetic:{seed}", oracle=False)  # oracle steps: not read here
        try:
            for q in [q for q in scene.questions if q.category == "count"]:
                stub = StubChatModel(lambda messages: "0")
                chat = RecordingChatModel(build_chat_model(parse_vlm(
                    stack.vlm, images=False))) if args.model else stub
                r = ask(q.question, scene, Path(tempfile.mkdtemp()), stack=stack,
                        config=config, model=chat, report=False).record
                prompt = (chat.exchanges[-1].prompt if isinstance(chat, RecordingChatModel)
                          else stub.requests[-1].messages[-1].text)
                said, told = stated_count(q.question, prompt), told_count(prompt)
                first = r.get("evidence_first_seen_step")
                if first:
                    waits.append(r["steps"] - first)
                n, right = n + 1, right + (str(said) == str(q.answer))
                told_right += str(told) == str(q.answer)
                final = bool(r["per_step"] and (r["per_step"][-1].get("gate") or {}).get("final"))
                if args.model:
                    judged = rule_judgement(q.question, "count", q.accepted, r["answer"])
                    judged_right += judged.value >= 100
                rows.append({"id": q.id, "question": q.question, "truth": q.answer,
                             "answer": r["answer"] if args.model else None,
                             "right": judged.value >= 100 if args.model else None,
                             "view": said, "told": told, "steps": r["steps"],
                             "stop": r["stop_reason"], "final": final, "first_sight": first,
                             "poses": [s["pose"] for s in r["per_step"]]})
                print(f"{q.id} truth {q.answer} told {told} view {said} steps {r['steps']} "
                      f"{r['stop_reason']}{' (final)' if final else ''} first sight {first}",
                      flush=True)
        finally:
            scene.env.close()
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("".join(json.dumps(row) + "\n" for row in rows))
    if args.model:
        print(f"answered by {stack.vlm}: {judged_right}/{n} right (rule judge)")
    print(f"seeds {args.seeds}, perception {args.perception}, gate_final "
          f"{config.stop.gate_final}: {told_right}/{n} told counts right, {right}/{n} counts of "
          f"the one focused view right; {sum(r['final'] for r in rows)} stopped by a whole "
          f"group, mean steps {statistics.mean(r['steps'] for r in rows):.1f}; first sight -> "
          f"stop {statistics.mean(waits) if waits else float('nan'):.2f} steps on average "
          f"(median {statistics.median(waits) if waits else None}) over {len(waits)} seen")


if __name__ == "__main__":
    main()
