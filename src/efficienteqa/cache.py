"""Where slow one-time artefacts live (converted furniture, built wheels, model files)."""

import os
from pathlib import Path


def cache_dir(*parts: str) -> Path:
    """``$EFFICIENTEQA_CACHE`` or ``$XDG_CACHE_HOME/efficienteqa`` (default ``~/.cache``)."""
    root = os.environ.get("EFFICIENTEQA_CACHE")
    if root:
        base = Path(root)
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "efficienteqa"
    path = base.joinpath(*parts)
    path.mkdir(parents=True, exist_ok=True)
    return path
