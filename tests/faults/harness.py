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

import os
import signal
import subprocess
import sys
import time
import traceback
import warnings
from collections.abc import Callable
from pathlib import Path

import pytest

from clirun import Result

KEY = "sk-FAKE-faults-ZZ9Q8W7"
PASSWORD = "URLSECRETPW-4f9c1e"
SECRETS = (KEY, PASSWORD)
QUESTION = "What is on the desk in the office?"

# The trials' short names (docs/fault-trials.md): B, the blind method on the fixed synthetic split with
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


class Forked:
    """``efficienteqa ARGS`` in a forked child of this process, for kills and signals: what a
    subprocess runs, without the interpreter start and the imports (2 s a command on two busy
    cores). The child has a session of its own; its output goes to ``log``. Not for commands
    that render (ask, houses): OpenGL's software renderer hangs in a forked child."""

    def __init__(self, env: dict[str, str], log: Path, *args: str,
                 first: Callable[[], object] | None = None, **extra: str) -> None:
        """``first``: what the child does before the command (e.g. wait for a moment)."""
        from efficienteqa.cli import main

        self.log = log
        with warnings.catch_warnings():  # the test server's thread stays in the parent
            warnings.simplefilter("ignore", DeprecationWarning)
            self.pid = os.fork()
        if self.pid:
            self.returncode: int | None = None
            return
        code = 70
        try:
            os.setsid()
            out = open(log, "w", buffering=1)  # noqa: SIM115 - the child ends in os._exit
            os.dup2(out.fileno(), 1)
            os.dup2(out.fileno(), 2)
            sys.stdout = sys.stderr = out
            os.environ.clear()
            os.environ.update({**env, **extra})
            sys.argv = ["efficienteqa", *args]
            signal.signal(signal.SIGINT, signal.default_int_handler)
            if first is not None:
                first()
            try:
                main()
                code = 0
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException:
            traceback.print_exc()
        finally:
            sys.stdout.flush()
            os._exit(code)

    def poll(self) -> int | None:
        if self.returncode is None:
            pid, status = os.waitpid(self.pid, os.WNOHANG)
            if pid:
                self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self, timeout: float = 60) -> int:
        deadline = time.monotonic() + timeout
        while self.poll() is None:
            if time.monotonic() > deadline:
                os.kill(self.pid, signal.SIGKILL)
                raise AssertionError(f"the command did not end: {self.output()[-3000:]}")
            time.sleep(0.01)
        return self.returncode  # type: ignore[return-value]

    def send_signal(self, sig: int) -> None:
        os.kill(self.pid, sig)

    def output(self) -> str:
        return self.log.read_text(errors="replace")


def wait_for(what: Callable[[], bool], proc: Forked | None = None, timeout: float = 60) -> None:
    deadline = time.monotonic() + timeout
    while not what():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"the command ended first: {proc.output()[-3000:]}")
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def count_lines(run: Path) -> int:
    path = run / "episodes.jsonl"
    return path.read_bytes().count(b"\n") if path.exists() else 0


# ---------------------------------------------------------------- 1.4, 1.9-1.11: corrupt lines
