"""Methods for runner tests, given to the runner as ``eval_stubs:NAME`` (importable by Ray
workers, which get the driver's ``sys.path``). They answer from the question itself, so they
cost nothing; environment variables set by a test make them slow, fail or die."""

from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.eval.methods import Outcome, RunSpec


def echo(q: EvalQuestion, spec: RunSpec, out: Path) -> Outcome:
    """Answers "stub: QUESTION" (or ``EQA_STUB_ANSWER``) after ``EQA_STUB_SLEEP`` seconds; the
    episode whose id is in
    ``EQA_STUB_FAIL`` raises; the one in ``EQA_STUB_DIE`` kills its own process the first time
    (a marker file under ``EQA_STUB_MARKS`` remembers the attempt)."""
    time.sleep(float(os.environ.get("EQA_STUB_SLEEP", "0")))
    if q.id == os.environ.get("EQA_STUB_FAIL"):
        raise RuntimeError(f"scripted failure of {q.id}\nsecond line not shown")
    if q.id == os.environ.get("EQA_STUB_DIE"):
        mark = Path(os.environ["EQA_STUB_MARKS"]) / q.id.replace("/", "_")
        if not mark.exists():
            mark.write_text(str(os.getpid()))
            os.kill(os.getpid(), signal.SIGKILL)
    return Outcome(os.environ.get("EQA_STUB_ANSWER", f"stub: {q.question}"), 0.9, steps=3, budget=10,
                   stop_reason="relevancy",
                   usage={"calls": 1, "cached_calls": 0, "prompt_tokens": 10,
                          "completion_tokens": 2, "latency_s": 0.01},
                   backends={"environment": "stub", "vlm": "stub"}, extra={"pid": os.getpid()})


def peek(q: EvalQuestion, spec: RunSpec, out: Path) -> Outcome:
    """Answers with everything it was told about the answer (a method must be told nothing)."""
    told = {"answer": q.answer, "alternatives": list(q.alternatives), "accepted": list(q.accepted),
            "oracle_steps": q.oracle_steps, "source": sorted(q.source)}
    return Outcome(json.dumps(told, sort_keys=True), 0.5, steps=0)


def fails_late(q: EvalQuestion, spec: RunSpec, out: Path) -> Outcome:
    """Fails after 3 steps and 4 model calls, as ``ask`` does when the answer call fails: the
    error carries the partial episode."""
    from efficienteqa.errors import EfficientEQAError

    error = EfficientEQAError("model server at http://x/v1 rejected the request: HTTP 400")
    call = {"cached": False, "prompt_tokens": 100, "completion_tokens": 5, "latency_s": 0.5}
    error.partial_episode = {"steps": 3, "model": {"exchanges": [call] * 4}}  # type: ignore[attr-defined]
    raise error
