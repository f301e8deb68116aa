"""Fault trials R6.35-R6.45, R6.47-R6.50, R6.55-R6.58 and R6.61 (FAULT-TRIALS-2): model replies
of any size or shape (the sighting call, the question's reading, the judge in each mode), the
judge's cache, capabilities files, secrets (``efficienteqa config``, a password URL from
``--config``, the API key), question files, and the on-demand local model server.

One rule for model replies: a reply of any size or shape is a recorded problem and "no
sighting" or "no grade", in bounded time (``vc.json_reply.json_reply``: no number that is not
finite, bounded depth, values and length; ``sightings.MAX_ENTRIES``; ASCII marks). One rule
for question files: a line that cannot be run is one line naming the file and the line, before
any episode. Most trials run ``efficienteqa`` in this process against the test server
(tests/vlm_server.py, its ``misbehave`` modes); the parser's bounds and the waits of a hung
server are tested on their units, where the command adds nothing but time."""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from pathlib import Path

import pytest

from faults.harness import (
    BLIND,
    KEY,
    PASSWORD,
    STUB,
    files_holding,
    one_error_line,
    ran,
    trial,
)
from vlm_server import Options, VLMServer

KEYED = ("--backends.api-key-env", "OPENAI_API_KEY")
FAST = ("--backends.retries", "0", "--backends.timeout-s", "2")
WORDS = ("--backends.relevancy", "overlap", "--explore.matching", "words", "--backends.no-cache")
# the trials' sighting episode, on the smallest budget that makes the sighting call
SIGHT = ("ask", "What colour is the bed?", "--scene", "synthetic:3", "--scene.assets", "builtin",
         "--explore.max-steps", "2", "--backends.sightings", "model", *WORDS, *KEYED)


@pytest.fixture(autouse=True)
def quick_houses(monkeypatch: pytest.MonkeyPatch) -> None:
    """Houses opened without their questions' oracle step counts (about 100 frames rendered,
    most of an ask's time here, and nothing these trials read)."""
    from efficienteqa import scenes

    monkeypatch.setattr(scenes, "annotate", lambda env, questions: questions)


def fake(server: VLMServer, model: str = "fake") -> tuple[str, str]:
    return "--backends.vlm", f"openai:{model}@{server.base_url}"


def rows(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()]


def sighting_problems(folder: Path) -> list[str]:
    record = json.loads((folder / "episode.json").read_text())
    return [p for step in record["per_step"]
            for p in (*step["relevancy_problems"], *step["explore_problems"])
            if p.startswith("sightings: ")]


# ---------------------------------------------------------------- R6.39-R6.42: sighting replies

SIGHTINGS = {  # mode -> the problem each of its replies is
    "sightnan": "a JSON number that is not finite (NaN) in the sighting reply",
    "sightinf": "a JSON number that is not finite (Infinity) in the sighting reply",
    "sightdeep": "a reply of 200009 characters (over 100000) in the sighting reply",
    "sighthuge": "characters (over 100000) in the sighting reply '{\"room\": \"bedroom\"",
}


@trial("R6.40", "R6.41", "R6.42")
@pytest.mark.parametrize("mode", sorted(SIGHTINGS))
def test_a_sighting_reply_of_any_shape_is_a_problem_and_no_sighting(cli, vlm, tmp_path, mode):
    """NaN gave ValueError from ``sightings._region``, Infinity OverflowError from
    ``box_mask``, 200,000 brackets RecursionError from the reply parser, and 100,000
    things held a step for minutes. Each reply is now a problem on the step's record (the deep
    one and the huge one are refused by their length before they are parsed)."""
    server = vlm(Options(misbehave=mode))
    start = time.monotonic()
    said = ran(cli(*SIGHT, *fake(server), "--out", str(tmp_path / "g")))
    assert time.monotonic() - start < 20  # bounded: the huge reply held a step for minutes
    assert "answer:" in said
    problems = sighting_problems(tmp_path / "g")
    calls = server.kinds().count("sightings")
    assert calls >= 1 and len(problems) == calls, problems
    assert all(SIGHTINGS[mode] in p and p.endswith(": no sighting") for p in problems), problems


@trial("R6.40")
def test_a_non_finite_box_over_images_is_a_problem_too(cli, vlm, tmp_path):
    """The same reply to the sighting call over the RGB frame (boxes, not item numbers: the
    OverflowError was ``box_mask``'s; NaN boxes are refused by the same parser, above)."""
    mode = "sightinf"
    server = vlm(Options(misbehave=mode))
    ran(cli(*SIGHT, *fake(server), "--backends.perception", "rgb", "--backends.relevancy",
            "vlm-match", "--out", str(tmp_path / "g")))
    assert any(r.kind == "sightings" and r.images == 1 for r in server.requests)
    problems = sighting_problems(tmp_path / "g")
    assert problems and all(SIGHTINGS[mode] in p for p in problems), problems


@trial("R6.39", "R6.40", "R6.41", "R6.42")
def test_the_reply_parser_refuses_what_is_unbounded_or_not_finite_in_bounded_time():
    """``json_reply``, shared by the sighting call and ``--explore.reading model``: each reply
    is refused whole, with why, in well under a second; a reply within the bounds is read."""
    from efficienteqa.vc.json_reply import MAX_JSON_DEPTH, MAX_JSON_VALUES, json_reply

    bad = {
        '{"item": NaN}': "not finite (NaN)",
        '{"box": [Infinity, 1, 2, 3]}': "not finite (Infinity)",
        '{"box": [-Infinity, 1, 2, 3]}': "not finite (-Infinity)",
        '{"box": [1e999, 1, 2, 3]}': "not finite (1e999)",
        '{"box": [-1e999, 1, 2, 3]}': "not finite (-1e999)",
        '{"item": ' + "9" * 400 + "}": "a JSON number of 400 digits",
        '{"room": ' + "[" * 200_000: "a reply of 200009 characters (over 100000)",
        '{"room": ' + "[" * 90_000: f"nested over {MAX_JSON_DEPTH} deep",
        '{"a": ' + "[" * 40 + "]" * 40 + "}": f"nested over {MAX_JSON_DEPTH} deep",
        '{"things": [' + ", ".join(['{"name": "bed", "item": 1}'] * 1000) + "]}":
            f"over {MAX_JSON_VALUES} values",
        '{"a": [' + ", ".join(["1"] * 40_000) + "]}": "a reply of 120007 characters",
        "{" * 99_000 + "x": "no JSON object",
        "{\"a\": [1, 2" * 9000: "no JSON object",
        "I'm sorry, but I can't help with that.": "no JSON object",
        '["room", "kitchen"]': "no JSON object",
    }
    for reply, why in bad.items():
        start = time.monotonic()
        said, said_why = json_reply(reply)
        assert time.monotonic() - start < 0.5, reply[:40]
        assert said is None and why in said_why, (reply[:40], said_why)
    good = 'Sure:\n```json\n{"room": "kitchen", "things": [{"name": "chair", "box": [1, 2.5, 3, 4]}]}\n```'
    assert json_reply(good) == ({"room": "kitchen", "things": [{"name": "chair",
                                                                "box": [1, 2.5, 3, 4]}]}, "")
    assert json_reply("a {broken one, then {\"room\": \"hallway\"}") == ({"room": "hallway"}, "")


@trial("R6.39", "R6.42")
def test_what_a_sighting_reply_holds_beyond_use_is_dropped_and_said():
    """R6.39 (held): junk text, and an item of 29 digits, are problems and no sighting.
    R6.42: a reply of many things within the JSON bounds reads its first ``MAX_ENTRIES``."""
    from efficienteqa.perception.sightings import MAX_ENTRIES, Region, read_reply
    from efficienteqa.question import Target

    bed = Target(kind="colour", object="bed")
    said, problems = read_reply("\x00\x07 <<>> not a sighting", bed, items=3)
    assert said is None and problems == ["no JSON object in the sighting reply "
                                         "'\\x00\\x07 <<>> not a sighting': no sighting"]
    huge_item = '{"room": "bedroom", "things": [{"name": "bed", "item": 99999999999999999999999999999}]}'
    said, problems = read_reply(huge_item, bed, items=3)
    assert said is not None and said.things == ()
    assert problems == ["item 99999999999999999999 is not listed"]
    many = json.dumps({"room": "bedroom", "doorways": [{"room": "hallway", "box": [0, 0, 9, 9]}]
                       * 40, "things": [{"name": "bed", "box": [10, 10, 500, 900]}] * 200})
    said, problems = read_reply(many, bed)
    assert said is not None and len(said.things) == MAX_ENTRIES == 32
    assert said.things[0] == ("bed", Region((10, 10, 500, 900))) and len(said.doorways) == 32
    assert problems == ["40 doorways, read the first 32", "200 things, read the first 32"]
    boxes = ('{"room": "bedroom", "things": [{"name": "bed", "box": [1e308, 0, 900, 900]}, '
             '{"name": "bed", "item": 2, "box": [true, 1, 2, 3]}]}')
    said, problems = read_reply(boxes, bed)
    assert said is not None and said.things == (("bed", Region((900, 0, 1000, 900))),)  # clamped
    assert problems == ["box [True, 1, 2, 3] is not four numbers"]


@trial("R6.41")
def test_a_reading_reply_beyond_the_bounds_is_a_problem_and_the_rules_target():
    """``--explore.reading model`` reads its reply with the same parser: a reply nested
    90,000 deep, or holding NaN, is a problem and the rules' reading, never a traceback."""
    from efficienteqa.models.stub import StubChatModel
    from efficienteqa.question import parse_question
    from efficienteqa.reading.reader import ModelReader

    question = "What colour is the bed in the bedroom?"
    for reply, why in (('{"kind": ' + "[" * 90_000, "nested over 16 deep"),
                       ('{"kind": "colour", "object": NaN}', "not finite (NaN)")):
        reader = ModelReader(StubChatModel([reply]))
        assert reader.read(question) == parse_question(question)
        assert len(reader.problems) == 1 and why in reader.problems[0], reader.problems
        assert reader.problems[0].endswith(": the rules' target")


# ---------------------------------------------------------------- R6.43-R6.45: the judge

@pytest.fixture
def stub_run(cli, vlm, tmp_path) -> Path:
    """A finished run of one episode to grade (the stub method: no model call)."""
    run = tmp_path / "run"
    ran(cli(*STUB, "--eval.limit", "1", *fake(vlm()), "--out", str(run)))
    return run


JUDGED = {  # mode -> the reply the judge's problem quotes
    "judgejunk": "'\\x00\\x07 <<>> 999...'", "judgeempty": "''", "judgedeep": "'Your mark: [[[",
    "judgearabic": "'٣'", "judgesup": "'²'", "judgesup5": "'5²'"}


@trial("R6.43", "R6.44")
def test_an_openeqa_judge_without_a_mark_gives_the_default_grade_and_says_so(cli, vlm, stub_run):
    """``judge --judge-mode openeqa`` against each unreadable mark: the default grade 1 with the
    problem "no mark from 1 to 5". "²" and "5²" passed ``isdigit()`` and failed ``int()``: a
    traceback (R6.44); "٣" was read as 3."""
    for mode, quoted in JUDGED.items():
        server = vlm(Options(misbehave=mode))
        said = ran(cli("judge", str(stub_run), "--judge", f"openai:j-{mode}@{server.base_url}",
                       "--judge-mode", "openeqa"))
        assert "1 episodes graded" in said and "LLM-Match 0.0" in said, (mode, said)
        [row] = rows(stub_run)
        verdict = row["judge"]
        assert (verdict["score"], verdict["cached"]) == (1, False), (mode, verdict)
        [problem] = verdict["problems"]
        assert problem.startswith(f"no mark from 1 to 5 in {quoted}"), (mode, problem)
        assert problem.endswith(", scored 1"), (mode, problem)
        assert server.kinds()[-1] == "judge-openeqa"


@trial("R6.44")
def test_an_eval_whose_openeqa_judge_writes_a_superscript_is_done_and_graded_1(cli, vlm, tmp_path):
    """In eval the episode failed (ValueError: invalid literal for int()), and again on every
    resume."""
    judge = vlm(Options(misbehave="judgesup"))
    args = (*BLIND, "--eval.limit", "1", *fake(vlm()), "--eval.judge",
            f"openai:j@{judge.base_url}", "--eval.judge-mode", "openeqa", *FAST,
            "--out", str(tmp_path / "run"))
    assert "1 episodes run, 0 already done, 0 failed" in ran(cli(*args))
    [row] = rows(tmp_path / "run")
    assert row["status"] == "done" and row["judge"]["score"] == 1
    assert row["judge"]["problems"] == ["no mark from 1 to 5 in '²', scored 1"]
    from efficienteqa.eval.judge_parse import openeqa_mark, parse_score

    assert [openeqa_mark(r) for r in ("²", "5²", "٣", "Your mark: 4²", "Your mark: **4**")] == \
        [None, None, None, None, 4]
    assert parse_score("٣")[0] is None and parse_score("Score: ٤")[0] is None


@trial("R6.45")
def test_the_judge_cache_is_kept_per_server_and_never_keeps_a_default_grade(cli, vlm, stub_run):
    """A judge server whose marks were unreadable, then a healthy one of the same model name:
    the healthy one returned the cached default (``'cached': True, 'raw': ''``) and was never
    asked. Now the default is not stored, and grades are keyed by the server too."""
    broken, healthy = vlm(Options(misbehave="judgeempty")), vlm(Options())
    for server in (broken, healthy, healthy):
        ran(cli("judge", str(stub_run), "--judge", f"openai:judgeT6@{server.base_url}",
                "--judge-mode", "openeqa"))
        verdict = rows(stub_run)[0]["judge"]
        if server is broken:
            assert (verdict["score"], verdict["raw"], verdict["cached"]) == (1, "", False)
    assert healthy.kinds().count("judge-openeqa") == 1  # the second time: the cache
    assert verdict["cached"] is True and verdict["raw"] == healthy.requests[-1].reply
    assert verdict["score"] == int(healthy.requests[-1].reply)


@trial("R6.45")
@pytest.mark.parametrize("mode", ["grade", "openeqa", "yes-prob"])
def test_a_judge_grade_is_stored_only_when_read_and_under_its_server(tmp_path, mode):
    """Each mode's path, at the judge itself: an unreadable reply is asked again next time;
    a read grade is kept for its server, not for another of the same model name."""
    from efficienteqa.eval.judge import LLMMatchJudge
    from efficienteqa.models.base import Capabilities
    from efficienteqa.models.stub import StubChatModel

    def judge(replies: list[str], server: str | None) -> LLMMatchJudge:
        model = StubChatModel(replies, name="judgeT6",
                              capabilities=Capabilities(logprobs=mode == "yes-prob"))
        model.server = server  # type: ignore[attr-defined]  # OpenAIChatClient.server
        return LLMMatchJudge(model, cache_path=tmp_path / "j.sqlite", mode=mode)

    unreadable = "I cannot grade this." if mode != "yes-prob" else "Maybe"
    readable = "4" if mode != "yes-prob" else "Yes"
    grade = ("Q: what colour is the sofa?", "red", "a crimson couch")
    first = judge([unreadable] * 4, "http://a/v1").judge(*grade)
    assert first.score == 1 and first.problems and not first.cached
    again = judge([readable] * 2, "http://a/v1")
    second = again.judge(*grade)
    assert not second.cached and second.score != 1 and again.model.requests  # asked again
    assert judge([], "http://a/v1").judge(*grade).cached  # read: kept for that server
    other = judge([readable] * 2, "http://b/v1")
    assert not other.judge(*grade).cached and other.model.requests  # another server: asked


# ---------------------------------------------------------------- R6.37, R6.38: capabilities files

CAPABILITIES = {  # file -> what its one line says
    b"\xff\xfe\x00\x01binary": "is not JSON",
    b"[1]": "holds no JSON object",
    b'{"logprobs": "yes"}': "bad entry 'logprobs': 'yes'",
    b'{"max_images": 0}': "allows 0 images",
    b'{"max_images": 1e999}': "bad entry 'max_images': inf",
    b'{"speed": true}': "bad entry 'speed'",
    b'{"logprobs": ' + b"[" * 100_000: "is not JSON",
}


@trial("R6.37")
def test_a_bad_capabilities_file_is_one_line_before_any_work(cli, tmp_path):
    for i, (text, said) in enumerate([*CAPABILITIES.items(), (None, "Is a directory")]):
        path = tmp_path / f"caps{i}.json"
        if text is None:
            path.mkdir()
        else:
            path.write_bytes(text)
        out = tmp_path / f"run{i}"
        line = one_error_line(cli(*BLIND, "--eval.limit", "1", "--backends.vlm",
                                  "openai:fake@http://127.0.0.1:9/v1", "--backends.capabilities",
                                  str(path), *FAST, "--out", str(out)))
        assert str(path) in line and said in line, (text, line)
        assert not (out / "episodes.jsonl").exists()


@trial("R6.38")
def test_capabilities_claimed_beyond_the_servers_are_the_users_word(cli, vlm, tmp_path):
    """A file claiming logprobs, JSON schemas and a grammar for a server that gives none of
    them (its replies carry no logprobs): ``ask`` runs, unprobed, on the user's word."""
    claimed = tmp_path / "caps.json"
    claimed.write_text('{"logprobs": true, "json_schema": true, "grammar": true}')
    server = vlm(Options(logprobs="ignore"))
    asked = ran(cli(*SIGHT[:6], "--explore.max-steps", "1", *WORDS, *fake(server),
                    "--backends.capabilities", str(claimed), "--out", str(tmp_path / "ask")))
    assert "answer:" in asked
    run = tmp_path / "explore-eqa"
    said = ran(cli("eval", "--preset", "explore-eqa", "--eval.dataset", "synthetic:3",
                   "--eval.limit", "1", "--eval.judge", "none", "--scene.assets", "builtin",
                   "--explore.max-steps", "1", *WORDS[:2], *WORDS[4:], *fake(server),
                   "--backends.capabilities", str(claimed),
                   "--out", str(run)))
    assert "1 episodes run, 0 already done, 0 failed" in said
    assert rows(run)[0]["status"] == "done"
    assert "probe" not in server.kinds() and server.requests
    assert any(r.body.get("logprobs") for r in server.requests)  # asked, and none came


# ---------------------------------------------------------------- R6.35, R6.36, R6.61: secrets

@trial("R6.35")
def test_config_prints_a_urls_password_as_stars(cli, tmp_path):
    """``efficienteqa config`` printed ``vlm = "openai:m@http://user:PASSWORD@..."``: from the
    flags, from --config and in ``--eval.judge``."""
    url = f"http://user:{PASSWORD}@127.0.0.1:8931/ok/v1"
    shown = "http://user:***@127.0.0.1:8931/ok/v1"
    config = Path(os.environ.get("TMPDIR", "/tmp")) / f"eqa-r635-{os.getpid()}.toml"
    config.write_text(f'[backends]\nvlm = "openai:m@{url}"\n[eval]\njudge = "openai:j@{url}"\n')
    try:
        printed = [ran(cli("config", "--backends.vlm", f"openai:m@{url}", "--eval.judge",
                           f"openai:j@{url}")),
                   ran(cli("config", "--config", str(config)))]
    finally:
        config.unlink()
    for text in printed:
        assert PASSWORD not in text
        assert f'vlm = "openai:m@{shown}"' in text and f'judge = "openai:j@{shown}"' in text
        assert text.startswith("# a password in a server's URL is shown as ***")
    plain = ran(cli("config", "--backends.vlm", "openai:m@http://127.0.0.1:8931/v1"))
    assert not plain.startswith("#") and "***" not in plain


@trial("R6.36")
def test_a_password_from_config_reaches_no_file_and_nothing_printed(cli, vlm, tmp_path):
    """The password URL from ``--config`` through ask (with --record and --rerun, the model
    sightings) and eval (with a judge URL with a password), and a dead judge with a password:
    the run record shows ``user:***@``, the dead judge's line too; no file written (run
    folders, the walk, the .rrd, the caches) holds the password (the autouse check reads them
    all; here it is said once more), nor does anything printed."""
    pytest.importorskip("rerun")
    server, judge = vlm(Options()), vlm(Options())
    url = server.base_url.replace("http://", f"http://user:{PASSWORD}@")
    judged = judge.base_url.replace("http://", f"http://user:{PASSWORD}@")
    config = Path(os.environ.get("TMPDIR", "/tmp")) / f"eqa-r636-{os.getpid()}.toml"
    config.write_text(f'[backends]\nvlm = "openai:fake@{url}"\n')
    try:
        said = [ran(cli(*SIGHT, "--config", str(config), "--record", str(tmp_path / "walk.mcap"),
                        "--rerun", str(tmp_path / "ask.rrd"), "--out", str(tmp_path / "ask"))),
                ran(cli(*BLIND, "--eval.limit", "1", "--config", str(config), "--eval.judge",
                        f"openai:j@{judged}", "--eval.judge-mode", "openeqa",
                        "--out", str(tmp_path / "run"))),
                one_error_line(cli(*BLIND, "--eval.limit", "1", "--config", str(config),
                                   "--eval.judge", f"openai:j@http://u:{PASSWORD}@127.0.0.1:9/v1",
                                   *FAST, "--out", str(tmp_path / "dead")))]
    finally:
        config.unlink()
    assert "--eval.judge openai:j@http://u:***@127.0.0.1:9/v1" in said[2]
    record = json.loads((tmp_path / "run" / "run.json").read_text())
    assert record["stack"]["vlm"] == "openai:fake@" + server.base_url.replace("http://",
                                                                             "http://user:***@")
    assert rows(tmp_path / "run")[0]["judge"]["score"] in range(1, 6)
    assert (tmp_path / "walk.mcap").stat().st_size and (tmp_path / "ask.rrd").stat().st_size
    assert "sightings" in server.kinds() and judge.kinds()[-1] == "judge-openeqa"
    assert files_holding(tmp_path, PASSWORD) == [] and PASSWORD not in "".join(said)


@trial("R6.61")
def test_the_api_key_sent_with_every_request_reaches_no_file(cli, vlm, tmp_path):
    """The key, sent to the server with every request of ask (model sightings, --record) and
    eval (the openeqa judge, reports), with the response cache on: the walk, the run folders,
    the probe, response and judge caches hold no trace of it, nor does anything printed."""
    server, judge = vlm(Options(api_key=KEY)), vlm(Options())  # any other key is refused
    cached = [a for a in SIGHT if a != "--backends.no-cache"]
    said = [ran(cli(*cached, *fake(server), "--record", str(tmp_path / "walk.mcap"),
                    "--out", str(tmp_path / "ask"))),
            ran(cli(*[a for a in BLIND if a != "--backends.no-cache"], "--eval.limit", "1",
                    *fake(server), *KEYED, "--eval.judge", f"openai:j@{judge.base_url}",
                    "--eval.judge-mode", "openeqa", "--eval.reports",
                    "--out", str(tmp_path / "run")))]
    assert {r.authorization for r in server.requests} == {f"Bearer {KEY}"}
    assert {"probe", "sightings", "answer"} <= set(server.kinds())
    assert judge.kinds()[-1] == "judge-openeqa"
    cache = tmp_path / "cache"
    for kept in (tmp_path / "walk.mcap", cache / "responses" / "responses.sqlite",
                 cache / "judge" / "llm_match.sqlite", tmp_path / "run" / "episodes.jsonl"):
        assert kept.stat().st_size, kept
    assert list((cache / "probes").glob("*.json"))
    assert files_holding(tmp_path, KEY) == [] and KEY not in "".join(said)


# ---------------------------------------------------------------- R6.47-R6.50: question files

ROW = {"question": "Is there a bed?", "scene": "synthetic:0"}


def questions(tmp_path: Path, *lines: str | bytes | dict, name: str = "q.jsonl") -> Path:
    path = tmp_path / name
    path.write_bytes(b"".join((line if isinstance(line, bytes) else
                               (line if isinstance(line, str) else json.dumps(line)).encode())
                              + b"\n" for line in lines))
    return path


def stub_eval(server: VLMServer, file: Path, out: Path, *extra: str) -> tuple[str, ...]:
    return ("eval", "--eval.dataset", str(file), "--eval.method", "eval_stubs:echo",
            "--eval.judge", "none", *fake(server), *extra, "--out", str(out))


BAD_FILES = {  # name -> (its lines, what the one line says after "FILE line N")
    "garbage": (["not json"], "line 1 is not JSON"),
    "noscene": ([{"question": "Is there a bed?"}], "line 1 needs a question and a scene"),
    "duplicate": ([{**ROW, "id": "a"}, {**ROW, "id": "a"}], "line 2: id 'a' is used twice"),
    "alternatives": ([ROW, {**ROW, "alternatives": 5}],  # R6.48
                     "line 2: alternatives is 5, not a list of answers"),
    "alternatives-list": ([{**ROW, "alternatives": ["navy", {"a": 1}]}],
                          "line 1: alternatives holds something other than answers"),
    "deep": ([ROW, '{"question": ' + "[" * 100_000], "line 2 is not JSON: nested too deep"),  # R6.48
    "utf8": ([ROW, ROW, b'{"question": "Is there a b\xe9d?", "scene": "synthetic:0"}'],  # R6.48
             "line 3 is not UTF-8 text (byte 27: b'\\xe9d?\"')"),
    "dotdot": ([{**ROW, "id": ".."}], "line 1: id '..' names no folder of its own"),  # R6.49
    "dot": ([{**ROW, "id": "."}], "line 1: id '.' names no folder of its own"),
    "nul": ([ROW, {**ROW, "id": "bed\x00x"}], "line 2: id 'bed\\x00x' holds a control "
                                              "character"),
    "long": ([{**ROW, "id": "x" * 5000}], "line 1: id 'xxxxxxxxxx"),
    "long-slashes": ([{**ROW, "id": "a/" * 80}], "line 1: id 'a/a/a/"),
    "id-object": ([{**ROW, "id": {"a": 1}}], "line 1: id is an object, not text"),
}

ALSO = {"long": "is 5000 bytes long, over 200", "long-slashes": "is 240 bytes long, over 200"}


@trial("R6.47", "R6.48", "R6.49")
@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_a_question_file_line_that_cannot_be_run_is_one_line_before_any_episode(cli, vlm,
                                                                               tmp_path, name):
    """R6.48: ``"alternatives": 5``, a line nested 100,000 deep and a line that is not UTF-8
    gave tracebacks. R6.49: ``".."`` wrote episode.json and report.html into the run folder
    itself; an id with NUL, or of 5,000 characters, ran its episode and then failed."""
    lines, said = BAD_FILES[name]
    file = questions(tmp_path, *lines)
    server = vlm()
    line = one_error_line(cli(*stub_eval(server, file, tmp_path / "run", "--eval.reports")))
    assert line.startswith(f"error: {file} {said}"), line
    assert ALSO.get(name, "") in line, line
    assert len(line) < 600
    assert not (tmp_path / "run" / "episodes.jsonl").exists()
    assert server.kinds() == []  # refused before the server was asked anything


@trial("R6.47")
def test_question_files_that_are_empty_or_name_what_is_not_there_are_one_line(cli, vlm, tmp_path):
    """An empty file, ``--episode nosuch`` and a row on a missing recording: one line each;
    ``"answer": {}`` and ids ``../../x`` and ``/abs`` run, in folders inside the run's."""
    server = vlm()
    empty = questions(tmp_path, name="empty.jsonl")
    assert f"{empty} holds no question" in one_error_line(cli(*stub_eval(server, empty,
                                                                         tmp_path / "e")))
    odd = questions(tmp_path, {**ROW, "id": "../../x", "answer": {}}, {**ROW, "id": "/abs"},
                    {"question": "Is there a bed?", "scene": "recorded:nosuch.mcap", "id": "m"})
    line = one_error_line(cli("ask", "--episode", "nosuch", "--eval.dataset", str(odd),
                              "--out", str(tmp_path / "a")))
    assert "no question 'nosuch' in the dataset (3 questions)" in line
    line = one_error_line(cli("ask", "--episode", "m", "--eval.dataset", str(odd), *fake(server),
                              "--out", str(tmp_path / "m")))
    assert f"{tmp_path / 'nosuch.mcap'}" in line and "does not exist" in line
    run = tmp_path / "run"
    assert "3 episodes run" in ran(cli(*stub_eval(server, odd, run)))
    assert [(r["id"], r["reference"]) for r in rows(run)] == [("../../x", ""), ("/abs", ""),
                                                              ("m", "")]
    from efficienteqa.eval.runner import episode_folder

    assert [episode_folder(run, r["id"]).name for r in rows(run)] == ["..__..__x", "__abs", "m"]


@trial("R6.50")
def test_a_row_on_a_broken_recording_fails_alone(cli, vlm, tmp_path):
    """Two rows, one on a recording cut short: the good one done, the broken one failed with
    one line, the run's one line counts it, no traceback."""
    walk = tmp_path / "broken.mcap"
    walk.write_bytes(b"\x89MCAP0\r\n" + os.urandom(2000))
    file = questions(tmp_path, {**ROW, "id": "good"},
                     {"question": "Is there a bed?", "scene": "recorded:broken.mcap",
                      "id": "broken"})
    server = vlm()
    line = one_error_line(cli("eval", "--eval.dataset", str(file), "--eval.judge", "none",
                              "--scene.assets", "builtin", "--explore.max-steps", "1", *WORDS,
                              *fake(server), "--out", str(tmp_path / "run")))
    assert "1 episode(s) failed" in line, [r.get("error") for r in rows(tmp_path / "run")]
    good, broken = rows(tmp_path / "run")
    assert (good["id"], good["status"], broken["id"], broken["status"]) == \
        ("good", "done", "broken", "failed")
    assert "\n" not in broken["error"] and str(walk) in broken["error"]


# ---------------------------------------------------------------- R6.55-R6.58: the local server

FAKE_LLAMA = '''"""A stand-in for ``python -m llama_cpp.server``: the test server on --port; with
$FAKE_LLAMA_DIE_AFTER=N it kills itself (SIGKILL) as request N + 1 comes in."""
import os, signal, sys, threading
from vlm_server import Options, VLMServer

DIE_AFTER = int(os.environ.get("FAKE_LLAMA_DIE_AFTER", "0"))


class Dying(VLMServer):
    def answer(self, headers, body, path):
        if DIE_AFTER and len(self.requests) >= DIE_AFTER:
            os.kill(os.getpid(), signal.SIGKILL)
        return super().answer(headers, body, path)


Dying(Options(), port=int(sys.argv[sys.argv.index("--port") + 1]))
threading.Event().wait()
'''
MODEL = "smollm2-135m"


@pytest.fixture
def local(tmp_path, monkeypatch, env):
    """A private cache holding a stand-in model file, and ``llama_cpp.server`` replaced by the
    test server (on the port the project picks): what ``ensure_server`` starts. Every server
    started is stopped after the test, and the leases given up."""
    from efficienteqa.models.local import keeper, server, weights

    fake = tmp_path / "fake"
    (fake / "llama_cpp" / "server").mkdir(parents=True)
    (fake / "llama_cpp" / "__init__.py").write_text("")
    (fake / "llama_cpp" / "server" / "__main__.py").write_text(FAKE_LLAMA)
    path = os.pathsep.join([str(fake), env["PYTHONPATH"]])
    env.update(PYTHONPATH=path, EFFICIENTEQA_SERVER_IDLE_S="0")
    for name in ("PYTHONPATH", "EFFICIENTEQA_SERVER_IDLE_S", "EFFICIENTEQA_CACHE"):
        monkeypatch.setenv(name, env[name])
    monkeypatch.setattr(server, "ensure_llama_cpp", lambda: None)
    model = Path(env["EFFICIENTEQA_CACHE"]) / "models" / weights.registry_entry(MODEL).filename
    model.parent.mkdir(parents=True)
    model.write_bytes(b"GGUF")
    yield server
    server.stop(MODEL, grace_s=2.0)
    keeper.release_lease(server.lease_file(MODEL))
    for pid in list(server._children):
        server._reap(pid)


def _ensure_in_a_child(at: float, out: Path) -> int:
    """``ensure_server`` in a forked child at the moment ``at``; what it said goes to ``out``."""
    import warnings

    from efficienteqa.models.local import server

    with warnings.catch_warnings():  # the test's threads stay in the parent
        warnings.simplefilter("ignore", DeprecationWarning)
        pid = os.fork()
    if pid:
        return pid
    code = 1
    try:
        with out.open("w") as said:
            os.dup2(said.fileno(), 2)
            sys.stderr = said
            time.sleep(max(0.0, at - time.time()))
            said.write(f"url {server.ensure_server(MODEL)}\n")
            code = 0
    finally:
        os._exit(code)


@trial("R6.55")
def test_two_commands_at_once_start_one_local_server(local, tmp_path):
    """Two processes ask for the server at the same instant, none running: one starts it and
    says so, the other waits for it and uses it."""
    at = time.time() + 0.3
    children = [_ensure_in_a_child(at, tmp_path / f"said{i}") for i in range(2)]
    for pid in children:
        _, status = os.waitpid(pid, 0)
        assert os.waitstatus_to_exitcode(status) == 0, [
            (tmp_path / f"said{i}").read_text() for i in range(2)]
    said = [(tmp_path / f"said{i}").read_text() for i in range(2)]
    urls = {line for text in said for line in text.splitlines() if line.startswith("url ")}
    assert len(urls) == 1, said
    assert sum(text.count("started the local model server") for text in said) == 1, said
    running = local.running()
    assert len(running) == 1 and running[0].healthy()
    local.stop(MODEL, grace_s=2.0)
    assert local.running() == []


@trial("R6.56")
def test_a_local_server_killed_mid_ask_is_one_line_and_a_partial_episode(cli, env, local,
                                                                        tmp_path):
    """The server dies (SIGKILL) after its first reply: the ask ends in one line naming it,
    keeps the partial episode, and the dead server's pid file is cleaned."""
    env["FAKE_LLAMA_DIE_AFTER"] = "1"
    line = one_error_line(cli("ask", "What colour is the bed?", "--scene", "synthetic:3",
                              "--scene.assets", "builtin", "--explore.max-steps", "2",
                              "--backends.vlm", f"local:{MODEL}", *WORDS,
                              "--backends.retries", "0", "--out", str(tmp_path / "a")))
    assert "model server at http://127.0.0.1:" in line and "unreachable after 1 tries" in line
    record = json.loads((tmp_path / "a" / "episode.json").read_text())
    assert record["model"]["exchanges"], record.get("model")
    assert local.running() == []
    assert list((tmp_path / "cache" / "server").glob("*.json")) == []


@trial("R6.57")
@pytest.mark.parametrize("idle", ["abc", "-5"])
def test_a_bad_server_idle_time_is_one_line(cli, env, tmp_path, idle):
    env["EFFICIENTEQA_SERVER_IDLE_S"] = idle
    line = one_error_line(cli("ask", "Is there a bed?", "--scene", "synthetic:0",
                              "--backends.vlm", f"local:{MODEL}", "--out", str(tmp_path / "a")))
    assert f"EFFICIENTEQA_SERVER_IDLE_S={idle!r} is not a number of seconds" in line


@trial("R6.58")
def test_a_stopped_local_server_is_said_while_waited_for_then_replaced(local, monkeypatch,
                                                                      capfd):
    """A server stopped with SIGSTOP: the wait for it says, once, which server it waits on;
    then one line with its log's tail, the server killed (a stopped process too), and the next
    command starts a new one. (The command waits 180 s: here the same wait, shorter.)"""
    from efficienteqa.errors import EfficientEQAError

    first = local.serve(MODEL, timeout_s=20)
    os.kill(first.pid, signal.SIGSTOP)
    monkeypatch.setattr(local, "WAIT_NOTICE_S", 0.2)
    capfd.readouterr()
    start = time.monotonic()
    with pytest.raises(EfficientEQAError) as raised:
        local.serve(MODEL, timeout_s=2)
    assert time.monotonic() - start < 10
    said = capfd.readouterr().err
    assert said.count("efficienteqa: waiting for the llama.cpp server") == 1, said
    assert f"on 127.0.0.1:{first.port} (pid {first.pid})" in said and "at most 2 s" in said
    assert "did not answer within 2 s" in str(raised.value) and "\n" not in str(raised.value)
    assert local.running() == [] and not local._alive(first.pid, first.proc_start)
    second = local.serve(MODEL, timeout_s=20)
    assert second.pid != first.pid and second.healthy()


@trial("R6.58")
def test_a_model_call_that_waits_says_which_server_it_waits_on(vlm, monkeypatch, capfd):
    """The low item "a hung server costs 180 s with no line": a call that has waited
    ``WAIT_NOTICE_S`` says so once on stderr, names the server, and goes on waiting."""
    from efficienteqa.models import client as client_module
    from efficienteqa.models.base import Message
    from efficienteqa.models.client import OpenAIChatClient
    from efficienteqa.models.client_config import ClientConfig

    monkeypatch.setattr(client_module, "WAIT_NOTICE_S", 0.4)
    slow, quick = vlm(Options(hang_s=1.0)), vlm(Options())
    for server in (slow, quick):
        capfd.readouterr()
        client = OpenAIChatClient(ClientConfig(base_url=server.base_url, model="fake",
                                               timeout_s=5, max_retries=2, cache=False))
        reply = client.chat([Message("user", "Say yes.")], max_tokens=2)
        assert reply.text == "yes"
        said = capfd.readouterr().err
        if server is slow:
            assert said.count("still waiting for the model server") == 1, said
            assert f"at {server.base_url}/chat/completions after 0.4 s" in said
            assert "each try may take 5 s, 3 tries" in said
        else:
            assert "still waiting" not in said, said
    time.sleep(0.5)  # a finished call's notice never comes late
    assert "still waiting" not in capfd.readouterr().err
