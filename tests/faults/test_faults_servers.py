"""Fault trials of the model server's side (the shared FAULT-TRIALS list; issue "No traceback
anywhere"), run as a user runs them: the ``efficienteqa`` command in a subprocess against the
test server (tests/vlm_server.py) on loopback, its cache in a folder of the test's own. The bar:
one clear error line or a normal run, no traceback, no secret in any file written."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from vlm_server import BROKEN, Options, servers

# `efficienteqa eval` of the trials' short name B: the blind method on the fixed synthetic
# split, answers grouped by rules, two episodes.
BLIND = ["eval", "--eval.method", "blind", "--eval.dataset", "synthetic", "--backends.grouping",
         "rules", "--backends.no-cache", "--eval.limit", "2"]


@pytest.fixture
def vlm():
    with servers() as start:
        yield start


@pytest.fixture
def env(tmp_path) -> dict[str, str]:
    """The command's environment: a cache of the test's own, no OpenAI key."""
    out = {k: v for k, v in os.environ.items() if k != "OPENAI_API_KEY"}
    return {**out, "EFFICIENTEQA_CACHE": str(tmp_path / "cache"), "COLUMNS": "300"}


def cli(*args: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "efficienteqa.cli", *args], capture_output=True,
                          text=True, env=env, timeout=300)


def one_error_line(result: subprocess.CompletedProcess[str]) -> str:
    """The command failed with exit 1 and one ``error:`` line, and no traceback."""
    assert "Traceback" not in result.stdout + result.stderr, result.stderr[-3000:]
    assert result.returncode == 1, result.stdout + result.stderr
    errors = [line for line in result.stdout.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.stdout
    return errors[0]


# ---------------------------------------------------------------- 2.19, N.13: 200s that are no JSON

@pytest.mark.parametrize("broken", sorted(BROKEN))
def test_eval_against_a_200_that_is_not_json_fails_in_one_line(vlm, env, tmp_path, broken):
    server = vlm(Options(broken=broken))
    result = cli(*BLIND, "--backends.vlm", f"openai:fake@{server.base_url}",
                 "--out", str(tmp_path / "run"), env=env)
    line = one_error_line(result)
    assert f"model server at {server.base_url}/chat/completions sent" in line
    assert not (tmp_path / "run" / "episodes.jsonl").exists()  # the probe, before any episode


def test_ask_and_judge_against_a_200_that_is_not_json_fail_in_one_line(vlm, env, tmp_path):
    html = vlm(Options(broken="html200json"))
    result = cli("ask", "What is on the desk in the office?", "--scene", "synthetic:0",
                 "--scene.assets", "builtin", "--explore.max-steps", "2", "--backends.no-cache",
                 "--backends.vlm", f"openai:fake@{html.base_url}", "--out", str(tmp_path / "ask"),
                 env=env)
    assert "sent a reply that is not JSON: <!DOCTYPE html>" in one_error_line(result)
    ok = vlm(Options())
    run = tmp_path / "run"
    done = cli(*BLIND, "--backends.vlm", f"openai:fake@{ok.base_url}", "--out", str(run), env=env)
    assert done.returncode == 0, done.stdout + done.stderr
    garbage = vlm(Options(broken="garbage"))
    result = cli("judge", str(run), "--judge", f"openai:fake@{garbage.base_url}", env=env)
    assert "sent a reply that is not UTF-8 (byte 0)" in one_error_line(result)


def test_a_server_that_breaks_after_the_probe_fails_the_episodes_not_the_run(vlm, env, tmp_path):
    """Past the probe, such a reply is a failed call: its episode fails with the one line, the
    run goes on, and ends with the count of failed episodes (they resume on a re-run)."""
    server = vlm(Options(broken="empty200", broken_after=2))
    run = tmp_path / "run"
    result = cli(*BLIND, "--backends.vlm", f"openai:fake@{server.base_url}", "--out", str(run),
                 env=env)
    assert "2 episode(s) failed" in one_error_line(result)
    rows = [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()]
    assert [r["status"] for r in rows] == ["failed", "failed"]
    assert all("sent an empty reply" in r["error"] for r in rows)


def test_the_test_server_answers_a_normal_blind_run(vlm, env, tmp_path):
    server = vlm(Options())
    result = cli(*BLIND, "--backends.vlm", f"openai:fake@{server.base_url}",
                 "--out", str(tmp_path / "run"), env=env)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "2 episodes run" in result.stdout
    assert Path(tmp_path / "run" / "episodes.jsonl").read_text().count("\n") == 2


# ---------------------------------------------------------------- 5.5: cache entries of other types

def test_cache_entries_of_another_type_are_dropped_and_asked_again(vlm, env, tmp_path):
    import sqlite3

    server = vlm(Options())
    cached = [a for a in BLIND if a != "--backends.no-cache"]
    vlm_flag = ["--backends.vlm", f"openai:fake@{server.base_url}"]
    first = cli(*cached, *vlm_flag, "--out", str(tmp_path / "first"), env=env)
    assert first.returncode == 0, first.stdout + first.stderr
    cache = tmp_path / "cache" / "responses" / "responses.sqlite"
    with sqlite3.connect(cache) as db:  # trial 5.5's nulltokens and wrongtypes
        db.execute("UPDATE responses SET response = CASE WHEN rowid % 2 THEN "
                   """'{"text": "B", "model": "fake", "prompt_tokens": null}' ELSE """
                   """'{"text": {"a": 1}, "model": "fake", "prompt_tokens": "many"}' END""")
    asked = len(server.requests)
    again = cli(*cached, *vlm_flag, "--out", str(tmp_path / "again"), env=env)
    assert again.returncode == 0 and "Traceback" not in again.stderr, again.stdout + again.stderr
    assert "2 episodes run, 0 already done, 0 failed" in again.stdout
    assert "dropped an unreadable response-cache entry (TypeError: " in again.stderr
    assert str(cache) in again.stderr
    assert len(server.requests) > asked  # the calls were made again


# ---------------------------------------------------------------- N.6: a cache folder that cannot be written

@pytest.fixture(params=["chmod", "file"])
def unwritable_cache(request, tmp_path) -> Path:
    """A cache folder that cannot be made: under a folder of mode 0o555 (root ignores that
    mode, so that case is skipped as root), or under a file (a path nobody can make a folder
    at, like a read-only file system; also checked by hand on a read-only tmpfs)."""
    if request.param == "chmod":
        if os.geteuid() == 0:
            pytest.skip("root writes into a folder of mode 0o555")
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o555)
        request.addfinalizer(lambda: locked.chmod(0o755))
        return locked / "cache"
    (tmp_path / "afile").write_text("")
    return tmp_path / "afile" / "cache"


def test_a_cache_folder_that_cannot_be_written_costs_the_cache_not_the_run(vlm, env, tmp_path,
                                                                          unwritable_cache):
    env["EFFICIENTEQA_CACHE"] = str(unwritable_cache)
    vlm_flag = ["--backends.vlm", f"openai:fake@{vlm(Options()).base_url}"]
    for i, cache_flag in enumerate(["--backends.cache", "--backends.no-cache"]):
        run = cli(*[a for a in BLIND if a != "--backends.no-cache"], cache_flag, *vlm_flag,
                  "--out", str(tmp_path / f"run{i}"), env=env)
        assert run.returncode == 0 and "Traceback" not in run.stderr, run.stdout + run.stderr
        assert "2 episodes run, 0 already done, 0 failed" in run.stdout
        said = run.stderr.splitlines()
        assert len([s for s in said if s.startswith("cannot keep the probe")]) == 1, said
        assert str(unwritable_cache / "probes") in run.stderr
        off = [s for s in said if s.startswith("response cache off")]
        assert len(off) == (cache_flag == "--backends.cache"), said
    asked = cli("ask", "What is on the desk in the office?", "--scene", "synthetic:0",
                "--scene.assets", "builtin", "--explore.max-steps", "2", *vlm_flag,
                "--out", str(tmp_path / "ask"), env=env)
    assert asked.returncode == 0 and "Traceback" not in asked.stderr, asked.stdout + asked.stderr
    assert (tmp_path / "ask" / "episode.json").is_file()
    # what cannot do without the cache says so in one line, before any work
    houses = cli(*BLIND, *vlm_flag, "--eval.dataset", "synthetic:0", "--out", str(tmp_path / "h"),
                 env=env)
    line = one_error_line(houses)
    assert f"cannot create the cache folder {unwritable_cache}" in line
    assert "set EFFICIENTEQA_CACHE to a writable folder" in line
    assert not unwritable_cache.exists()


# ---------------------------------------------------------------- 4.4: a password in the server's URL

PASSWORD = "URLSECRETPW-4f9c1e"


def files_holding(folder: Path, secret: str) -> list[str]:
    return [str(p) for p in folder.rglob("*")
            if p.is_file() and not p.is_symlink() and secret.encode() in p.read_bytes()]


def test_a_password_in_the_servers_url_is_never_written_or_printed(vlm, env, tmp_path):
    """Fault trial 4.4: the password of ``http://user:PASSWORD@host/v1`` was stored verbatim in
    run.json, episodes.jsonl, the episode records and the kept probe, and printed in error
    lines. It is written and printed as ``***``; the user and host stay, so the run still names
    its server and resumes with the command that made it."""
    server = vlm(Options())
    url = server.base_url.replace("http://", f"http://alice:{PASSWORD}@")
    shown = server.base_url.replace("http://", "http://alice:***@")
    spec = f"openai:fake@{url}"
    agent = ["eval", "--eval.method", "efficienteqa", "--eval.dataset", "synthetic:0",
             "--eval.limit", "1", "--scene.assets", "builtin", "--explore.max-steps", "2",
             "--eval.reports", "--backends.vlm", spec, "--eval.judge", spec,
             "--out", str(tmp_path / "agent")]
    runs = [cli(*agent, env=env), cli(*agent, env=env),  # the second resumes: nothing to run
            cli(*[a for a in BLIND if a != "--backends.no-cache"], "--backends.vlm", spec,
                "--out", str(tmp_path / "blind"), env=env),
            cli("ask", "What is on the desk in the office?", "--scene", "synthetic:0",
                "--scene.assets", "builtin", "--explore.max-steps", "2", "--backends.vlm", spec,
                "--out", str(tmp_path / "ask"), env=env),
            cli("judge", str(tmp_path / "agent"), "--judge", spec, env=env)]
    for run in runs:
        assert run.returncode == 0, run.stdout + run.stderr
    assert "0 episodes run, 1 already done" in runs[1].stdout
    assert [r["status"] for r in map(json.loads, (tmp_path / "agent" / "episodes.jsonl")
                                     .read_text().splitlines())] == ["done"]
    record = json.loads((tmp_path / "agent" / "run.json").read_text())
    assert record["stack"]["vlm"] == f"openai:fake@{shown}" and record["judge"] == record["stack"]["vlm"]
    assert list((tmp_path / "agent" / "episodes").rglob("episode.json"))
    assert list((tmp_path / "cache" / "probes").glob("*.json"))
    assert (tmp_path / "cache" / "responses" / "responses.sqlite").is_file()
    dead = cli(*BLIND, "--backends.vlm", "openai:fake@http://alice:" + PASSWORD + "@127.0.0.1:9/v1",
               "--backends.retries", "0", "--out", str(tmp_path / "dead"), env=env)
    assert "model server at http://alice:***@127.0.0.1:9/v1/chat/completions unreachable" in \
        one_error_line(dead)
    said = "".join(r.stdout + r.stderr for r in [*runs, dead])
    assert PASSWORD not in said and f"vlm_backend={record['stack']['vlm']}" in said
    assert files_holding(tmp_path, PASSWORD) == []
    assert server.requests and not server.image_errors


# ---------------------------------------------------------------- 4.7, N.14: a local Ray run

def descendants(pid: int) -> set[int]:
    """``pid`` and every process under it (Ray's GCS, raylet, agents and workers)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except (OSError, ValueError):
            continue
        parent = int(stat.rsplit(")", 1)[1].split()[1])
        children.setdefault(parent, []).append(int(entry.name))
    found, todo = set(), [pid]
    while todo:
        found.add(todo[-1])
        todo += [c for c in children.get(todo.pop(), []) if c not in found]
    return found


def listening(pids: set[int]) -> set[tuple[str, str]]:
    """(process name, address) of each TCP socket the processes listen on, from /proc/net."""
    import ipaddress

    addresses = {}
    for table in ("tcp", "tcp6"):
        for row in Path(f"/proc/net/{table}").read_text().splitlines()[1:]:
            field = row.split()
            if field[3] != "0A":  # LISTEN
                continue
            raw = bytes.fromhex(field[1].split(":")[0])  # 32-bit words in host (little) order
            ip = ipaddress.ip_address(b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4)))
            addresses[field[9]] = str(ip)
    found = set()
    for pid in pids:
        try:
            name = Path(f"/proc/{pid}/comm").read_text().strip()
            links = [os.readlink(f"/proc/{pid}/fd/{fd}") for fd in os.listdir(f"/proc/{pid}/fd")]
        except OSError:  # the process ended
            continue
        found |= {(name, addresses[link[8:-1]]) for link in links
                  if link.startswith("socket:[") and link[8:-1] in addresses}
    return found


def is_loopback(address: str) -> bool:
    import ipaddress

    ip = ipaddress.ip_address(address)
    return ip.is_loopback or bool(getattr(ip, "ipv4_mapped", None) and ip.ipv4_mapped.is_loopback)


@pytest.mark.slow
def test_a_local_ray_run_listens_on_loopback_and_writes_no_key(vlm, env, tmp_path):
    """Fault trials 4.7 and N.14 with two Ray workers: Ray's GCS, raylet and workers listened on
    all interfaces, and the key of --backends.api-key-env EFFICIENTEQA_AUTH (a name that does not
    look secret) was written to Ray's world-readable runtime_env_agent.log. Now every socket of
    the run's processes is on loopback, the workers still send the key (the server refuses any
    other), and no file of Ray's session, the run or the cache holds it."""
    import importlib.util
    import shutil
    import tempfile
    import time

    if importlib.util.find_spec("ray") is None:
        pytest.skip("Ray is not installed")
    key = "sk-FAKE-rel5-ZZ9Q8W7-netfaults"
    server = vlm(Options(api_key=key, hang_s=0.5, hang_after=2))  # the episodes' calls wait
    temp = Path(tempfile.mkdtemp(prefix="eqa-ray-"))  # short: Ray's unix sockets' paths
    env.update(EFFICIENTEQA_AUTH=key, RAY_TMPDIR=str(temp))
    env.pop("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", None)
    args = [*BLIND, "--eval.limit", "4", "--eval.workers", "2", "--backends.api-key-env",
            "EFFICIENTEQA_AUTH", "--backends.vlm", f"openai:fake@{server.base_url}",
            "--out", str(tmp_path / "run")]
    try:
        with (tmp_path / "stdout").open("w") as out, (tmp_path / "stderr").open("w") as err:
            run = subprocess.Popen([sys.executable, "-m", "efficienteqa.cli", *args], stdout=out,
                                   stderr=err, env=env, text=True)
            sockets: set[tuple[str, str]] = set()
            while run.poll() is None:
                sockets |= listening(descendants(run.pid))
                time.sleep(0.1)
        said = (tmp_path / "stdout").read_text() + (tmp_path / "stderr").read_text()
        assert run.returncode == 0 and "4 episodes run" in said, said
        assert {"gcs_server", "raylet"} <= {name for name, _ in sockets}, sockets
        assert [s for s in sockets if not is_loopback(s[1])] == []
        assert len(server.requests) >= 6 and {r.status for r in server.requests} == {200}
        assert any("runtime_env" in p.name for p in temp.rglob("*"))  # Ray did log here
        assert files_holding(temp, key) == [] and files_holding(tmp_path, key) == []
    finally:
        shutil.rmtree(temp, ignore_errors=True)
