"""Fault trials of the output surfaces and their settings (FAULT-TRIALS-2, R6.22-R6.28, R6.32-R6.34,
R6.46, R6.51-R6.54, R6.59, R6.60): ``--record`` and ``--rerun`` onto targets that cannot take
them and onto a disk that fills mid-episode, ``--config`` files, ``--scene.noise``, Ctrl-C in
``eval`` and ``ask``, two runs into one folder, and the map's size.

A full disk is a real one where this process may mount a 1 MB tmpfs (root), and is otherwise
made by writers that fail as a full disk makes them (``full_disk``): the MCAP file's stream
with ENOSPC after 60 kB, and rerun's flush as rerun reports its file writer ended."""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from clirun import Result
from faults.harness import (
    ASK,
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
DEAD = "openai:fake@http://127.0.0.1:9/v1"  # refused before any call: never reached
LOCAL = ("--backends.relevancy", "overlap", "--explore.matching", "words")  # no torch


@pytest.fixture
def no_scene(monkeypatch: pytest.MonkeyPatch) -> None:
    """A command that builds a house fails the test: its error was due before the slow work."""
    from efficienteqa import scenes

    def built(cls: object, seed: int, *args: object) -> None:
        pytest.fail(f"house {seed} was built before the bad input was refused")

    monkeypatch.setattr(scenes.SyntheticEnv, "from_seed", classmethod(built))


def refused(cli: Cli, out: Path, *extra: str) -> str:
    """``ask`` into ``out`` with ``extra``, refused in one line before the scene; nothing
    written to ``out`` but its lock."""
    line = one_error_line(cli(*ASK, "--backends.vlm", DEAD, "--out", str(out), *extra))
    left = sorted(p.name for p in out.iterdir()) if out.exists() else []
    assert left in ([], [".lock"]), left
    return line


def asking(server: object, out: Path, *extra: str, steps: int = 1) -> tuple[str, ...]:
    """``A`` with ``steps`` steps against the test server, into ``out``."""
    return (*ASK, "--explore.max-steps", str(steps), "--backends.vlm",
            f"openai:fake@{server.base_url}", *LOCAL, "--out", str(out), *extra)  # type: ignore[attr-defined]


@pytest.fixture
def unwritable(tmp_path: Path) -> Iterator[list[tuple[str, Path]]]:
    """Folders that cannot take a new file, with the reason each gives, of every kind this
    process can make: a read-only tmpfs and an immutable folder (root, who passes every
    permission check), or a folder without write permission (anyone else)."""
    made: list[tuple[str, Path]] = []
    with contextlib.ExitStack() as stack:
        if os.geteuid() == 0:
            ro = tmp_path / "ro"
            ro.mkdir()
            if subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(ro)],
                              capture_output=True).returncode == 0:
                stack.callback(subprocess.run, ["umount", "-l", str(ro)], check=False)
                made.append(("Read-only file system", ro))
            fixed = tmp_path / "immutable"
            fixed.mkdir()
            if subprocess.run(["chattr", "+i", str(fixed)], capture_output=True).returncode == 0:
                stack.callback(subprocess.run, ["chattr", "-i", str(fixed)], check=False)
                made.append(("Operation not permitted", fixed))
        else:
            shut = tmp_path / "shut"
            shut.mkdir()
            shut.chmod(0o555)
            stack.callback(shut.chmod, 0o755)
            made.append(("Permission denied", shut))
        yield made


# ---------------------------------------------------------------- R6.22-R6.24, R6.26, R6.27: refused

@trial("R6.22", "R6.24")
def test_record_onto_what_exists_is_refused_before_the_scene(cli, tmp_path, no_scene):
    """An existing file, a non-empty folder, a path under a file (held), an empty folder named
    .mcap and /dev/null (R6.24: tracebacks once the scene was built) are each one line."""
    out = tmp_path / "out"
    (tmp_path / "walk.mcap").write_bytes(b"x")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "a").write_text("a")
    (tmp_path / "empty.mcap").mkdir()
    cases = [(tmp_path / "walk.mcap", "walk.mcap exists; a recording is never written over"),
             (tmp_path / "full", "full exists; a recording is never written over"),
             (tmp_path / "walk.mcap" / "x.mcap", "walk.mcap: "),
             (tmp_path / "empty.mcap", "empty.mcap is a folder, and an MCAP recording is a file"),
             (Path("/dev/null"), "/dev/null exists; a recording is never written over")]
    for target, said in cases:
        line = refused(cli, out, "--record", str(target))
        assert said in line and ("cannot write to" in line or "exists" in line
                                 or "is a folder" in line), line
    assert (tmp_path / "walk.mcap").read_bytes() == b"x" and list((tmp_path / "empty.mcap").iterdir()) == []


@trial("R6.23", "R6.26")
def test_record_and_rerun_into_unwritable_folders_are_refused_before_the_scene(
        cli, tmp_path, no_scene, unwritable):
    """A read-only file system and an immutable folder (as root), or a folder without write
    permission: --record (MCAP and folder) used to pass the check and end in a traceback once
    the scene was built, since root passes ``os.access``; --rerun is refused too (held), as are
    a .mcap name and a folder named .rrd."""
    pytest.importorskip("rerun")
    out = tmp_path / "out"
    (tmp_path / "x.rrd").mkdir()
    for target, said in [("e.mcap", "--rerun takes a .rrd file or live, not 'e.mcap'"),
                         (str(tmp_path / "x.rrd"), "x.rrd is a folder, and a rerun recording is a file")]:
        assert said in refused(cli, out, "--rerun", target)
    if not unwritable:
        pytest.skip("no unwritable folder can be made here")
    for why, folder in unwritable:
        for target in (folder / "walk.mcap", folder / "walk", folder / "sub" / "walk.mcap"):
            line = refused(cli, out, "--record", str(target))
            assert f"cannot write to {folder}" in line and why in line, line
        line = refused(cli, out, "--rerun", str(folder / "e.rrd"))
        assert f"cannot write the rerun recording {folder / 'e.rrd'}: {why}" in line, line
        assert list(folder.iterdir()) == []


@trial("R6.26")
def test_rerun_live_without_a_screen_is_one_line(cli, env, tmp_path, no_scene, monkeypatch):
    pytest.importorskip("rerun")
    from efficienteqa.report import rerun_target

    monkeypatch.setattr(rerun_target, "viewer_executable", lambda: "/usr/bin/rerun")
    for name in ("DISPLAY", "WAYLAND_DISPLAY"):
        env.pop(name, None)
    line = refused(cli, tmp_path / "out", "--rerun", "live")
    assert "no rerun viewer can start here: no screen" in line


@trial("R6.27")
def test_rerun_onto_an_existing_file_is_refused_unless_overwrite(cli, tmp_path, no_scene):
    """An existing .rrd used to be written over without a word (--record refuses the same):
    refused in one line before the scene, and --overwrite named as the way to replace it (as
    test_a_full_disk_costs_the_recordings_not_the_episode does)."""
    pytest.importorskip("rerun")
    rrd = tmp_path / "e.rrd"
    rrd.write_bytes(b"old")
    line = refused(cli, tmp_path / "out", "--rerun", str(rrd))
    assert f"{rrd} exists; a rerun recording is not written over" in line
    assert "--overwrite" in line and rrd.read_bytes() == b"old"
    (tmp_path / "link.rrd").symlink_to(tmp_path / "nowhere.rrd")  # a dangling link: exists too
    assert "link.rrd exists" in refused(cli, tmp_path / "out", "--rerun",
                                        str(tmp_path / "link.rrd"))


# ---------------------------------------------------------------- R6.25, R6.28: a full disk

class FullDisk(io.FileIO):
    """A file on a disk with ``room`` bytes left: a write beyond fails with ENOSPC."""

    room = 60_000

    def write(self, data: object) -> int:
        size = len(memoryview(data))  # type: ignore[arg-type]
        if self.tell() + size > self.room:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self.name)
        return super().write(data)  # type: ignore[arg-type]


@pytest.fixture
def full_disk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A folder on a disk that fills mid-episode: a 1 MB tmpfs filled but for 300 kB where
    this process may mount one (root; the first frames do not fit); else a folder whose MCAP
    files fill after 60 kB and whose rerun flush reports rerun's writer thread dead, as it does
    once a full disk ended it (checked on the tmpfs)."""
    small = tmp_path / "small"
    small.mkdir()
    if os.geteuid() == 0 and subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(small)],
            capture_output=True).returncode == 0:
        try:
            filler = small / "filler"
            with contextlib.suppress(OSError), open(filler, "wb") as f:
                f.write(b"\0" * (1 << 20))
            os.truncate(filler, filler.stat().st_size - 300_000)
            yield small
        finally:
            subprocess.run(["umount", "-l", str(small)], check=False)
        return
    import rerun

    from efficienteqa.envs.recorded import write

    def opened(path: object, mode: str = "r", *args: object, **kwargs: object) -> object:
        assert mode == "wb", mode
        return io.BufferedWriter(FullDisk(str(path), "wb"))

    def flush(self: object, *, timeout_sec: float = 0) -> None:
        raise RuntimeError("File-writer thread shut down prematurely")

    monkeypatch.setattr(write, "open", opened, raising=False)
    monkeypatch.setattr(rerun.RecordingStream, "flush", flush)
    yield small


@trial("R6.25", "R6.28", "R6.27")
def test_a_full_disk_costs_the_recordings_not_the_episode(cli, vlm, tmp_path, full_disk):
    """A disk that fills mid-episode used to fail the episode (--record: ENOSPC, also from
    close) or the command after it (--rerun: the flush's RuntimeError, no report.html): now
    the episode runs to its end (exit 0, episode.json done, report.html written) and each
    recording cut short is one warning line. The rerun file is an existing one, replaced as
    --overwrite asks (R6.27)."""
    pytest.importorskip("rerun")
    out, walk, rrd = tmp_path / "out", full_disk / "walk.mcap", full_disk / "e.rrd"
    rrd.write_bytes(b"old")
    said = ran(cli(*asking(vlm(Options()), out, "--record", str(walk), "--rerun", str(rrd),
                           "--overwrite", steps=2)))
    warnings = [line for line in said.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 2, said
    assert warnings[0].startswith(f"warning: the recording {walk} stopped after ")
    assert "No space left on device (mcap recover may rescue the frames written); the episode " \
           "went on without it" in warnings[0]
    # rerun's reason: "File-writer thread shut down prematurely", as a rule (the flush began
    # long after the writer ended); "Flush timed out" where the two met
    assert warnings[1].startswith(f"warning: the rerun recording {rrd} is incomplete: ")
    assert warnings[1].endswith("(rerun's own message says why); the episode went on without it")
    assert f"rerun:   {rrd}" not in said and "recorded: " not in said
    record = json.loads((out / "episode.json").read_text())
    assert record["answer"] and record["steps"] == 2 and "error" not in record
    assert (out / "report.html").stat().st_size > 0
    assert 0 < walk.stat().st_size <= 300_000 and rrd.read_bytes()[:3] != b"old"


@trial("R6.28")
def test_a_rerun_writer_that_hangs_is_given_up_and_the_episode_goes_on(tmp_path, monkeypatch):
    """Once a full disk ended rerun's file writer, rerun may wait for it forever (seen on the
    tmpfs: in ``save`` as the recording begins, and in ``disconnect`` after a flush that timed
    out): each such call is given up after ``WATCH_S``, as a warning, and the log does nothing
    more."""
    pytest.importorskip("rerun")
    import threading

    import rerun

    from efficienteqa.report import rerun_log

    release = threading.Event()
    monkeypatch.setattr(rerun_log, "WATCH_S", 0.2)
    monkeypatch.setattr(rerun.RecordingStream, "save", lambda *a, **k: release.wait())
    try:
        log = rerun_log.RerunLog(tmp_path / "e.rrd", QUESTION)
        assert log.closed and log.error == (
            f"the rerun recording {tmp_path / 'e.rrd'} is incomplete: rerun's writer did not "
            "start within 0.2 s (rerun's own message says why); the episode went on without it")
        log(object(), object(), None)  # type: ignore[arg-type]  # a step: nothing, no error
        log.close()
        monkeypatch.undo()
        monkeypatch.setattr(rerun_log, "WATCH_S", 0.2)
        monkeypatch.setattr(rerun_log, "FLUSH_S", 0.1)
        log = rerun_log.RerunLog(tmp_path / "f.rrd", QUESTION)
        monkeypatch.setattr(rerun.RecordingStream, "disconnect", lambda *a: release.wait())
        log.close()  # the flush is fine, the disconnect hangs
        assert log.closed and log.error is not None and "did not close within 0.2 s" in log.error
    finally:
        release.set()


# ---------------------------------------------------------------- R6.32-R6.34: --config files

CONFIGS = [  # R6.32
    (b"this is not toml = = =", "is not valid TOML"),
    (b"[nosuch]\nx = 1\n", "unknown option 'nosuch' in CFG"),
    (b"[stop]\nz_tj = 2\n", "unknown option 'stop.z_tj' in CFG (did you mean 'stop.z_th'?)"),
    (b'[stop]\nz_th = "abc"\n', "stop.z_th in CFG must be a number, not 'abc'"),
    (b"[stop]\nz_th = nan\n", "z_th must be a finite number, got nan"),
    (b"[stop]\nz_th = 1e400\n", "z_th must be a finite number, got inf"),
    (b"[stop]\nz_th = {a = 1}\n", "stop.z_th in CFG must be a number"),
    (b"[scene]\nhm3d_root = 5\n", "scene.hm3d_root in CFG must be a path (a string), not 5"),
    (b"\x00\xff\xfe binary \x80\x81", "cannot read the configuration CFG: 'utf-8' codec"),
    # R6.33: a base names a preset, so a file cannot be its own (or any file's) base
    (b'base = "nosuch"\n', "unknown preset 'nosuch'"),
    (b'base = "../../../etc/passwd"\n', "unknown preset '../../../etc/passwd'"),
    (b'base = ["paper"]\n', "base in CFG must be a preset's name, not ['paper']"),
    (b'base = "cfg/self"\n', "unknown preset 'cfg/self'"),
    # R6.34: a section given a value was an unknown option "(did you mean 'top_k'?)"
    (b"stop = 3\n", "stop in CFG is a section, so it must be a table, not 3 (write [stop] and "
                    "name = value lines under it"),
    (b'[explore]\nsfe = "x"\n', "explore.sfe in CFG is a section, so it must be a table"),
]


@trial("R6.32", "R6.33", "R6.34")
def test_bad_config_files_are_one_line_each(cli, tmp_path):
    cfg = tmp_path / "cfg"
    cfg.mkdir()
    (cfg / "self.toml").write_text('base = "cfg/self"\n')
    for i, (text, said) in enumerate(CONFIGS):
        path = cfg / f"c{i}.toml"
        path.write_bytes(text)
        line = one_error_line(cli("config", "--config", str(path)))
        assert said.replace("CFG", str(path)) in line, (text, line)
        assert "top_k" not in line, line
    line = one_error_line(cli("config", "--config", str(cfg / "self.toml")))
    assert "unknown preset 'cfg/self'" in line


# ---------------------------------------------------------------- R6.46: noise profiles

@trial("R6.46")
def test_noise_profiles_that_do_not_apply_are_one_line(cli, vlm, tmp_path, no_scene):
    out = tmp_path / "out"
    for profile in ("bogus", ""):
        line = refused(cli, out, "--scene.noise", profile)
        assert "noise must be one of none, robot" in line and f"not {profile!r}" in line
    walk = tmp_path / "walk"
    walk.mkdir()
    (walk / "poses.jsonl").write_text("")
    for scene in (f"recorded:{walk}", "ros2"):
        line = one_error_line(cli("ask", QUESTION, "--scene", scene, "--scene.noise", "robot",
                                  "--backends.vlm", DEAD, "--out", str(out)))
        assert f"noise profile 'robot' is for the synthetic houses, not '{scene}'" in line
    run = tmp_path / "run"
    stub = (*STUB, "--backends.vlm", f"openai:fake@{vlm(Options()).base_url}", "--eval.limit",
            "2", "--out", str(run))
    ran(cli(*stub, "--scene.noise", "robot-depth"))
    rows = run.joinpath("episodes.jsonl").read_bytes()
    line = one_error_line(cli(*stub, "--scene.noise", "robot"))
    assert f"{run} holds a run with" in line and "noise" in line
    assert run.joinpath("episodes.jsonl").read_bytes() == rows


# ---------------------------------------------------------------- R6.51-R6.54: Ctrl-C, two runs

@pytest.fixture
def stub(vlm) -> tuple[str, ...]:
    return (*STUB, "--backends.vlm", f"openai:fake@{vlm(Options()).base_url}")


@trial("R6.51")
def test_an_interrupted_eval_says_so_and_the_same_command_resumes(cli, stub, env, tmp_path):
    """SIGINT mid-run: exit 130 and one line that says it was interrupted, what is done and
    that the same command resumes (Typer used to end it silently); then it does."""
    run, n = tmp_path / "run", 12
    args = (*stub, "--eval.limit", str(n), "--out", str(run))
    first = Forked(env, tmp_path / "first.log", *args, EQA_STUB_SLEEP="0.05")
    wait_for(lambda: count_lines(run) >= 2, first)
    first.send_signal(signal.SIGINT)
    first.wait(30)
    said = first.output()
    assert first.returncode == 130 and "Traceback" not in said, said[-3000:]
    done = len(set(episode_ids(run)))
    assert 2 <= done < n, "the run ended before the interrupt"
    lines = [line for line in said.splitlines() if "interrupted" in line]
    assert lines == [f"interrupted: {done} of {n} episodes are done in {run / 'episodes.jsonl'}; "
                     "the same command resumes the others"], said[-3000:]
    assert f"{n - done} episodes run, {done} already done, 0 failed" in ran(cli(*args))


@trial("R6.51")
def test_any_other_command_interrupted_says_so(cli, tmp_path, monkeypatch):
    """Ctrl-C in a command that says nothing more of its own (here ``report``): one line,
    exit 130, no traceback (Typer ended it silently)."""
    from efficienteqa.eval import tables

    def reading(*args: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(tables, "read_summaries", reading)
    result = cli("report", str(tmp_path))
    assert result.returncode == 130 and "Traceback" not in result.stdout + result.stderr
    assert result.stdout.strip().splitlines() == ["interrupted"]


@trial("R6.53")
def test_two_evals_into_one_folder_at_the_same_instant(stub, env, tmp_path):
    """Started together: one runs, the other is refused in one line; each episode once."""
    run, n = tmp_path / "run", 6
    args = (*stub, "--eval.limit", str(n), "--out", str(run))
    at = time.time() + 0.3  # both forked by then

    def together() -> None:
        time.sleep(max(0.0, at - time.time()))

    both = [Forked(env, tmp_path / f"{i}.log", *args, first=together, EQA_STUB_SLEEP="0.1")
            for i in range(2)]
    codes = sorted(p.wait(60) for p in both)
    assert codes == [0, 1], [p.output()[-2000:] for p in both]
    loser = next(p for p in both if p.returncode == 1)
    line = one_error_line(Result(1, loser.output(), ""))
    assert f"another run is writing to {run}" in line
    ids = episode_ids(run)
    assert len(ids) == len(set(ids)) == n


@trial("R6.52")
def test_an_interrupted_ask_keeps_its_partial_episode_and_says_so(vlm, env, tmp_path):
    """Ctrl-C (a real SIGINT to a real process: ask renders) after the first step of an ask
    that records its walk: exit 130, one line naming what was kept and how to ask again;
    episode.json holds the steps and the model calls paid for (none was written: _ask caught
    Exception, not KeyboardInterrupt), and the walk replays. (A rerun log is closed whole by
    the same path as a failed episode's: test_rerun_log.)"""
    server = vlm(Options(hang_s=0.3, hang_after=2))  # the probes fast, each step's call slow
    out, walk = tmp_path / "out", tmp_path / "walk"
    args = asking(server, out, "--record", str(walk), "--backends.explore-scorer", "vlm",
                  steps=6)
    proc = subprocess.Popen([sys.executable, "-m", "efficienteqa.cli", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 120
        poses = walk / "poses.jsonl"
        while not (poses.exists() and poses.read_bytes().count(b"\n") >= 1):
            assert proc.poll() is None, proc.communicate()[0][-3000:]
            assert time.monotonic() < deadline, "no step in 120 s"
            time.sleep(0.02)
        time.sleep(0.1)  # into the second step's call to the model
        proc.send_signal(signal.SIGINT)
        said = proc.communicate(timeout=60)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130 and "Traceback" not in said, said[-3000:]
    record = json.loads((out / "episode.json").read_text())
    steps = record["steps"]
    assert record["status"] == "interrupted" and record["error"] == "interrupted (Ctrl-C)"
    assert 1 <= steps < 6 and len(record["per_step"]) == steps
    assert record["model"]["calls"] >= steps and len(record["model"]["exchanges"]) >= steps
    lines = [line for line in said.splitlines() if line.startswith("interrupted")]
    assert lines == [f"interrupted at step {steps}: the episode so far (its steps and model "
                     f"calls) is in {out / 'episode.json'}, its frames in {walk}; the same "
                     "command asks again, with another --record path"], said[-3000:]
    from efficienteqa.envs.recorded import open_recording

    replay = open_recording(str(walk))
    assert replay.length >= steps
    replay.close()


@trial("R6.52")
def test_an_ask_interrupted_before_exploring_says_so(cli, vlm, tmp_path, monkeypatch):
    """Ctrl-C while the scene opens: nothing explored, so no episode; exit 130, one line."""
    from efficienteqa import scenes

    def opening(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(scenes, "open_scene", opening)
    result = cli(*asking(vlm(Options()), tmp_path / "out"))
    assert result.returncode == 130 and "Traceback" not in result.stdout + result.stderr
    assert result.stdout.strip().splitlines()[-1] == (
        "interrupted before exploring began; the same command asks again")
    assert not (tmp_path / "out" / "episode.json").exists()


# ---------------------------------------------------------------- R6.59, R6.60: the map's size

@trial("R6.59", "R6.60")
def test_map_sizes_out_of_bounds_are_one_line_before_any_allocation(cli, tmp_path, no_scene):
    """0, -5, nan (held) and 500, 2000, 100000 m, inf (R6.60: MemoryError after gigabytes): one
    line, the large ones with the estimate and the bound."""
    out = tmp_path / "out"
    for size in ("0", "-5", "nan"):
        line = refused(cli, out, "--explore.map-size-m", size)
        assert "map_size_m must be at least 4, not" in line
    for size, need in (("500", "about 13 GiB"), ("2000", "about 206 GiB"),
                       ("100000", "about 515,021 GiB"), ("inf", "unbounded memory")):
        line = refused(cli, out, "--explore.map-size-m", size)
        assert (f"map_size_m {size} would need {need} for the map, beyond its bound of 2 GiB "
                "(a side of at most 197 m, 98.5 m from the start each way") in line, line
    config = tmp_path / "big.toml"
    config.write_text("[explore]\nmap_size_m = 500.0\n")
    assert "would need about 13 GiB" in one_error_line(cli("config", "--config", str(config)))
    assert "map_size_m = 197.0" in ran(cli("config", "--explore.map-size-m", "197"))


def test_the_map_estimate_counts_what_the_map_allocates():
    """``map_bytes``'s volume part is the TSDF volume's arrays exactly, so the bound follows a
    change of layers or types; the whole estimate is above what the volume alone takes."""
    from efficienteqa.agent import map_around
    from efficienteqa.mapping import extent

    for size in (4.0, 12.3):
        mapper = map_around((1.23, -4.5), size)
        v = mapper.volume
        n = v.spec.shape[0] * v.spec.shape[1]
        assert v.spec.shape[2] == extent.MAP_LAYERS
        assert v.tsdf.nbytes + v.weight.nbytes + v.explored.nbytes == \
            n * extent.MAP_LAYERS * extent.BYTES_PER_VOXEL
        assert extent.map_bytes(size) == n * (extent.MAP_LAYERS * extent.BYTES_PER_VOXEL
                                              + extent.BYTES_PER_COLUMN)
    assert extent.map_bytes(extent.MAP_SIZE_M) < 100e6  # the default: under 100 MB
    assert extent.map_bytes(extent.max_map_size_m()) <= extent.MAX_MAP_BYTES
    assert extent.map_bytes(extent.max_map_size_m() + 1) > extent.MAX_MAP_BYTES


@trial("R6.59")
def test_a_map_over_the_scene_box_on_a_walk_is_one_line(cli, vlm, tmp_path):
    walk = tmp_path / "walk"
    make_walk(walk)
    line = one_error_line(cli("ask", QUESTION, "--scene", f"recorded:{walk}", "--backends.vlm",
                              f"openai:fake@{vlm(Options()).base_url}", *LOCAL,
                              "--explore.map-extent", "scene", "--out", str(tmp_path / "out")))
    assert "explore.map-extent scene maps a simulated scene's box" in line


def make_walk(path: Path) -> None:
    """A folder walk of two frames of house 0 (small frames)."""
    from efficienteqa.envs.recorded.write import WalkRecorder
    from efficienteqa.envs.synthetic.env import SyntheticEnv
    from efficienteqa.envs.synthetic.generate import generate_house
    from efficienteqa.envs.synthetic.primitives import builtin_catalog
    from efficienteqa.geometry import CameraSpec, Pose2D

    catalog = builtin_catalog()
    env = SyntheticEnv(generate_house(0, catalog, "builtin"), catalog,
                       camera=CameraSpec().scaled(160, 120))
    try:
        s = env.start
        with WalkRecorder(path, labels=env.scene_labels()) as recorder:
            for k in range(2):
                recorder.add(env.observe(Pose2D(s.x, s.y, s.yaw + k)))
    finally:
        env.close()
