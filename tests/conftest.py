"""Shared fixtures. Houses use the built-in box assets unless a test needs the real furniture."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.primitives import builtin_catalog
from efficienteqa.geometry import CameraSpec


def egl_available() -> bool:
    try:
        import moderngl

        moderngl.create_standalone_context(backend="egl").release()
        return True
    except Exception:
        return False


def local_model_missing(name: str = "smollm2-135m") -> str | None:
    """Why a real local model's server (``name``: SmolLM2 by default, the tests' fast one)
    cannot run here, or None when it can."""

    from efficienteqa.models import local

    if importlib.util.find_spec("llama_cpp") is None:
        return "llama_cpp is not installed (run scripts/setup.sh or: efficienteqa models runtime)"
    if not local.is_installed(name):
        return f"{name} is not installed (run: efficienteqa models install {name})"
    return None


needs_small_model = pytest.mark.skipif(local_model_missing() is not None,
                                       reason=str(local_model_missing()))
needs_default_model = pytest.mark.skipif(local_model_missing("qwen2.5-coder-1.5b") is not None,
                                         reason=str(local_model_missing("qwen2.5-coder-1.5b")))

@pytest.fixture
def small_model_cache(tmp_path, monkeypatch):
    """A private cache (``EFFICIENTEQA_CACHE``) holding only a link to the installed SmolLM2, so
    server state (pid files, logs, responses) never touches the user's running servers."""
    from efficienteqa.models import local

    model = local.model_path("smollm2-135m")
    cache = tmp_path / "cache"
    (cache / "models").mkdir(parents=True)
    (cache / "models" / model.name).symlink_to(model)
    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(cache))
    return cache


# HM-EQA's csv files (third-party data, never vendored): the shared copy beside the checkout, or
# wherever $EFFICIENTEQA_HM_EQA points (read at collection, before any test unsets it).
HM_EQA = Path(os.environ.get("EFFICIENTEQA_HM_EQA")
              or (Path(__file__).parents[1] / ".." / "shared" / "datasets" / "hm-eqa")).resolve()
needs_hm_eqa = pytest.mark.skipif(not (HM_EQA / "questions.csv").is_file(),
                                  reason=f"HM-EQA csv files not found in {HM_EQA}")


@pytest.fixture
def hm_eqa_dir() -> Path:
    if not (HM_EQA / "questions.csv").is_file():
        pytest.skip(f"HM-EQA csv files not found in {HM_EQA}")
    return HM_EQA


needs_egl = pytest.mark.skipif(
    not egl_available(), reason="no EGL (apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri)")


@pytest.fixture
def vlm(tmp_path, monkeypatch):
    """``vlm(Options(...))`` starts the test server (tests/vlm_server.py), stopped after the
    test; the cache is the test's own and no OpenAI key is in the environment."""
    from vlm_server import servers

    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    with servers() as start:
        yield start


@pytest.fixture
def cli(capfd, monkeypatch):
    """``cli(*args, env=None)`` runs ``efficienteqa ARGS`` in this process (tests/clirun.py) with
    ``env`` as its environment (None: this process's); returns its exit status and output."""
    from clirun import run_cli

    def run(*args: str, env: dict[str, str] | None = None):
        return run_cli(args, dict(os.environ) if env is None else env, capfd, monkeypatch)

    return run


@pytest.fixture(scope="session")
def catalog():
    return builtin_catalog()


@pytest.fixture(scope="session")
def small_camera() -> CameraSpec:
    return CameraSpec().scaled(160, 120)


@pytest.fixture(scope="session")
def env_seed3(catalog) -> SyntheticEnv:
    from efficienteqa.envs.synthetic.generate import generate_house

    env = SyntheticEnv(generate_house(3, catalog, "builtin"), catalog)
    yield env
    env.close()
