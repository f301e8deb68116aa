"""Progress lines of the local-model set-up: ours and pip's go to stderr, so stdout carries only
results (scripts can hide the chatter)."""

from __future__ import annotations

import sys

STDERR_FD = 2


def say(progress: bool, text: str) -> None:
    if progress:
        print(text, file=sys.stderr, flush=True)
