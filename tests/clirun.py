"""``efficienteqa ARGS`` run in the test's own process: ``efficienteqa.cli.main`` with ``sys.argv``
and the environment set, its output captured at the file descriptors. An exception that escapes
``main`` fails the test with its traceback, as it would print one to a user. No interpreter
start and no imports per command: a command costs what its work costs."""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass

import pytest


@dataclass
class Result:
    returncode: int
    stdout: str
    stderr: str

    @property
    def said(self) -> str:
        return self.stdout + self.stderr


def run_cli(args: list[str] | tuple[str, ...], env: dict[str, str],
            capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> Result:
    """Runs the command with exactly ``env`` as its environment (restored after)."""
    from efficienteqa.cli import main
    from efficienteqa.cli.app import console

    capfd.readouterr()
    with monkeypatch.context() as patch:
        for name in set(os.environ) - set(env):
            patch.delenv(name)
        for name, value in env.items():
            patch.setenv(name, value)
        columns = env.get("COLUMNS", "")
        if columns.isdigit():  # read by a new process's console when it starts
            patch.setattr(console, "_width", int(columns))
        patch.setattr(sys, "argv", ["efficienteqa", *args])
        try:
            main()
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    out, err = capfd.readouterr()
    return Result(code, out, err)
