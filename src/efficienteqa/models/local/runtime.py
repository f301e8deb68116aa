"""The llama.cpp runtime: ``llama-cpp-python`` built once as a portable wheel (its default build
segfaults in the AMX kernel on the project's CPUs), cached in ``cache_dir("wheels")`` and
installed from there with its server's dependencies. Never installed from the index."""

from __future__ import annotations

import importlib
import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

from efficienteqa.cache import cache_dir
from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.local._progress import STDERR_FD, say

LLAMA_CPP_VERSION = "0.3.36"
# Plain AVX2, no native tuning: the default build crashes in its AMX kernel here.
PORTABLE_CMAKE_ARGS = ("-DGGML_NATIVE=OFF -DGGML_AVX=ON -DGGML_AVX2=ON -DGGML_FMA=ON -DGGML_F16C=ON "
                       "-DGGML_BMI2=ON -DLLAVA_BUILD=OFF")
# llama_cpp.server's extra ("server" in its pyproject) as import names and as requirements.
SERVER_MODULES = ("fastapi", "uvicorn", "sse_starlette", "starlette_context", "pydantic_settings", "yaml")
SERVER_REQUIREMENTS = ("uvicorn>=0.22.0", "fastapi>=0.100.0", "pydantic-settings>=2.0.1",
                       "sse-starlette>=1.6.1", "starlette-context>=0.3.6,<0.4", "PyYAML>=5.1")


def _importable(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


def cached_wheel() -> Path | None:
    wheels = sorted(cache_dir("wheels").glob(f"llama_cpp_python-{LLAMA_CPP_VERSION}-*.whl"))
    return wheels[-1] if wheels else None


def _pip(*args: str) -> None:
    result = subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", *args],
                            stdout=STDERR_FD)
    if result.returncode != 0:
        raise EfficientEQAError(f"pip {' '.join(args[:3])}... failed (see its output above)",
                                fix="check that PyPI is reachable, then retry")


def build_wheel(progress: bool = True) -> Path:
    """Build the portable llama-cpp-python wheel once into ``cache_dir("wheels")`` (4-5 minutes)."""
    missing = [tool for tool in ("cc", "c++") if shutil.which(tool) is None]
    if missing:
        raise EfficientEQAError(
            f"no cached llama.cpp wheel and no C/C++ compiler ({', '.join(missing)} not found)",
            fix="run: sudo apt-get install build-essential (or scripts/setup.sh), then retry")
    say(progress, f"building llama-cpp-python {LLAMA_CPP_VERSION} (portable, no AMX) once; "
                  "this takes 4-5 minutes on 2 cores and is cached in " + str(cache_dir("wheels")))
    env = {**os.environ, "CMAKE_ARGS": PORTABLE_CMAKE_ARGS, "FORCE_CMAKE": "1"}
    cmd = [sys.executable, "-m", "pip", "--disable-pip-version-check", "wheel", "--no-deps",
           "--no-binary", "llama-cpp-python", f"llama-cpp-python=={LLAMA_CPP_VERSION}",
           "-w", str(cache_dir("wheels"))]
    if subprocess.run(cmd, env=env, stdout=STDERR_FD).returncode != 0 or cached_wheel() is None:
        raise EfficientEQAError("building llama-cpp-python failed (see the compiler output above)",
                                fix="install build-essential, then run: efficienteqa models runtime")
    wheel = cached_wheel()
    assert wheel is not None
    return wheel


def ensure_llama_cpp(progress: bool = True) -> None:
    """Make ``llama_cpp`` and its server importable: install the cached portable wheel, building it
    first if there is none. Never installs the default build from the index (it crashes here)."""
    if not _importable("llama_cpp"):
        wheel = cached_wheel() or build_wheel(progress)
        say(progress, f"installing {wheel.name} and the server's dependencies...")
        # The wheel file itself satisfies the requirement, so pip never looks for a source build.
        _pip("install", "-q", f"{wheel}[server]")
    elif not all(_importable(m) for m in SERVER_MODULES):
        say(progress, "installing the llama.cpp server's dependencies...")
        _pip("install", "-q", *SERVER_REQUIREMENTS)
    else:
        return
    importlib.invalidate_caches()
    if not _importable("llama_cpp") or not all(_importable(m) for m in SERVER_MODULES):
        raise EfficientEQAError("llama_cpp or its server is still not importable after installing",
                                fix=f"delete the wheel in {cache_dir('wheels')}, then run: "
                                    "efficienteqa models runtime")
