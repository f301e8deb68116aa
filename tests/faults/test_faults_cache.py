"""Fault trials of the response cache (docs/fault-trials.md section 5): writers killed, several writers at
once, a cache file corrupted by hand, entries of the wrong types. The bar: every episode is
answered (a broken cache costs model calls, never an episode), no traceback, and the cache a
killed writer leaves is a whole database the next writer uses."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from faults.harness import BLIND, Forked, count_lines, episode_ids, ran, trial, wait_for
from vlm_server import Options

CACHED = tuple(a for a in BLIND if a != "--backends.no-cache")  # B with its cache on

# A tight writer of the project's cache: 50 kB values, as fast as it can.
WRITER = """
import sys, time
from efficienteqa.models.base import ChatResponse
from efficienteqa.models.cache import ResponseCache
cache, tag, n = ResponseCache(sys.argv[1]), sys.argv[2], int(sys.argv[3])
text = "x" * 50_000
for i in range(n):
    cache.put(f"{tag}-{i}", ChatResponse(text=text, model="fake"))
    cache.put("hot", ChatResponse(text=tag, model="fake"))
    assert cache.get(f"{tag}-{i}").text == text and cache.get("hot") is not None
print("done", flush=True)
"""


def writer(path: Path, tag: str, n: int, env: dict[str, str]) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", WRITER, str(path), tag, str(n)], text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env)


def rows(path: Path) -> int:
    try:
        with sqlite3.connect(path, timeout=30) as db:
            return db.execute("SELECT COUNT(*) FROM responses").fetchone()[0]
    except sqlite3.Error:
        return 0


def whole_cache(path: Path) -> int:
    """The cache is a sound database whose every entry is JSON; its number of entries."""
    with sqlite3.connect(path) as db:
        assert db.execute("PRAGMA integrity_check").fetchone() == ("ok",)
        entries = [r for (r,) in db.execute("SELECT response FROM responses")]
    for entry in entries:
        json.loads(entry)
    return len(entries)


@pytest.fixture
def blind(vlm) -> tuple[str, ...]:
    return (*CACHED, "--backends.vlm", f"openai:fake@{vlm(Options()).base_url}")


@trial("5.1", "5.2")
def test_writers_killed_mid_write_leave_a_cache_the_next_ones_use(cli, vlm, env, tmp_path):
    cache = tmp_path / "cache" / "responses" / "responses.sqlite"
    cache.parent.mkdir(parents=True)
    tight = writer(cache, "a", 10_000, env)  # 5.2: a tight writer, killed
    wait_for(lambda: rows(cache) >= 20 or tight.poll() is not None)
    tight.send_signal(signal.SIGKILL)
    tight.wait(30)
    assert whole_cache(cache) >= 20  # the next writers: the command below
    # 5.1: the command killed while its episodes write the cache, then resumed
    slow = vlm(Options(hang_s=0.05))
    run = tmp_path / "run"
    args = (*CACHED, "--backends.vlm", f"openai:fake@{slow.base_url}", "--eval.limit", "12",
            "--out", str(run))
    child = Forked(env, tmp_path / "eval.log", *args)
    wait_for(lambda: count_lines(run) >= 3, child)
    child.send_signal(signal.SIGKILL)
    child.wait(30)
    killed_at = len(episode_ids(run))
    assert killed_at < 12, "the run ended before the kill"
    before = whole_cache(cache)
    said = ran(cli(*args))
    assert f"{12 - killed_at} episodes run, {killed_at} already done, 0 failed" in said
    assert sorted(set(episode_ids(run))) == sorted(episode_ids(run)) and len(episode_ids(run)) == 12
    assert whole_cache(cache) > before


@trial("5.3")
def test_several_writers_at_once_lose_nothing(cli, blind, env, tmp_path):
    cache = tmp_path / "cache" / "responses" / "responses.sqlite"
    cache.parent.mkdir(parents=True)
    writers = [writer(cache, tag, 150, env) for tag in ("a", "b")]
    run = tmp_path / "run"
    result = cli(*blind, "--eval.limit", "6", "--out", str(run))
    said = ran(result)
    assert "6 episodes run, 0 already done, 0 failed" in said
    assert "locked" not in said and "unavailable" not in said
    for w in writers:
        assert w.communicate(timeout=120)[0].strip() == "done"
    assert whole_cache(cache) >= 2 * 150 + 1 + 6


def _corrupt(path: Path, how: str) -> None:
    data = path.read_bytes()
    if how == "random":
        path.write_bytes(os.urandom(len(data)))
    elif how == "truncated":
        path.write_bytes(data[:len(data) // 3])
    elif how == "overwritten":
        middle = len(data) // 2
        path.write_bytes(data[:middle] + os.urandom(8192) + data[middle + 8192:])
    elif how == "schema":
        path.unlink()
        with sqlite3.connect(path) as db:
            db.execute("CREATE TABLE responses (key TEXT PRIMARY KEY, other TEXT)")
    elif how == "folder":
        path.unlink()
        path.mkdir()
    elif how == "empty":
        path.write_bytes(b"")


@trial("5.4")
def test_a_corrupt_cache_file_costs_model_calls_not_episodes(cli, blind, tmp_path):
    ran(cli(*blind, "--eval.limit", "2", "--out", str(tmp_path / "first")))
    cache = tmp_path / "cache" / "responses" / "responses.sqlite"
    with sqlite3.connect(cache) as db:  # the whole cache in the one file
        db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        db.execute("INSERT INTO responses VALUES ('pad', 'fake', 0, ?)", ("x" * 40_000,))
    good = cache.read_bytes()
    for how in ("random", "truncated", "overwritten", "schema", "folder", "empty"):
        for extra in cache.parent.glob(cache.name + "-*"):
            extra.unlink()
        if cache.is_dir():
            cache.rmdir()
        cache.write_bytes(good)
        _corrupt(cache, how)
        run = tmp_path / how
        said = ran(cli(*blind, "--eval.limit", "2", "--out", str(run)))
        assert "2 episodes run, 0 already done, 0 failed" in said, how
        assert len(set(episode_ids(run))) == 2, how


@trial("5.5")
def test_cache_entries_that_are_no_response_are_dropped_and_asked_again(cli, vlm, tmp_path):
    server = vlm(Options())
    blind = (*CACHED, "--backends.vlm", f"openai:fake@{server.base_url}")
    ran(cli(*blind, "--eval.limit", "5", "--out", str(tmp_path / "first")))
    cache = tmp_path / "cache" / "responses" / "responses.sqlite"
    bad = ["not json {", '{"text": "B", "model": "fake", "unknown_field": 1}',
           '{"text": "B", "model": "fake", "logprobs": [{"token": "B", "top": []}]}',
           '{"text": {"a": 1}, "model": "fake", "prompt_tokens": "many"}',
           '{"text": "B", "model": "fake", "prompt_tokens": null, "completion_tokens": null}']
    with sqlite3.connect(cache) as db:
        keys = [k for (k,) in db.execute("SELECT key FROM responses ORDER BY key")]
        assert len(keys) >= len(bad)
        for i, key in enumerate(keys):
            db.execute("UPDATE responses SET response = ? WHERE key = ?", (bad[i % len(bad)], key))
    asked = len(server.requests)
    for _ in range(2):  # and the resume of a run whose entries were bad
        run = tmp_path / "again"
        said = ran(cli(*blind, "--eval.limit", "5", "--out", str(run)))
        assert "0 failed" in said
        rows_ = [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()]
        assert [r["status"] for r in rows_] == ["done"] * 5
    assert len(server.requests) > asked  # the bad entries were asked again
    whole_cache(cache)
