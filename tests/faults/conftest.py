"""The fault suite's fixtures (its shared names and what the suite holds: harness.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from clirun import Result, run_cli
from faults.harness import KEY, SECRETS, files_holding


@pytest.fixture
def env(tmp_path: Path) -> dict[str, str]:
    """The commands' environment: a cache of the test's own, ``KEY`` as the OpenAI key, no Ray
    address, wide lines. A test may change it before running commands."""
    out = {k: v for k, v in os.environ.items() if not k.startswith(("EFFICIENTEQA_", "RAY_"))}
    hm_eqa = os.environ.get("EFFICIENTEQA_HM_EQA")
    return {**out, **({"EFFICIENTEQA_HM_EQA": hm_eqa} if hm_eqa else {}),
            "OPENAI_API_KEY": KEY, "EFFICIENTEQA_CACHE": str(tmp_path / "cache"),
            "COLUMNS": "300", "PYTHONPATH": os.pathsep.join(
                [str(Path(__file__).parents[1]), os.environ.get("PYTHONPATH", "")])}


@pytest.fixture
def cli(env: dict[str, str], capfd: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> Callable[..., Result]:
    """``cli(*args)`` runs ``efficienteqa ARGS`` in this process with ``env``."""

    def run(*args: str) -> Result:
        return run_cli(args, env, capfd, monkeypatch)

    return run


@pytest.fixture
def spawn(env: dict[str, str]) -> Callable[..., subprocess.CompletedProcess[str]]:
    """``spawn(*args, timeout=120)`` runs ``efficienteqa ARGS`` in a subprocess with ``env``."""

    def run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "efficienteqa.cli", *args],
                              capture_output=True, text=True, env=env, timeout=timeout)

    return run


@pytest.fixture(autouse=True)
def no_secret_written(tmp_path: Path) -> Iterator[None]:
    """After each trial: no file under the test's folder (its run folders, its cache, any Ray
    session a test keeps there) holds the key or the URL password."""
    yield
    found = [f for secret in SECRETS for f in files_holding(tmp_path, secret)]
    assert found == [], f"a secret was written to {found}"
