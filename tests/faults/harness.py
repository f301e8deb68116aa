"""The fault suite's shared names (its fixtures are in conftest.py). The suite holds a hostile
user's trials (kills and resumes, corrupt run folders, bad input, misbehaving model servers,
secrets, the response cache), each run as the user ran it: the ``efficienteqa`` command against
the test server (tests/vlm_server.py) on loopback.

The bar of every trial: exit 0 or one ``error:`` line with exit 1; no traceback; no episode lost
or doubled; no secret in any file the command wrote (``KEY`` is exported as the API key of
every command, and the ``no_secret_written`` check reads every file under the test's folder).

Two ways to run a command:
- ``cli(*args)``: in this process (``efficienteqa.cli.main`` with ``sys.argv`` set, output
  captured at the file descriptors). An exception that escapes ``main`` fails the test with
  its traceback, as it would print one to a user. Most trials run so: no interpreter start.
- ``spawn(*args)``: a subprocess, for what needs one: signals, kills, two commands at once,
  Ray.

Each test is marked with the trials it holds: ``@trial("1.4", "1.9")``.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from clirun import Result

KEY = "sk-FAKE-faults-ZZ9Q8W7"
PASSWORD = "URLSECRETPW-4f9c1e"
SECRETS = (KEY, PASSWORD)
QUESTION = "What is on the desk in the office?"

# The trials' short names (FAULT-TRIALS): B, the blind method on the fixed synthetic split with
# answers grouped by rules and no cache; A, ask in synthetic house 0 with two steps; S, the stub
# method of tests/eval_stubs.py on the synthetic split (no model calls, no judge).
BLIND = ("eval", "--eval.method", "blind", "--eval.dataset", "synthetic", "--backends.grouping",
         "rules", "--backends.no-cache")
ASK = ("ask", QUESTION, "--scene", "synthetic:0", "--scene.assets", "builtin",
       "--explore.max-steps", "2", "--backends.no-cache")
STUB = ("eval", "--eval.method", "eval_stubs:echo", "--eval.dataset", "synthetic",
        "--eval.judge", "none")

trial = pytest.mark.trial


def one_error_line(result: Result | subprocess.CompletedProcess[str]) -> str:
    """The command failed with exit 1, one ``error:`` line on stdout, and no traceback."""
    said = result.stdout + result.stderr
    assert "Traceback" not in said, said[-3000:]
    assert result.returncode == 1, said[-3000:]
    errors = [line for line in result.stdout.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, said[-3000:]
    return errors[0]


def ran(result: Result | subprocess.CompletedProcess[str]) -> str:
    """The command succeeded without a traceback; what it said."""
    said = result.stdout + result.stderr
    assert result.returncode == 0 and "Traceback" not in said, said[-3000:]
    return said


def episode_ids(run: Path) -> list[str]:
    """The ids of the whole rows of a run's ``episodes.jsonl``, in order (torn lines skipped)."""
    import json

    ids = []
    for line in (run / "episodes.jsonl").read_text(errors="replace").splitlines():
        try:
            row = json.loads(line)
        except ValueError:
            continue
        if isinstance(row, dict) and isinstance(row.get("id"), str):
            ids.append(row["id"])
    return ids


def files_holding(folder: Path, secret: str) -> list[str]:
    return [str(p) for p in folder.rglob("*")
            if p.is_file() and not p.is_symlink() and secret.encode() in p.read_bytes()]
