"""Fault trials of run folders (docs/fault-trials.md sections 1, 2.16, N.1-N.3, N.9-N.11): runs killed,
interrupted, resumed with other settings, run into folders that cannot be written, and run folders
corrupted by hand. The stub method (tests/eval_stubs.py, no model and no houses) stands in for a
method wherever the trial is about the run folder; the runs are scaled down to what still shows
the property (a few kills of a short run, each at a moment read from episodes.jsonl)."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from clirun import Result
from faults.harness import (
    ASK,
    KEY,
    QUESTION,
    STUB,
    Forked,
    count_lines,
    episode_ids,
    one_error_line,
    ran,
    trial,
    wait_for,
)
from vlm_server import Options

Cli = Callable[..., Result]


@pytest.fixture
def server(vlm):
    """The test server that answers well (the stub method needs one: the capability probe)."""
    return vlm(Options())


@pytest.fixture
def stub(server) -> tuple[str, ...]:
    """The trials' S: the stub method on the synthetic split, its server the test server."""
    return (*STUB, "--backends.vlm", f"openai:fake@{server.base_url}")


def lines_of(run: Path) -> list[bytes]:
    return (run / "episodes.jsonl").read_bytes().splitlines()


def whole(run: Path, n: int) -> list[str]:
    """The run holds each of its ``n`` episodes exactly once, done, and its file ends whole."""
    ids = episode_ids(run)
    assert len(ids) == len(set(ids)) == n, ids
    assert (run / "episodes.jsonl").read_bytes().endswith(b"\n")
    rows = [json.loads(line) for line in lines_of(run) if line.endswith(b"}")]  # torn: skipped
    assert [r["status"] for r in rows] == ["done"] * n, [r.get("error") for r in rows]
    return ids


GARBAGE = [b"some text", b"\x00\xff\xfe\x80 binary", b"[]", b"42", b"null", b'"str"',
           b'{"no_id": 1}', b'\xef\xbb\xbf{"id": "bom"}', b"{" * 100_000, b"x" * 200_000, b"",
           b'{"id": ["a", "list"], "status": "done"}', b'{"id": {"an": "object"}, "status": "done"}',
           b'{"id": 5}', b'{"id": null}', b'{"id": "synthetic/99999/q0", "status": "done"}']


@trial("1.4", "1.9", "1.10", "1.11")
def test_torn_and_foreign_lines_are_skipped_and_the_torn_episode_runs_again(cli, stub, tmp_path):
    run = tmp_path / "run"
    ran(cli(*stub, "--eval.limit", "8", "--out", str(run)))
    kept = whole(run, 8)
    data = (run / "episodes.jsonl").read_bytes()
    last = data.splitlines()[-1]
    torn = data[:len(data) - len(last) // 2 - 1]  # the last line cut in half, no newline
    (run / "episodes.jsonl").write_bytes(torn + b"\n" + b"\n".join(GARBAGE) + b"\n")
    said = ran(cli(*stub, "--eval.limit", "8", "--out", str(run)))
    assert "1 episodes run, 7 already done, 0 failed" in said
    assert "8/8" in said and "9/8" not in said
    assert sorted(i for i in episode_ids(run) if i in kept) == sorted(kept)  # each once
    report = ran(cli("report", str(run)))
    assert "8/8" in report
    summary = json.loads((run / "summary.json").read_text())
    assert (summary["n"], summary["planned"]) == (8, 8)
    assert summary["torn"] == 1 + len(GARBAGE)  # every line that is not an episode of the run
    assert f"{summary['torn']} line(s) in episodes.jsonl were skipped" in (
        run / "report.md").read_text()


# ---------------------------------------------------------------- 1.5-1.8: run.json broken or gone

@trial("1.5", "1.6", "1.7")
def test_a_broken_run_json_is_one_line_and_keeps_the_episodes(cli, stub, tmp_path):
    run = tmp_path / "run"
    ran(cli(*stub, "--eval.limit", "2", "--out", str(run)))
    text = (run / "run.json").read_bytes()
    for name, broken in [("truncated", text[:len(text) // 2]), ("random", os.urandom(300)),
                         ("empty", b""), ("list", b"[1, 2, 3]"), ("empty-object", b"{}")]:
        copy = tmp_path / name
        shutil.copytree(run, copy)
        (copy / "run.json").write_bytes(broken)
        episodes = (copy / "episodes.jsonl").read_bytes()
        line = one_error_line(cli(*stub, "--eval.limit", "3", "--out", str(copy)))
        if name == "empty-object":
            assert f"{copy} holds a run with another method, dataset" in line
        else:
            assert f"{copy / 'run.json'} is not a run's JSON object" in line
            assert "restore it, or use another --out folder" in line
        assert (copy / "episodes.jsonl").read_bytes() == episodes, name
        assert (copy / "run.json").read_bytes() == broken, name
        if name == "list":
            report = one_error_line(cli("report", str(copy)))
            assert "run.json is not a run's JSON object" in report


@trial("1.8")
def test_episodes_without_run_json_are_adopted_by_no_configuration(cli, stub, tmp_path):
    run = tmp_path / "run"
    ran(cli(*stub, "--eval.limit", "2", "--out", str(run)))
    (run / "run.json").unlink()
    episodes = (run / "episodes.jsonl").read_bytes()
    for other in (("--backends.temperature", "1.5"), ("--eval.method", "eval_stubs:peek"), ()):
        line = one_error_line(cli(*stub, *other, "--eval.limit", "3", "--out", str(run)))
        assert f"{run} holds episodes but no run.json, so what ran them is unknown" in line
        assert (run / "episodes.jsonl").read_bytes() == episodes
        assert not (run / "run.json").exists()


# ---------------------------------------------------------------- 1.1-1.3, 1.15: kills and resumes

@trial("1.1", "1.2", "1.3", "1.15")
def test_a_run_killed_and_interrupted_resumes_with_every_episode_once(cli, stub, env, tmp_path):
    """kill -9 at a moment read from the file (with a second run into the folder tried then),
    SIGINT later, then the same command: every episode once, none torn."""
    run, n = tmp_path / "run", 40
    args = (*stub, "--eval.limit", str(n), "--out", str(run))
    slow = {"EQA_STUB_SLEEP": "0.05"}
    first = Forked(env, tmp_path / "first.log", *args, **slow)
    wait_for(lambda: count_lines(run) >= 3, first)
    second = one_error_line(cli(*args))  # 1.15: the folder is taken
    assert f"another run is writing to {run}" in second
    first.send_signal(signal.SIGKILL)
    first.wait(30)
    killed_at = len(set(episode_ids(run)))
    assert killed_at < n, "the run ended before the kill"
    interrupted = Forked(env, tmp_path / "interrupted.log", *args, **slow)
    wait_for(lambda: count_lines(run) >= killed_at + 3, interrupted)
    interrupted.send_signal(signal.SIGINT)
    interrupted.wait(30)
    said = interrupted.output()
    assert interrupted.returncode == 130 and "Traceback" not in said, said[-3000:]
    done = len(set(episode_ids(run)))
    assert killed_at + 3 <= done < n, "the run ended before the interrupt"
    assert len(episode_ids(run)) == done  # no episode written twice by the resume
    final = ran(cli(*args))
    assert f"{n - done} episodes run, {done} already done, 0 failed" in final
    whole(run, n)


# ---------------------------------------------------------------- 1.18: judge killed, judged again

@trial("1.18")
def test_a_judge_killed_mid_way_is_judged_again_once(cli, stub, vlm, env, tmp_path):
    run, n = tmp_path / "run", 12
    ran(cli(*stub, "--eval.limit", str(n), "--out", str(run)))
    before = {r["id"]: r for r in map(json.loads, lines_of(run))}
    slow = vlm(Options(hang_s=0.1))
    judge = Forked(env, tmp_path / "judge.log", "judge", str(run), "--judge", f"openai:fake@{slow.base_url}",
                  "--judge-mode", "grade")
    wait_for(lambda: count_lines(run) >= n + 2, judge)  # regraded lines appended
    judge.send_signal(signal.SIGKILL)
    judge.wait(30)
    assert n + 2 <= count_lines(run) < 2 * n, "the judge ended before the kill"
    fast = vlm(Options())
    judged = ran(cli("judge", str(run), "--judge", f"openai:fake@{fast.base_url}",
                     "--judge-mode", "grade"))
    assert f"{run}: {n} episodes graded" in judged
    rows = [json.loads(line) for line in lines_of(run)]
    assert sorted(r["id"] for r in rows) == sorted(before)  # compacted: each once, none torn
    assert all(r["judge"]["score"] is not None for r in rows)
    assert all(r["answer"] == before[r["id"]]["answer"] for r in rows)
    manifest = json.loads((run / "run.json").read_text())
    assert manifest["judge"] == f"openai:fake@{fast.base_url}" and manifest["judge_mode"] == "grade"


# ---------------------------------------------------------------- 1.12-1.14: resumed otherwise

@trial("1.12")
def test_a_resume_with_a_setting_that_changes_results_is_refused_in_one_line(cli, stub, vlm,
                                                                              tmp_path):
    run = tmp_path / "run"
    ran(cli(*stub, "--eval.limit", "3", "--out", str(run)))
    other = vlm(Options())
    refused = {"stack": [("--backends.temperature", "0.7"), ("--backends.grouping", "rules"),
                         ("--backends.vlm", f"openai:fake@{other.base_url}")],
               "config": [("--stop.z-th", "2", "--stop.gate", "none"), ("--explore.seed", "7")],
               "judge": [("--eval.judge", f"openai:fake@{other.base_url}")]}
    episodes = (run / "episodes.jsonl").read_bytes()
    for what, changes in refused.items():
        for change in changes:
            line = one_error_line(cli(*stub, *change, "--eval.limit", "4", "--out", str(run)))
            assert f"{run} holds a run with another {what}" in line, change
            assert "use a new --out folder for a new configuration" in line
            assert (run / "episodes.jsonl").read_bytes() == episodes, change
    # what changes no result: how long a call may take, how often it is tried, the key's
    # variable, the cache; a refusal of these is over-strict but allowed (one line, no loss)
    n = 3
    for change in [("--backends.timeout-s", "30", "--backends.retries", "1"),
                   ("--backends.no-cache",), ("--backends.api-key-env", "none"),
                   ("--backends.image-max-side", "256")]:
        result = cli(*stub, *change, "--eval.limit", str(n + 1), "--out", str(run))
        if change[0] == "--backends.timeout-s" or result.returncode == 0:
            ran(result)
            n += 1
        else:
            assert f"{run} holds a run with another" in one_error_line(result), change
        whole(run, n)
    assert n >= 4


@trial("1.13")
def test_a_resume_with_another_limit_or_reports_continues_the_run(cli, stub, tmp_path):
    run = tmp_path / "run"
    ran(cli(*stub, "--eval.limit", "3", "--out", str(run)))
    assert "6 episodes run, 3 already done" in ran(cli(*stub, "--eval.limit", "9", "--out", str(run)))
    assert "0 episodes run, 4 already done" in ran(cli(*stub, "--eval.limit", "4", "--out", str(run)))
    assert "0 episodes run, 9 already done" in ran(cli(*stub, "--eval.limit", "9", "--eval.reports",
                                                       "--out", str(run)))
    whole(run, 9)


@trial("1.14")
def test_a_resume_with_other_houses_or_simulator_is_refused_before_any_house(cli, stub, tmp_path,
                                                                             monkeypatch):
    """Refused before the dataset's houses are built (with --scene.assets sh3d and a dataset of
    house seeds, the furniture was converted first, 70 s and more, to refuse the folder after
    it)."""
    import efficienteqa.datasets

    run = tmp_path / "run"
    ran(cli(*stub, "--eval.limit", "3", "--out", str(run)))  # the split's assets, sh3d
    kept = whole(run, 3)

    def no_houses(*args: object, **kwargs: object) -> None:
        raise AssertionError("the dataset was built before the folder was refused")

    monkeypatch.setattr(efficienteqa.datasets, "load_dataset", no_houses)
    line = one_error_line(cli(*stub, "--scene.assets", "builtin", "--eval.limit", "5",
                              "--out", str(run)))
    assert f"{run} holds a run with another assets (assets: sh3d -> builtin)" in line
    (tmp_path / "hm3d").mkdir()
    line = one_error_line(cli(*stub, "--scene.env", "habitat",
                              "--scene.hm3d-root", str(tmp_path / "hm3d"), "--eval.limit", "5",
                              "--out", str(run)))
    assert f"{run} holds a run with another env" in line
    assert whole(run, 3) == kept


# ---------------------------------------------------------------- 1.17, 2.16: disks that refuse

@trial("1.17")
def test_a_full_disk_mid_run_is_one_line_and_the_same_command_resumes(cli, stub, tmp_path,
                                                                      monkeypatch):
    """No space left after 5 lines (a tmpfs of 48 kB, simulated: mounting one needs root): the
    6th line is written in part, as a full disk leaves it."""
    import errno

    from efficienteqa.eval import records

    run, real, written = tmp_path / "run", os.write, []

    def full(fd: int, data: bytes) -> int:
        if not os.readlink(f"/proc/self/fd/{fd}").endswith("episodes.jsonl"):
            return real(fd, data)
        written.append(data)
        if len(written) == 6:
            return real(fd, data[:len(data) // 2])  # a short write, then nothing
        if len(written) > 6:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd, data)

    monkeypatch.setattr(records.os, "write", full)
    line = one_error_line(cli(*stub, "--eval.limit", "12", "--out", str(run)))
    assert f"cannot write {run / 'episodes.jsonl'}: No space left on device" in line
    assert "the same command resumes the run" in line
    assert len(set(episode_ids(run))) == 5
    monkeypatch.undo()
    assert "7 episodes run, 5 already done, 0 failed" in ran(
        cli(*stub, "--eval.limit", "12", "--out", str(run)))
    assert len(whole(run, 12)) == 12


@trial("2.16")
def test_an_out_that_cannot_be_written_is_one_line_before_any_work(cli, stub, env, tmp_path):
    """Paths nobody can write, whoever runs the test: a file where the folder should be, a
    folder under a file, a folder where a run's file should be."""
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    vlm = stub[stub.index("--backends.vlm") + 1]
    for out in (afile, afile / "sub"):
        line = one_error_line(cli(*ASK, "--backends.vlm", vlm, "--out", str(out)))
        assert f"cannot write to {out}" in line
        line = one_error_line(cli(*stub, "--eval.limit", "2", "--out", str(out)))
        assert f"cannot write to {out}" in line
    assert afile.read_text() == "not a folder"
    run = tmp_path / "run"
    ran(cli(*stub, "--eval.limit", "2", "--out", str(run)))
    line = one_error_line(cli("report", str(run), "--out", str(afile)))
    assert f"cannot write to {afile}" in line
    for name in ("run.json", "episodes.jsonl"):
        broken = tmp_path / name.replace(".", "-")
        shutil.copytree(run, broken)
        (broken / name).unlink()
        (broken / name).mkdir()
        for args in ((*stub, "--eval.limit", "3", "--out", str(broken)), ("report", str(broken))):
            line = one_error_line(cli(*args))
            assert f"{broken / name}: Is a directory" in line, args
        assert "episodes run" not in cli(*stub, "--eval.limit", "3", "--out", str(broken)).stdout
    # the run's lock a folder (it was a traceback): one line from eval and from ask, nothing run
    locked = tmp_path / "lock-folder"
    shutil.copytree(run, locked)
    (locked / ".lock").unlink(missing_ok=True)
    (locked / ".lock").mkdir()
    before = (locked / "episodes.jsonl").read_bytes()
    line = one_error_line(cli(*stub, "--eval.limit", "3", "--out", str(locked)))
    assert f"cannot open the run's lock {locked / '.lock'}: Is a directory" in line
    assert (locked / "episodes.jsonl").read_bytes() == before
    asked = tmp_path / "ask-lock"
    (asked / ".lock").mkdir(parents=True)
    line = one_error_line(cli(*ASK, "--backends.vlm", vlm, "--out", str(asked)))
    assert "cannot open the run's lock" in line and not (asked / "episode.json").exists()


@trial("2.16")
def test_an_episodes_file_made_read_only_is_refused_before_any_episode(cli, stub, tmp_path):
    run = tmp_path / "run"
    ran(cli(*stub, "--eval.limit", "2", "--out", str(run)))
    path = run / "episodes.jsonl"
    path.chmod(0o444)
    try:
        path.open("a").close()
    except PermissionError:
        pass
    else:
        pytest.skip("this user writes to a file of mode 0o444 (root)")
    line = one_error_line(cli(*stub, "--eval.limit", "3", "--out", str(run)))
    assert f"cannot write {path}: Permission denied" in line
    path.chmod(0o644)
    whole(run, 2)


# ---------------------------------------------------------------- N.9: --out with ..

@trial("N.9")
def test_an_out_with_dot_dots_is_a_path_like_any_other(cli, stub, tmp_path, monkeypatch):
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    ran(cli(*stub, "--eval.limit", "2", "--eval.reports", "--out", "../rel/out/../out/trav_out"))
    run = tmp_path / "rel" / "out" / "trav_out"
    whole(run, 2)
    written = {p.relative_to(tmp_path).parts[:3] for p in tmp_path.rglob("*") if p.is_file()}
    assert written <= {("rel", "out", "trav_out")} | {("cache",) + p[1:] for p in written
                                                      if p[0] == "cache"}
    line = one_error_line(cli(*ASK, "--backends.vlm", stub[stub.index("--backends.vlm") + 1],
                              "--scene", "synthetic:../../x", "--out", "../ask"))
    assert "synthetic:../../x" in line
    assert not (tmp_path / "x").exists() and not (tmp_path / "ask" / "episode.json").exists()


# ---------------------------------------------------------------- N.10, N.11: two asks at once

def locked(folder: Path) -> bool:
    """Whether a command holds ``folder``'s run lock (eval's and ask's)."""
    import fcntl

    try:
        fd = os.open(folder / ".lock", os.O_RDWR)
    except FileNotFoundError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


@trial("N.10", "N.11", "R6.54")
def test_two_asks_at_once_share_the_cache_but_not_a_folder(cli, server, env, tmp_path):
    """While an ask explores, a second ask of another question into its folder is refused (it
    used to overwrite the first's episode without a word), and another writer of the response
    cache works beside it. The second ask is a child forked before the first starts here; it
    waits for the first to hold the folder (it is refused before it would render, which a
    forked child cannot)."""
    import sqlite3

    from faults.test_faults_cache import writer

    fast = ("--backends.relevancy", "overlap", "--explore.matching", "words",
            "--explore.max-steps", "1", "--backends.vlm", f"openai:fake@{server.base_url}")
    ask = [a for a in ASK if a != "--backends.no-cache"]  # the cache on: shared
    one = tmp_path / "one"
    one.mkdir()
    cache = tmp_path / "cache" / "responses" / "responses.sqlite"
    cache.parent.mkdir(parents=True)
    second = Forked(env, tmp_path / "second.log", "ask", "Where is the sofa?", *ask[2:], *fast,
                    "--out", str(one), first=lambda: wait_for(lambda: locked(one), timeout=120))
    other = writer(cache, "other", 400, env)  # N.10: another writer of the cache, meanwhile
    said = ran(cli(*ask, *fast, "--out", str(one)))
    assert f"episode: {one / 'episode.json'}" in said
    second.wait(60)
    line = one_error_line(Result(second.returncode, second.output(), ""))
    assert (f"another run is writing to {one}" in line  # while the first ran, as a rule
            or f"{one} holds the episode of another question" in line)
    line = one_error_line(cli("ask", "Where is the sofa?", *ask[2:], *fast, "--out", str(one)))
    assert f"{one} holds the episode of another question" in line
    assert json.loads((one / "episode.json").read_text())["question"] == QUESTION
    other.kill()
    other.wait()
    with sqlite3.connect(cache) as db:
        assert db.execute("PRAGMA integrity_check").fetchone() == ("ok",)
        served = db.execute("SELECT COUNT(*) FROM responses WHERE key NOT LIKE 'other-%' "
                            "AND key != 'hot'").fetchone()[0]
    assert served > 0  # the ask's own calls were written beside the other writer's


# ---------------------------------------------------------------- 1.16, N.1: Ray

def end_session(sid: int) -> None:
    """Kill what is left of the session ``sid`` (a killed Ray driver's: workers and Ray's
    agents), by their process ids, until none is left."""
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        left = []
        for stat in Path("/proc").glob("[0-9]*/stat"):
            try:
                fields = stat.read_text().rpartition(")")[2].split()
            except OSError:
                continue
            if int(fields[3]) == sid and fields[0] != "Z":  # the session, the 4th field
                left.append(int(stat.parent.name))
        for pid in left:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        if not left:
            return
        time.sleep(0.2)


@pytest.mark.slow
@trial("1.16", "N.1")
def test_ray_survives_a_killed_worker_and_a_killed_driver_resumes(cli, stub, env, tmp_path):
    """Two Ray workers; one dies mid-episode (Ray runs its episode again, N.1); then the driver
    is killed (1.16) and the same command, without Ray, finishes the run: every episode once."""
    pytest.importorskip("ray")
    import tempfile

    from efficienteqa.datasets import load_dataset

    n = 12
    ids = [q.id for q in load_dataset("synthetic", limit=n)]
    marks = tmp_path / "marks"
    marks.mkdir()
    # Ray's unix sockets need a path under 107 bytes: a short folder, not tmp_path
    ray_tmp = Path(tempfile.mkdtemp(prefix="eqa-ray-"))
    env.update(RAY_TMPDIR=str(ray_tmp), EQA_STUB_SLEEP="0.3", EQA_STUB_DIE=ids[1],
               EQA_STUB_MARKS=str(marks))
    run = tmp_path / "run"
    args = (*stub, "--eval.limit", str(n), "--eval.workers", "2", "--out", str(run))
    driver = Forked(env, tmp_path / "driver.log", *args)
    try:
        wait_for(lambda: count_lines(run) >= 3 and ids[1] in episode_ids(run), driver, timeout=120)
        driver.send_signal(signal.SIGKILL)
        driver.wait(30)
    finally:
        end_session(driver.pid)
    rows = {r["id"]: r for r in map(json.loads, lines_of(run)) if r.get("id") in ids}
    died = int((marks / ids[1].replace("/", "_")).read_text())
    assert rows[ids[1]]["status"] == "done" and rows[ids[1]]["extra"]["pid"] != died
    killed_at = len(rows)
    assert killed_at < n, "the run ended before the kill"
    for name in ("EQA_STUB_SLEEP", "EQA_STUB_DIE"):
        del env[name]
    said = ran(cli(*args[:-4], "--out", str(run)))  # the same run, in this process
    assert f"{n - killed_at} episodes run, {killed_at} already done, 0 failed" in said
    whole(run, n)
    leaks = [str(p) for p in ray_tmp.rglob("*") if p.is_file() and not p.is_symlink()
             and KEY.encode() in p.read_bytes()]
    shutil.rmtree(ray_tmp, ignore_errors=True)
    assert leaks == []


# ---------------------------------------------------------------- N.2, N.3: perception interrupted

@pytest.fixture
def builtin_houses(monkeypatch: pytest.MonkeyPatch) -> None:
    """``perception dataset`` renders the sh3d furniture, minutes to convert in a fresh cache:
    here it renders the builtin boxes, one house a shard."""
    import functools

    from efficienteqa.perception.pixels import dataset

    monkeypatch.setattr(dataset, "SHARD_HOUSES", 1)
    monkeypatch.setattr(dataset, "render_dataset",
                        functools.partial(dataset.render_dataset, assets="builtin"))


@trial("N.2", "N.3")
def test_interrupted_perception_dataset_and_train_resume_and_write_nothing_partial(
        cli, tmp_path, monkeypatch, builtin_houses):
    """SIGINT (KeyboardInterrupt, raised where the signal would land) while the second shard
    renders; a torn temporary shard, as kill -9 during a write leaves it; the same command
    renders only the missing shards. Then training interrupted at its 4th step writes no
    weights, and --resume finishes from the checkpoint."""
    from efficienteqa.perception.pixels import dataset, train

    data = tmp_path / "data"
    args = ("perception", "dataset", "--seeds", "3010-3012", "--frames-per-house", "1",
            "--workers", "1", "--out", str(data))
    real_shard, rendered = dataset._render_shard, []

    def shard(job: tuple) -> tuple[str, int]:
        if len(rendered) == 1 and interrupt:
            raise KeyboardInterrupt
        rendered.append(job[0])
        return real_shard(job)

    monkeypatch.setattr(dataset, "_render_shard", shard)
    interrupt = True
    stopped = cli(*args)
    assert stopped.returncode == 130 and "Traceback" not in stopped.said, stopped.said
    assert sorted(p.name for p in data.iterdir()) == ["houses-3010-3010.npz"]
    (data / "houses-3011-3011.tmp.npz").write_bytes(b"PK\x03\x04 torn")
    interrupt, rendered[:] = False, []
    assert "3 houses, 3 frames" in ran(cli(*args))
    assert rendered == [[3011], [3012]]  # the finished shard was kept
    assert json.loads((data / "meta.json").read_text())["houses"] == [3010, 3011, 3012]
    assert sorted(p.name for p in data.glob("*.npz")) == [
        "houses-3010-3010.npz", "houses-3011-3011.npz", "houses-3012-3012.npz"]

    weights = tmp_path / "w" / "pixels.pt"
    train_args = ("perception", "train", "--data", str(data), "--out", str(weights), "--steps",
                  "6", "--batch", "1", "--threads", "1", "--widths", "4,4,4,4,4",
                  "--checkpoint-every", "2", "--device", "cpu")
    real_losses, steps = train.losses, []

    def losses(*a: object, **k: object) -> object:
        steps.append(1)
        if len(steps) == 4 and interrupt:
            raise KeyboardInterrupt
        return real_losses(*a, **k)

    monkeypatch.setattr(train, "losses", losses)
    interrupt = True
    stopped = cli(*train_args)
    assert stopped.returncode == 130 and "Traceback" not in stopped.said, stopped.said
    assert not weights.exists() and not weights.with_suffix(".json").exists()
    assert [p.name for p in weights.parent.iterdir()] == [train.checkpoint_path(weights).name]
    interrupt = False
    said = ran(cli(*train_args, "--resume"))
    assert "resuming from" in said and "at step 2" in said
    assert weights.is_file() and weights.with_suffix(".json").is_file()
    assert json.loads(weights.with_suffix(".json").read_text())["steps_done"] == 6
