"""Where an episode's rerun log can go, checked before any slow work: the rerun SDK (imported
here, when asked, never with this module), the viewer that ``live`` spawns, or a ``.rrd`` file
that can be written. Kept apart from ``rerun_log`` because the command line checks a target
before the scene opens, without loading the agent's modules that the log needs.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path
from types import ModuleType

from efficienteqa.errors import EfficientEQAError
from efficienteqa.records import probe_write

LIVE = "live"  # the target that spawns a viewer instead of writing a file
INSTALL = "pip install 'efficienteqa[rerun]'"


def import_rerun() -> ModuleType:
    """The rerun SDK, or the one-line error that says how to install it."""
    try:
        import rerun
    except ImportError as error:
        missing = isinstance(error, ModuleNotFoundError) and (error.name or "rerun").startswith("rerun")
        said = "is not installed" if missing else f"does not import ({str(error).splitlines()[0]})"
        raise EfficientEQAError(f"the rerun SDK {said}", fix=INSTALL) from None
    return rerun


def viewer_executable() -> str | None:
    """The rerun viewer that the SDK installs beside this Python, or one on PATH."""
    here = Path(sys.executable).parent / "rerun"
    return str(here) if here.is_file() and os.access(here, os.X_OK) else shutil.which("rerun")


def check_target(target: str | Path, *, overwrite: bool = False) -> None:
    """Fail in one line, before any slow work, where ``target`` cannot be logged to: rerun is
    not installed, ``live`` where no viewer can start (no executable, no screen), a file that
    is not ``.rrd``, that exists (unless ``overwrite``; a folder, never) or whose folder cannot
    be written (a file is made and removed there to know)."""
    import_rerun()
    if str(target) == LIVE:
        if viewer_executable() is None:
            raise EfficientEQAError("no rerun viewer to start: the rerun executable is not "
                                    "installed here", fix=f"{INSTALL}, or write a file: "
                                    "--rerun episode.rrd")
        if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                     or os.environ.get("WAYLAND_DISPLAY")):
            raise EfficientEQAError("no rerun viewer can start here: no screen (DISPLAY and "
                                    "WAYLAND_DISPLAY are unset)",
                                    fix="write a file, --rerun episode.rrd, and open it with "
                                        "rerun episode.rrd where there is a screen")
        return
    path = Path(target)
    if path.suffix != ".rrd":
        raise EfficientEQAError(f"--rerun takes a .rrd file or {LIVE}, not {str(target)!r}",
                                fix="e.g. --rerun out/ask/episode.rrd, or --rerun live")
    if path.is_dir():
        raise EfficientEQAError(f"--rerun {path} is a folder, and a rerun recording is a file",
                                fix="choose another --rerun file")
    if (path.exists() or path.is_symlink()) and not overwrite:
        raise EfficientEQAError(f"{path} exists; a rerun recording is not written over",
                                fix="remove it, choose another --rerun file, or give --overwrite "
                                    "to replace it")
    try:
        probe_write(path.parent)
    except OSError as error:
        raise EfficientEQAError(f"cannot write the rerun recording {path}: "
                                f"{error.strerror or error}", fix="choose another --rerun file") from None
