"""Fault trials of the model server's side (docs/fault-trials.md 2.17-2.21, 4.1-4.4, 4.7, N.12-N.14):
dead, refusing, misbehaving and hung servers, a missing key, and secrets (the key, a password in
the server's URL, a key echoed in an error, Ray's logs and sockets); and two of the client's
cache (5.5: entries of another type; N.6: a cache folder that cannot be made). Each runs
``efficienteqa`` against the test server (tests/vlm_server.py, its ``Options.misbehave`` modes)
on loopback, with the cheapest command that shows the trial: most fail at the capability probe,
before any episode. In this process, but for the one Ray run."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from faults.harness import ASK, BLIND, KEY, PASSWORD, episode_ids, files_holding, one_error_line, ran, trial
from vlm_server import Options, VLMServer

DEAD = "openai:fake@http://127.0.0.1:9/v1"  # the discard port: nothing listens
KEYED = ("--backends.api-key-env", "OPENAI_API_KEY")  # the key is sent to the test server
FAST = ("--backends.retries", "0", "--backends.timeout-s", "2")
# ask that finishes, with the cache: relevancy and the target's matching by words, not by
# MiniLM (whose import alone takes seconds)
ASKED = (*[a for a in ASK if a != "--backends.no-cache"], "--backends.relevancy", "overlap",
         "--explore.matching", "words")


def vlm_flag(server: VLMServer) -> tuple[str, str]:
    return "--backends.vlm", f"openai:fake@{server.base_url}"


def blind(tmp_path: Path, *args: str, name: str = "run") -> tuple[str, ...]:
    """B with one episode into ``tmp_path / name``."""
    return (*BLIND, "--eval.limit", "1", *args, "--out", str(tmp_path / name))


def rows(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()]


def no_episode(run: Path) -> bool:
    """The command stopped before any episode (at the probe)."""
    jsonl = run / "episodes.jsonl"
    return not jsonl.exists() or jsonl.read_text() == ""


# ---------------------------------------------------------------- 2.17: a dead server, a refused key

@trial("2.17")
def test_a_dead_server_or_a_refused_key_is_one_line_before_any_episode(cli, vlm, tmp_path):
    dead = one_error_line(cli(*blind(tmp_path, "--backends.vlm", DEAD, *FAST)))
    assert "model server at http://127.0.0.1:9/v1/chat/completions unreachable after 1 tries" \
        in dead
    assert no_episode(tmp_path / "run")
    asked = one_error_line(cli(*ASK, "--backends.vlm", DEAD, *FAST, "--out", str(tmp_path / "a")))
    assert "unreachable" in asked and not (tmp_path / "a" / "episode.json").exists()
    judge = one_error_line(cli(*blind(tmp_path, *vlm_flag(vlm()), "--eval.judge", DEAD, *FAST,
                                      name="judged")))
    assert f"the server of --eval.judge {DEAD}" in judge  # named as the judge, not as the VLM
    assert no_episode(tmp_path / "judged")
    refusing = vlm(Options(misbehave="e401"))
    refused = one_error_line(cli(*blind(tmp_path, *vlm_flag(refusing), *KEYED, name="r401")))
    assert "rejected the request: HTTP 401" in refused
    assert "check the API key in $OPENAI_API_KEY" in refused
    keyless = one_error_line(cli(*blind(tmp_path, *vlm_flag(refusing), name="r401b")))
    assert "no key was sent" in keyless and "--backends.api-key-env NAME" in keyless
    assert no_episode(tmp_path / "r401") and no_episode(tmp_path / "r401b")


# ---------------------------------------------------------------- 2.18, 2.19, N.12, N.13: misbehaving servers

AT_THE_PROBE = {  # mode -> what the one line says
    "html": "still answered HTTP 502 after 1 tries: <html><head><title>502 Bad Gateway",
    "html200": "sent a reply that is not JSON: <!DOCTYPE html>",  # N.12
    "garbage": r"sent a reply that is not UTF-8 (byte 0): b'\xfe\xff",  # 2.19
    "html200json": "sent a reply that is not JSON: <!DOCTYPE html>",  # N.13
    "empty200": "sent an empty reply",  # N.13
    "e500": "still answered HTTP 500 after 1 tries: Internal server error",
    "e429": "still answered HTTP 429 after 1 tries: Rate limit reached",
    "listbody": "[1, 2, 3]",
    "truncated": "RemoteProtocolError",
}
NORMAL = ("nullcontent", "badlogprobs", "underflow", "lengthcut", "ctrl", "huge", "xss")


@trial("2.18", "2.19", "N.12", "N.13")
@pytest.mark.parametrize("mode", sorted(AT_THE_PROBE))
def test_a_server_that_misbehaves_at_the_probe_is_one_line_before_any_episode(cli, vlm, tmp_path,
                                                                             mode):
    server = vlm(Options(misbehave=mode))
    line = one_error_line(cli(*blind(tmp_path, *vlm_flag(server), *FAST)))
    assert f"model server at {server.base_url}/chat/completions " in line
    assert AT_THE_PROBE[mode] in line
    assert no_episode(tmp_path / "run")


@trial("2.18", "2.19", "N.13")
@pytest.mark.parametrize("mode", ["e500", "garbage", "html200json", "nochoices", "wrongshape",
                                  "truncated"])
def test_a_server_that_misbehaves_after_the_probe_fails_the_episode_which_resumes(cli, vlm,
                                                                                 tmp_path, mode):
    """Past the probe (its two requests answered) a bad reply fails its episode, written as
    failed with the one line; the run ends with the count; a re-run once the server is well
    runs it again, once."""
    server = vlm(Options(misbehave=mode, misbehave_after=2))
    assert "1 episode(s) failed" in one_error_line(cli(*blind(tmp_path, *vlm_flag(server),
                                                              *FAST)))
    [row] = rows(tmp_path / "run")
    assert row["status"] == "failed"
    assert f"model server at {server.base_url}/chat/completions " in row["error"]
    server.options = Options()
    assert "1 episodes run, 0 already done, 0 failed" in ran(cli(*blind(tmp_path, *vlm_flag(server),
                                                                    *FAST)))
    assert rows(tmp_path / "run")[-1]["status"] == "done"
    assert len(set(episode_ids(tmp_path / "run"))) == 1


@trial("2.18")
@pytest.mark.parametrize("mode", NORMAL)
def test_a_server_with_odd_replies_still_gives_a_normal_run(cli, vlm, tmp_path, mode):
    server = vlm(Options(misbehave=mode))
    assert "1 episodes run, 0 already done, 0 failed" in ran(cli(*blind(tmp_path, *vlm_flag(server),
                                                                    *FAST)))
    [row] = rows(tmp_path / "run")
    assert row["status"] == "done"
    assert len(json.dumps(row)) < 20_000  # a huge reply is not kept whole
    assert server.requests[-1].status == 200 and len(server.requests) >= 3


# ---------------------------------------------------------------- 2.20: a server that never answers

@trial("2.20")
def test_a_server_that_never_answers_costs_the_timeout_not_the_run(cli, vlm, tmp_path):
    hung = vlm(Options(hang_s=8))
    start = time.monotonic()
    line = one_error_line(cli(*blind(tmp_path, *vlm_flag(hung), "--backends.timeout-s", "0.5",
                                     "--backends.retries", "0")))
    assert time.monotonic() - start < 6  # not the 8 s the server waits
    assert "did not answer within 0.5 s (1 tries)" in line and "raise --backends.timeout-s" in line
    assert no_episode(tmp_path / "run")
    later = vlm(Options(hang_s=8, hang_after=2))  # "hangafter": the probe is answered
    line = one_error_line(cli(*blind(tmp_path, *vlm_flag(later), "--backends.timeout-s", "0.5",
                                     "--backends.retries", "1", name="later")))
    assert "1 episode(s) failed" in line
    [row] = rows(tmp_path / "later")
    assert row["status"] == "failed" and "did not answer within 0.5 s (2 tries)" in row["error"]


# ---------------------------------------------------------------- 2.21: no OPENAI_API_KEY

@trial("2.21")
def test_a_missing_key_is_one_line_naming_the_variable(cli, env, vlm, tmp_path):
    """eval with the key's model as the VLM and as the judge, and judge (ask fails at the same
    client as on a dead server, 2.17)."""
    env.pop("OPENAI_API_KEY")
    server, keyed = vlm(Options()), vlm(Options())
    missing = "error: environment variable OPENAI_API_KEY is not set"
    for i, args in enumerate([blind(tmp_path, "--backends.vlm", "openai:gpt-4o", name="b"),
                              blind(tmp_path, *vlm_flag(server), "--eval.judge", "openai:gpt-4o",
                                    name="j"),
                              blind(tmp_path, *vlm_flag(keyed), *KEYED, name="k")]):
        line = one_error_line(cli(*args))
        assert line.startswith(missing) and "export OPENAI_API_KEY=" in line, (i, line)
    other = one_error_line(cli(*blind(tmp_path, *vlm_flag(keyed), "--backends.api-key-env",
                                      "NOPE_NOT_SET", name="n")))
    assert "environment variable NOPE_NOT_SET is not set" in other
    assert keyed.requests == []  # nothing was sent without its key
    assert all(no_episode(tmp_path / n) for n in "bjkn")
    done = tmp_path / "done"
    ran(cli(*blind(tmp_path, *vlm_flag(server), name="done")))  # a run to judge again
    line = one_error_line(cli("judge", str(done), "--judge", "openai:gpt-4o"))
    assert line.startswith(missing)


# ---------------------------------------------------------------- 4.1, 4.2: the key in outputs

@trial("4.1")
def test_the_key_reaches_the_server_and_no_file_or_output(cli, vlm, tmp_path, caplog):
    """Every command of a keyed run (eval with the cache and the episode reports, its resume,
    ask, judge, report) with the key exported and sent: the server got it, no file of the runs
    or the cache holds it, and nothing printed or logged does."""
    server = vlm(Options(api_key=KEY))  # any other key is refused
    judge = vlm(Options())  # judge sends no key to a server not OpenAI's
    cached = [a for a in BLIND if a != "--backends.no-cache"]
    run = str(tmp_path / "run")
    args = (*cached, "--eval.limit", "1", "--eval.reports", *vlm_flag(server), *KEYED, "--out", run)
    said = [ran(cli(*args)), ran(cli(*args)),
            ran(cli(*ASKED, *vlm_flag(server), *KEYED, "--out", str(tmp_path / "ask"))),
            ran(cli("judge", run, "--judge", f"openai:fake@{judge.base_url}")),
            ran(cli("report", run, "--out", str(tmp_path / "report"))), caplog.text]
    assert "0 episodes run, 1 already done" in said[1]
    assert {r.authorization for r in server.requests} == {f"Bearer {KEY}"}
    assert {r.kind for r in server.requests} >= {"probe", "answer", "answer-short"}
    assert judge.requests[-1].kind == "judge"
    written = [p for p in tmp_path.rglob("*") if p.is_file()]
    names = {p.name for p in written}
    assert {"run.json", "episodes.jsonl", "episode.json", "report.html",
            "responses.sqlite"} <= names, names
    assert list((tmp_path / "cache" / "probes").glob("*.json"))
    assert files_holding(tmp_path, KEY) == []
    assert KEY not in "".join(said)


@trial("4.2")
def test_a_server_that_echoes_the_authorization_header_shows_no_key(cli, vlm, tmp_path):
    """eval, at the probe (ask's and judge's errors are the same client's)."""
    e401, e500 = vlm(Options(misbehave="echokey401")), vlm(Options(misbehave="echokey500"))
    lines = [one_error_line(cli(*blind(tmp_path, *vlm_flag(e401), *KEYED, *FAST))),
             one_error_line(cli(*blind(tmp_path, *vlm_flag(e500), *KEYED, *FAST, name="r500")))]
    assert {r.authorization for r in e401.requests + e500.requests} == {f"Bearer {KEY}"}
    for line in lines:  # the key was sent, and echoed
        assert "Authorization: Bearer ***" in line and KEY not in line
    assert no_episode(tmp_path / "run") and no_episode(tmp_path / "r500")


# ---------------------------------------------------------------- 4.4: a password in the server's URL

@trial("4.4")
def test_a_password_in_the_servers_url_is_never_written_or_printed(cli, vlm, tmp_path):
    """The password of ``http://user:PASSWORD@host/v1`` was stored verbatim in run.json,
    episodes.jsonl, the episode records and the kept probe, and printed in error lines. It is
    written and printed as ``***``; the user and host stay, so the run still names its server
    and resumes with the command that made it."""
    server = vlm(Options())
    url = server.base_url.replace("http://", f"http://alice:{PASSWORD}@")
    shown = server.base_url.replace("http://", "http://alice:***@")
    spec = f"openai:fake@{url}"
    cached = [a for a in BLIND if a != "--backends.no-cache"]
    args = (*cached, "--eval.limit", "1", "--backends.vlm", spec,
            "--out", str(tmp_path / "run"))
    runs = [cli(*args), cli(*args),  # the second resumes: nothing to run
            cli(*ASKED, "--backends.vlm", spec, "--out", str(tmp_path / "ask")),
            cli("judge", str(tmp_path / "run"), "--judge", spec)]
    for run in runs:
        ran(run)
    assert "0 episodes run, 1 already done" in runs[1].stdout
    assert [r["status"] for r in rows(tmp_path / "run")] == ["done"]
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["stack"]["vlm"] == f"openai:fake@{shown}"
    assert (tmp_path / "ask" / "episode.json").is_file()
    assert list((tmp_path / "cache" / "probes").glob("*.json"))
    assert (tmp_path / "cache" / "responses" / "responses.sqlite").is_file()
    dead = cli(*blind(tmp_path, "--backends.vlm", f"openai:fake@http://alice:{PASSWORD}@127.0.0.1:9/v1",
                      *FAST, name="dead"))
    assert "model server at http://alice:***@127.0.0.1:9/v1/chat/completions unreachable" in \
        one_error_line(dead)
    said = "".join(r.stdout + r.stderr for r in [*runs, dead])
    assert PASSWORD not in said and f"vlm_backend={record['stack']['vlm']}" in said
    assert files_holding(tmp_path, PASSWORD) == []
    assert server.requests and not server.image_errors


# ---------------------------------------------------------------- 5.5: cache entries of other types

@trial("5.5")
def test_cache_entries_of_another_type_are_dropped_and_asked_again(cli, vlm, tmp_path, caplog):
    server = vlm(Options())
    cached = [a for a in BLIND if a != "--backends.no-cache"]
    first = cli(*cached, "--eval.limit", "2", *vlm_flag(server), "--out", str(tmp_path / "first"))
    ran(first)
    cache = tmp_path / "cache" / "responses" / "responses.sqlite"
    with sqlite3.connect(cache) as db:  # trial 5.5's nulltokens and wrongtypes
        db.execute("UPDATE responses SET response = CASE WHEN rowid % 2 THEN "
                   """'{"text": "B", "model": "fake", "prompt_tokens": null}' ELSE """
                   """'{"text": {"a": 1}, "model": "fake", "prompt_tokens": "many"}' END""")
    asked = len(server.requests)
    again = cli(*cached, "--eval.limit", "2", *vlm_flag(server), "--out", str(tmp_path / "again"))
    ran(again)
    assert "2 episodes run, 0 already done, 0 failed" in again.stdout
    said = again.stderr + caplog.text  # a warning: on stderr, or in this process, logged
    assert "dropped an unreadable response-cache entry (TypeError: " in said
    assert str(cache) in said
    assert len(server.requests) > asked  # the calls were made again


# ---------------------------------------------------------------- N.6: a cache folder that cannot be written

@trial("N.6")
def test_a_cache_folder_that_cannot_be_written_costs_the_cache_not_the_run(cli, env, vlm,
                                                                          tmp_path, caplog):
    """A cache folder under a file: a path nobody can make a folder at, like a read-only file
    system (also checked by hand on a read-only tmpfs, and under a folder of mode 0o555)."""
    (tmp_path / "afile").write_text("")
    unwritable = tmp_path / "afile" / "cache"
    env["EFFICIENTEQA_CACHE"] = str(unwritable)
    cached = [a for a in BLIND if a != "--backends.no-cache"]
    for i, cache_flag in enumerate(["--backends.cache", "--backends.no-cache"]):
        # a server each: the warnings are said once per server and process
        caplog.clear()
        run = cli(*cached, cache_flag, "--eval.limit", "1", *vlm_flag(vlm()),
                  "--out", str(tmp_path / f"run{i}"))
        assert "1 episodes run, 0 already done, 0 failed" in ran(run)
        said = run.stderr.splitlines() + caplog.messages  # warnings: logged in this process
        assert len([s for s in said if s.startswith("cannot keep the probe")]) == 1, said
        assert str(unwritable / "probes") in "".join(said)
        off = [s for s in said if s.startswith("response cache off")]
        assert len(off) == (cache_flag == "--backends.cache"), said
    ran(cli(*ASKED, *vlm_flag(vlm()), "--out", str(tmp_path / "ask")))
    assert (tmp_path / "ask" / "episode.json").is_file()
    # what cannot do without the cache says so in one line, before any work
    line = one_error_line(cli(*blind(tmp_path, *vlm_flag(vlm()), "--eval.dataset", "synthetic:0",
                                     name="h")))
    assert f"cannot create the cache folder {unwritable}" in line
    assert "set EFFICIENTEQA_CACHE to a writable folder" in line
    assert not unwritable.exists()


# ---------------------------------------------------------------- 4.3, 4.7, N.14: a local Ray run

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


@trial("4.3", "4.7", "N.14")
@pytest.mark.slow
def test_a_local_ray_run_listens_on_loopback_and_writes_no_key(env, vlm, tmp_path):
    """Two Ray workers, the key in a variable whose name does not look secret
    (--backends.api-key-env EFFICIENTEQA_AUTH): it was written to Ray's world-readable
    runtime_env_agent.log (N.14), and Ray's GCS, raylet and workers listened on all interfaces
    (4.7). Now every socket of the run's processes is on loopback, the workers still send the
    key (the server refuses any other), and no file of Ray's session, the run or the cache
    holds it (4.3)."""
    import importlib.util
    import shutil
    import tempfile

    if importlib.util.find_spec("ray") is None:
        pytest.skip("Ray is not installed")
    server = vlm(Options(api_key=KEY, hang_s=0.5, hang_after=2))  # the episodes' calls wait
    temp = Path(tempfile.mkdtemp(prefix="eqa-ray-"))  # short: Ray's unix sockets' paths
    env.pop("OPENAI_API_KEY")
    token = "tok-efficienteqa-faults-5a0e44c1"  # a secret-named variable beside it
    env.update(EFFICIENTEQA_AUTH=KEY, EFFICIENTEQA_HUB_TOKEN=token, RAY_TMPDIR=str(temp))
    args = [*BLIND, "--eval.limit", "4", "--eval.workers", "2", "--backends.api-key-env",
            "EFFICIENTEQA_AUTH", *vlm_flag(server), "--out", str(tmp_path / "run")]
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
        assert "Traceback" not in said and KEY not in said
        assert {"gcs_server", "raylet"} <= {name for name, _ in sockets}, sockets
        assert [s for s in sockets if not is_loopback(s[1])] == []
        assert len(server.requests) >= 6 and {r.status for r in server.requests} == {200}
        assert any("runtime_env" in p.name for p in temp.rglob("*"))  # Ray did log here
        assert files_holding(temp, KEY) == [] and files_holding(temp, token) == []
        assert sorted(episode_ids(tmp_path / "run")) == sorted(set(episode_ids(tmp_path / "run")))
    finally:
        shutil.rmtree(temp, ignore_errors=True)
