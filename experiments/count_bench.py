"""Count bench (DESIGN 9, defect 4 of the walks): how long count questions wait after first sight, and the
count the direct answer's one focused view states, without a language model.

Each count question of the given houses is walked by the default agent with a stub answer
model (no model call is made for the walk); the answer prompt it would send is read back, and
the count of the question's object in its view (``answer.calls.parse_entry``) is compared with
the reference. First sight is ``evidence_first_seen_step`` (every chair of the group in view,
the oracle's rule).

    python -m experiments.count_bench --seeds training
    python -m experiments.count_bench --seeds training --no-gate-final   # the outlier alone

Develop on the training houses (0-20).
"""

from __future__ import annotations

import argparse
import re
import statistics
import tempfile
from dataclasses import replace
from pathlib import Path

from efficienteqa.agent import AgentConfig
from efficienteqa.answer.calls import parse_entry
from efficienteqa.ask import ask
from efficienteqa.models.stub import StubChatModel
from efficienteqa.question import parse_question
from efficienteqa.scenes import open_scene
from efficienteqa.stack import Stack
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="training")
    ap.add_argument("--no-gate-final", action="store_true")
    args = ap.parse_args()
    config = replace(AgentConfig(), gate_final=not args.no_gate_final)
    waits, right, n = [], 0, 0
    for seed in seed_set(args.seeds):
        scene = open_scene(f"synthetic:{seed}")
        try:
            for q in [q for q in scene.questions if q.category == "count"]:
                stub = StubChatModel(lambda messages: "0")
                r = ask(q.question, scene, Path(tempfile.mkdtemp()), stack=Stack(),
                        config=config, model=stub, report=False).record
                said = stated_count(q.question, stub.requests[-1].messages[-1].text)
                first = r.get("evidence_first_seen_step")
                if first:
                    waits.append(r["steps"] - first)
                n, right = n + 1, right + (str(said) == str(q.answer))
                print(f"{q.id} truth {q.answer} stated {said} steps {r['steps']} "
                      f"{r['stop_reason']} first sight {first}", flush=True)
        finally:
            scene.env.close()
    print(f"seeds {args.seeds}, gate_final {config.stop.gate_final}: {right}/{n} stated counts right; "
          f"first sight -> stop {statistics.mean(waits):.2f} steps on average "
          f"(median {statistics.median(waits)}) over {len(waits)} seen")


if __name__ == "__main__":
    main()
