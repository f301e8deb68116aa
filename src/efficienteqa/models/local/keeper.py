"""The on-demand server goes away by itself once nobody uses it.

Every process that uses a local model server holds a shared lock on the server's lease file
(``server/<model>.lease``) for as long as it lives (``hold_lease``, taken before the server is
looked up, so a server cannot be stopped between being found and being used). The keeper, a
small detached process started beside each server it should stop (``python -m
efficienteqa.models.local keep MODEL IDLE_S``: ``server.keep_main``, which calls ``keep``
here), checks every few seconds
whether it can take the lease exclusively: when it can, nobody uses the server; once that has
lasted ``idle_s`` seconds it stops the server while still holding the lease, so a command that
arrives meanwhile waits, then starts a fresh one. Two commands that share a server never see it
vanish: each holds the lease until it exits.

``EFFICIENTEQA_SERVER_IDLE_S`` sets the idle time (default ``IDLE_S``; 0 keeps servers until
``efficienteqa models stop``, as before).
"""

from __future__ import annotations

import fcntl
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO

from efficienteqa.errors import EfficientEQAError

IDLE_S = 300.0  # five minutes, as Ollama unloads an idle model
POLL_S = 2.0
IDLE_ENV = "EFFICIENTEQA_SERVER_IDLE_S"

# The leases this process holds, one per model: released when the process exits.
_held: dict[str, IO[str]] = {}


def idle_seconds() -> float:
    """The idle time after which a server this process starts stops: ``$EFFICIENTEQA_SERVER_IDLE_S``
    (0: never), else ``IDLE_S``."""
    text = os.environ.get(IDLE_ENV, "").strip()
    if not text:
        return IDLE_S
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0 or value == float("inf"):
        raise EfficientEQAError(f"{IDLE_ENV}={text!r} is not a number of seconds",
                                fix="set it to 0 (keep servers) or a positive number, or unset it")
    return value


def hold_lease(path: Path) -> None:
    """Hold a shared lock on ``path`` for the rest of this process (idempotent): the server it
    guards stays up while this process lives. Blocks while a keeper is stopping the server."""
    key = str(path)
    if key in _held:
        return
    handle = path.open("a")
    fcntl.flock(handle, fcntl.LOCK_SH)
    _held[key] = handle


def release_lease(path: Path) -> None:
    """Give up this process's lease on ``path`` (tests; a process's exit does it too)."""
    handle = _held.pop(str(path), None)
    if handle is not None:
        handle.close()


def keep(lease: Path, idle_s: float, alive: Callable[[], bool], stop: Callable[[], None],
         poll_s: float = POLL_S, clock: Callable[[], float] = time.monotonic) -> bool:
    """Watch ``lease`` until the server is gone (``alive`` false: returns False) or nobody has
    held the lease for ``idle_s`` seconds (then ``stop`` runs under the exclusive lock: returns
    True)."""
    idle_since: float | None = None
    with lease.open("a") as handle:
        while alive():
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:  # someone uses the server
                idle_since = None
            else:
                now = clock()
                idle_since = now if idle_since is None else idle_since
                if now - idle_since >= idle_s:
                    try:
                        stop()
                    finally:
                        fcntl.flock(handle, fcntl.LOCK_UN)
                    return True
                fcntl.flock(handle, fcntl.LOCK_UN)
            time.sleep(poll_s)
    return False
