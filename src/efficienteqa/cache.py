"""Where slow one-time artefacts live (converted furniture, built wheels, model files)."""

import os
from pathlib import Path

from efficienteqa.errors import EfficientEQAError


def cache_path(*parts: str) -> Path:
    """``$EFFICIENTEQA_CACHE`` or ``$XDG_CACHE_HOME/efficienteqa`` (default ``~/.cache``), and
    ``parts`` under it, not created: for what is only read there when it exists (a kept probe)."""
    root = os.environ.get("EFFICIENTEQA_CACHE")
    if root:
        base = Path(root)
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "efficienteqa"
    return base.joinpath(*parts)


def cache_dir(*parts: str) -> Path:
    """``cache_path(*parts)``, created. A folder that cannot be created (a read-only home, an
    immutable folder, a file in its place, common in containers and on shared clusters) is one
    line naming it, not the ``OSError``'s traceback; callers that can do without it catch that
    and go on without the cache."""
    path = cache_path(*parts)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise EfficientEQAError(f"cannot create the cache folder {path}: "
                                f"{error.strerror or error}",
                                fix="set EFFICIENTEQA_CACHE to a writable folder") from None
    return path
