"""Records on disk: JSON-safe values, atomic JSON files, the code version that wrote them and a
run folder's lock.

Low level on purpose: the episode report, the evaluation runner and the benchmarks all write
results through these, and none of them should import another to do so.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, is_dataclass
from pathlib import Path
from typing import Any

import numpy as np

import efficienteqa
from efficienteqa.errors import EfficientEQAError
from efficienteqa.redact import redacted

LOCK_FILE = ".lock"  # a run folder's lock (run_lock)


def read_json(data: str | bytes) -> Any:
    """``json.loads`` for files a user hands over: a document nested too deep for the parser
    is a ``ValueError`` like any other that is not JSON (not a ``RecursionError``)."""
    try:
        return json.loads(data)
    except RecursionError:
        raise ValueError("nested too deep") from None


def code_version() -> str:
    """The package version, plus the git commit (and "-dirty") when run from a checkout."""
    root = Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(["git", "-C", str(root), "describe", "--always", "--dirty"],
                                capture_output=True, text=True, timeout=5, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit = ""
    return f"{efficienteqa.__version__}+{commit}" if commit else efficienteqa.__version__


def plain(value: Any) -> Any:
    """JSON-safe: dataclasses, tuples, numpy scalars and arrays; NaN/inf become None."""
    if is_dataclass(value) and not isinstance(value, type):
        return plain(asdict(value))
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return plain(value.item())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def probe_write(folder: Path) -> None:
    """``folder`` (made where missing) takes a new file: one is created and removed there.
    OSError where it cannot be (read-only, immutable, not a folder, full of inodes). A probe,
    not ``os.access``: root passes every permission check, but not a read-only file system or
    an immutable folder."""
    folder.mkdir(parents=True, exist_ok=True)
    fd, probe = tempfile.mkstemp(dir=folder, prefix=".write-check")
    os.close(fd)
    os.unlink(probe)


def check_writable(folder: Path) -> None:
    """Fail in one line, before any work, when ``folder`` cannot be created or written to."""
    try:
        probe_write(folder)
    except OSError as error:
        raise EfficientEQAError(f"cannot write to {folder}: {error.strerror or error}",
                                fix="choose another --out folder") from None


def write_json(path: Path, data: dict[str, Any]) -> Path:
    """Written atomically (temporary file, then rename): a reader never sees half a file.
    Passwords in URLs are written as ``***`` (``redact``)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        json.dump(redacted(data), f, indent=1, allow_nan=False)
    os.replace(tmp, path)
    return path


@contextmanager
def run_lock(out: Path) -> Iterator[None]:
    """Hold ``out``'s lock while a run (an evaluation, an ask) writes there: a second run into
    the same folder fails at once instead of running every episode again beside the first."""
    import fcntl

    out.mkdir(parents=True, exist_ok=True)
    try:
        fd = os.open(out / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as error:  # a folder of that name, a file this user may not write
        raise EfficientEQAError(f"cannot open the run's lock {out / LOCK_FILE}: "
                                f"{error.strerror or error}",
                                fix="remove it if no run is writing there, or use another --out "
                                    "folder") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise EfficientEQAError(f"another run is writing to {out}",
                                    fix="wait for it to end, or use another --out folder") from None
        yield
    finally:
        os.close(fd)  # releases the lock
