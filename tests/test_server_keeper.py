"""The on-demand model server stops by itself once nobody uses it (models/local/keeper.py), and
never under a process that uses it."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import pytest

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.local import keeper, server


def test_the_idle_time_is_read_from_the_environment(monkeypatch):
    monkeypatch.delenv(keeper.IDLE_ENV, raising=False)
    assert keeper.idle_seconds() == keeper.IDLE_S == 300
    monkeypatch.setenv(keeper.IDLE_ENV, "0")
    assert keeper.idle_seconds() == 0  # keep servers
    monkeypatch.setenv(keeper.IDLE_ENV, "45")
    assert keeper.idle_seconds() == 45
    for bad in ("soon", "-1", "inf", "nan"):
        monkeypatch.setenv(keeper.IDLE_ENV, bad)
        with pytest.raises(EfficientEQAError, match="not a number of seconds"):
            keeper.idle_seconds()


def _watch(lease, idle_s, proc):
    """Run ``keeper.keep`` on a real process in a thread; returns (thread, result box)."""
    box: dict[str, object] = {}

    def run() -> None:
        box["stopped"] = keeper.keep(lease, idle_s, lambda: proc.poll() is None, proc.terminate,
                                     poll_s=0.05)
        box["at"] = time.monotonic()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, box


def test_a_server_in_use_stays_and_an_idle_one_stops(tmp_path):
    lease = tmp_path / "m.lease"
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        keeper.hold_lease(lease)  # a command is using the server
        thread, box = _watch(lease, 0.3, proc)
        time.sleep(1.0)
        assert proc.poll() is None and "stopped" not in box  # in use: never stopped
        released = time.monotonic()
        keeper.release_lease(lease)  # the command exits
        thread.join(timeout=5)
        assert box["stopped"] is True and proc.wait(timeout=5) is not None
        assert 0.3 <= box["at"] - released < 2.0  # after the idle time, not before
    finally:
        keeper.release_lease(lease)
        proc.kill()


def test_the_keeper_leaves_when_the_server_is_gone(tmp_path):
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    thread, box = _watch(tmp_path / "m.lease", 60, proc)
    thread.join(timeout=5)
    assert box["stopped"] is False


def test_a_command_arriving_while_the_keeper_stops_waits_then_finds_no_server(tmp_path):
    lease = tmp_path / "m.lease"
    order: list[str] = []

    def slow_stop() -> None:
        order.append("stopping")
        time.sleep(0.5)
        order.append("stopped")

    alive = iter([True] * 1000)
    thread = threading.Thread(target=keeper.keep, args=(lease, 0.0, lambda: next(alive),
                                                          slow_stop, 0.01), daemon=True)
    thread.start()
    while not order:
        time.sleep(0.01)
    keeper.hold_lease(lease)  # blocks until the stop is done
    order.append("leased")
    keeper.release_lease(lease)
    thread.join(timeout=5)
    assert order == ["stopping", "stopped", "leased"]


def test_ensure_server_holds_the_lease_before_looking_and_says_when_it_started_one(
        monkeypatch, tmp_path, capsys):
    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(tmp_path))
    monkeypatch.setenv(keeper.IDLE_ENV, "120")
    info = server.ServerInfo(name="m", pid=4242, port=8765, model="m.gguf", started=0.0, log="l")
    looked: list[bool] = []

    def status(name=None):
        looked.append(str(server.lease_file("m")) in keeper._held)
        return None

    monkeypatch.setattr(server, "status", status)
    monkeypatch.setattr(server, "serve", lambda name, idle_s: info)
    try:
        assert server.ensure_server("m") == info.base_url  # another process's server: no word
        assert capsys.readouterr().err == ""
        monkeypatch.setitem(server._children, info.pid, None)  # started by this process
        assert server.ensure_server("m") == info.base_url
    finally:
        keeper.release_lease(server.lease_file("m"))
    assert looked == [True, True]
    line = capsys.readouterr().err.strip()
    assert "started the local model server for m" in line and "stops after 2 min unused" in line
    assert len(line.splitlines()) == 1
