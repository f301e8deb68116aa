"""The ``efficienteqa`` command: parse, build, call a library function, print.

``run`` holds the agent's commands (ask, eval, judge, report), whose options are made from the
configuration tree (``options``); ``tools`` the others (scenes, models, perception);
``splits`` the frozen splits' (``scenes verify``, ``scenes export-walks``).
"""

from __future__ import annotations

import sys

from rich.markup import escape

from efficienteqa.cli import run, splits, tools  # noqa: F401 - registers the commands
from efficienteqa.cli.app import app, console
from efficienteqa.errors import EfficientEQAError
from efficienteqa.redact import redact_urls

__all__ = ["app", "main"]


def main() -> None:
    """Entry point: user-fixable errors become one red line and exit code 1."""
    try:
        app()
    except EfficientEQAError as exc:
        # escaped: a fix such as pip install 'efficienteqa[ray]' is text, not rich markup; a
        # URL's password (e.g. in a --backends.vlm the error quotes) is not printed
        console.print(f"[red]error:[/red] {escape(redact_urls(str(exc)))}", highlight=False,
                      soft_wrap=True)
        sys.exit(1)
    except KeyboardInterrupt:  # before a command runs (a command's own: app.Commands)
        console.print("[yellow]interrupted[/yellow]")
        sys.exit(130)
