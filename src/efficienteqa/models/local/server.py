"""The llama.cpp server process: started detached on 127.0.0.1 for one model, known afterwards by
its pid file (``cache_dir("server")/<model>.json``, log beside it), health-checked with
``GET /v1/models``, stopped by its process id (SIGTERM, then SIGKILL). A server started on
demand (``ensure_server``) stops by itself once no process has used it for a while
(``keeper``)."""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from dataclasses import asdict, dataclass
from pathlib import Path

from efficienteqa.cache import cache_dir
from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.local import keeper
from efficienteqa.models.local.runtime import ensure_llama_cpp
from efficienteqa.models.local.weights import DEFAULT_MODEL, LOCAL_MODELS, is_installed, model_path

DEFAULT_PORT = 8765
HOST = "127.0.0.1"


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


def lease_file(name: str) -> Path:
    """The lock file whose shared holders keep ``name``'s server up (``keeper``)."""
    return cache_dir("server") / f"{name}.lease"


# ---------------------------------------------------------------------------- processes

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


def _signal(pid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        if os.getpgid(pid) == pid:  # started in its own session: signal the whole group
            os.killpg(pid, sig)
        else:
            os.kill(pid, sig)


def _terminate(info: ServerInfo, grace_s: float) -> None:
    _signal(info.pid, signal.SIGTERM)
    _signal(info.pid, signal.SIGCONT)  # a stopped server (SIGSTOP, ^Z) acts on it, not on SIGKILL
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


# ---------------------------------------------------------------------------- network

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


# ---------------------------------------------------------------------------- life cycle

def _read_info(path: Path) -> ServerInfo | None:
    try:
        return ServerInfo(**json.loads(path.read_text()))
    except (OSError, ValueError, TypeError):
        return None


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


def status(name: str | None = None) -> ServerInfo | None:
    """The running server of ``name`` (any model when None, the default first); stale pid files
    (process gone or pid reused) are removed."""
    servers = running()
    if name is not None:
        servers = [s for s in servers if s.name == name]
    servers.sort(key=lambda s: s.name != DEFAULT_MODEL)
    return servers[0] if servers else None


def status_rows() -> list[tuple[str, str, str]]:
    """``efficienteqa models status``: per registered model, whether it is installed (its
    size) and its running server (answering or not)."""
    servers = {info.name: info for info in running()}
    rows = []
    for name, entry in LOCAL_MODELS.items():
        info = servers.get(name)
        server = "-" if info is None else (f"{info.base_url} (pid {info.pid})"
                                           + ("" if info.healthy() else " not answering"))
        rows.append((name, f"yes, {entry.size_mb} MB" if is_installed(name) else "no", server))
    return rows


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


# Waiting this long for a server to answer is said, once, on stderr (a stopped or stuck server
# otherwise costs the whole timeout in silence).
WAIT_NOTICE_S = 15.0


def _wait_healthy(info: ServerInfo, timeout_s: float, proc: subprocess.Popen | None = None,
                  notice_s: float | None = None) -> None:
    """Poll ``GET /v1/models`` until it answers; one-line errors with the log's tail otherwise.
    After ``notice_s`` (default ``WAIT_NOTICE_S``) without an answer, one line on stderr says
    which server the command waits on, and for how long at most."""
    start = time.monotonic()
    deadline = start + timeout_s
    notice_at: float | None = start + (WAIT_NOTICE_S if notice_s is None else notice_s)
    while time.monotonic() < deadline:
        if notice_at is not None and time.monotonic() >= notice_at:
            notice_at = None
            print(f"efficienteqa: waiting for the llama.cpp server for {info.name} on "
                  f"{HOST}:{info.port} (pid {info.pid}) to answer: {time.monotonic() - start:.0f} "
                  f"s so far, at most {timeout_s:.0f} s (log: {info.log})", file=sys.stderr,
                  flush=True)
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
          timeout_s: float = 180.0, idle_s: float = 0.0) -> ServerInfo:
    """Start llama.cpp's OpenAI-compatible server for ``name`` on 127.0.0.1, detached, and wait
    until ``GET /v1/models`` answers; reuse a running server of the same model (on ``port``
    when one is given). A lock file keeps concurrent callers from starting two. ``idle_s`` > 0:
    a server started here stops once unused that long (``keeper``); 0 keeps it."""
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
        if idle_s > 0:
            keeper = [sys.executable, "-m", "efficienteqa.models.local", "keep", name, str(idle_s)]
            with _log_file(f"{name}.keeper").open("ab") as out:
                subprocess.Popen(keeper, stdin=subprocess.DEVNULL, stdout=out,
                                 stderr=subprocess.STDOUT, start_new_session=True, close_fds=True)
        return info


def ensure_server(name: str = DEFAULT_MODEL) -> str:
    """The base URL (``http://127.0.0.1:PORT/v1``) of a healthy server for ``name``, starting one
    when needed: what the default back-end calls. This process holds the server's lease until
    it exits, so the server cannot stop under it; a server started here stops by itself after
    ``keeper.idle_seconds()`` unused, and says so in one line."""
    idle_s = keeper.idle_seconds()
    keeper.hold_lease(lease_file(name))
    before = status(name)
    info = serve(name, idle_s=idle_s)
    # said by the process that started it only: another command that looked at the same moment,
    # then waited for the lock, found this one's server
    if (before is None or before.pid != info.pid) and info.pid in _children:
        after = (f"stops after {idle_s / 60:g} min unused" if idle_s > 0 else
                 "keeps running")
        print(f"efficienteqa: started the local model server for {name} on {HOST}:{info.port}; "
              f"it {after} (efficienteqa models stop ends it now)", file=sys.stderr)
    return info.base_url


def keep_main(argv: list[str]) -> int:
    """``python -m efficienteqa.models.local keep MODEL IDLE_S``: the keeper process of
    MODEL's server (started by ``serve``), which stops it once idle IDLE_S seconds
    (``keeper.keep``)."""
    name, idle_s = argv[0], float(argv[1])
    info = status(name)
    if info is None:
        return 0
    started = info.pid

    def alive() -> bool:
        now = status(name)
        return now is not None and now.pid == started  # a restarted server has its own keeper

    def stop_it() -> None:
        stop(name)

    keeper.keep(lease_file(name), idle_s, alive, stop_it)
    return 0
