"""The evaluation runner: one line per episode, resume without double counting, failures
recorded per episode, a killed run resumed, and Ray on two local workers."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from efficienteqa.agent import AgentConfig
from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.methods import METHODS, RunSpec, method_config, resolve
from efficienteqa.eval.records import EPISODES_FILE, append_episode, read_episodes
from efficienteqa.eval.runner import run_eval
from efficienteqa.stack import Stack

TESTS = Path(__file__).parent


def questions(n: int) -> list[EvalQuestion]:
    return [EvalQuestion(id=f"toy/{i:03d}", dataset="toy", scene="synthetic:0",
                         question=f"How many cups are on table {i}?", answer=str(i % 4),
                         category="count") for i in range(n)]


def spec(method: str = "eval_stubs:echo", **kwargs) -> RunSpec:
    return RunSpec.of(method=method, dataset="toy", judge=None, **kwargs)


def lines(out: Path) -> list[dict]:
    return [json.loads(x) for x in (out / EPISODES_FILE).read_text().splitlines() if x.strip()]


def test_sequential_run_writes_each_episode_once_and_resume_skips_them(tmp_path):
    first = run_eval(spec(), questions(5), tmp_path, prepare=False)
    assert (first.ran, first.skipped, first.failed) == (5, 0, 0)
    rows = lines(tmp_path)
    assert [r["id"] for r in rows] == [q.id for q in questions(5)]
    assert all(r["status"] == "done" and r["answer"] == f"stub: {r['question']}" for r in rows)
    again = run_eval(spec(), questions(8), tmp_path, prepare=False)  # a larger limit continues
    assert (again.ran, again.skipped) == (3, 5)
    assert sorted(r["id"] for r in lines(tmp_path)) == [q.id for q in questions(8)]


def test_a_failing_episode_is_recorded_and_retried_on_resume(tmp_path, monkeypatch):
    monkeypatch.setenv("EQA_STUB_FAIL", "toy/002")
    result = run_eval(spec(), questions(4), tmp_path, prepare=False)
    assert (result.ran, result.failed) == (4, 1)
    failed = [r for r in lines(tmp_path) if r["status"] == "failed"]
    assert [r["id"] for r in failed] == ["toy/002"]
    assert failed[0]["error"] == "RuntimeError: scripted failure of toy/002"  # one line
    monkeypatch.delenv("EQA_STUB_FAIL")
    retry = run_eval(spec(), questions(4), tmp_path, prepare=False)
    assert (retry.ran, retry.skipped, retry.failed) == (1, 3, 0)
    episodes = read_episodes(tmp_path / EPISODES_FILE)
    assert len(episodes.by_id) == 4 and episodes.done == {q.id for q in questions(4)}


def test_a_folder_of_another_configuration_is_refused(tmp_path):
    run_eval(spec(), questions(1), tmp_path, prepare=False)
    other = spec(config=AgentConfig.of(top_k=3))
    with pytest.raises(EfficientEQAError, match="another config"):
        run_eval(other, questions(1), tmp_path, prepare=False)


def test_a_run_recorded_before_a_setting_existed_is_the_same_run(tmp_path):
    """A format-1 run.json without a setting added later (the temperature) still resumes: it is
    read as the value it ran with (records.upgrade)."""
    run_eval(spec(), questions(1), tmp_path, prepare=False)
    manifest = json.loads((tmp_path / "run.json").read_text())
    del manifest["format"], manifest["stack"]["temperature"]
    (tmp_path / "run.json").write_text(json.dumps(manifest))
    again = run_eval(spec(), questions(2), tmp_path, prepare=False)
    assert (again.ran, again.skipped) == (1, 1)
    with pytest.raises(EfficientEQAError, match="another stack"):
        run_eval(spec(stack=Stack(temperature=1.0)), questions(2), tmp_path, prepare=False)


def test_a_torn_last_line_is_skipped_and_the_next_line_starts_fresh(tmp_path):
    path = tmp_path / EPISODES_FILE
    append_episode(path, {"id": "a", "status": "done"})
    with path.open("ab") as f:
        f.write(b'{"id": "b", "sta')  # a writer killed mid-line
    append_episode(path, {"id": "c", "status": "done"})
    episodes = read_episodes(path)
    assert list(episodes.by_id) == ["a", "c"] and episodes.torn == 1


def test_a_run_killed_mid_way_resumes_with_every_episode_exactly_once(tmp_path):
    script = (f"import sys; sys.path.insert(0, {str(TESTS)!r})\n"
              "from pathlib import Path\n"
              "from test_eval_runner import questions, spec\n"
              "from efficienteqa.eval.runner import run_eval\n"
              f"run_eval(spec(), questions(12), Path({str(tmp_path)!r}), prepare=False)\n")
    env = {**os.environ, "EQA_STUB_SLEEP": "0.15"}
    proc = subprocess.Popen([sys.executable, "-c", script], env=env)
    path = tmp_path / EPISODES_FILE
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(read_episodes(path).done) < 3:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    killed_at = len(read_episodes(path).done)
    assert 3 <= killed_at < 12
    result = run_eval(spec(), questions(12), tmp_path, prepare=False)
    assert result.skipped == killed_at and result.ran == 12 - killed_at
    ids = [r["id"] for r in lines(tmp_path)]
    assert sorted(ids) == [q.id for q in questions(12)]  # each exactly once


def test_methods_are_configurations_of_the_agent():
    base = AgentConfig()
    assert method_config("efficienteqa", base).stop.enabled
    white = method_config("explore-eqa", base)
    assert (white.answer.confidence, white.answer.answer_at, white.stop.enabled) == (
        "token", "best-step", False)
    black = method_config("explore-eqa-blackbox", base)
    assert (black.answer.confidence, black.answer.answer_at, black.explore.explorer) == (
        "verbalized", "best-step", "sfe")
    assert method_config("frontier-only", base).explore.explorer == "frontier-only"
    direct = AgentConfig.of(answer="direct")  # ExploreEQA keeps its own answer at every step
    assert method_config("explore-eqa", direct).answer.answer == "paper"
    assert method_config("efficienteqa", direct).answer.answer == "direct"
    assert set(METHODS) >= {"efficienteqa", "explore-eqa", "explore-eqa-blackbox", "blind",
                            "frontier-only", "random"}
    with pytest.raises(EfficientEQAError, match="unknown method"):
        resolve("nope")
    with pytest.raises(EfficientEQAError, match="cannot load method"):
        resolve("no_such_module:run")


def test_agent_methods_on_hm3d_scenes_need_habitat_before_any_episode(tmp_path, monkeypatch):
    hm3d = [EvalQuestion(id="hm-eqa/000", dataset="hm-eqa", scene="hm3d:00004-VqCaAuuoeWk",
                         question="Is the lamp on?", answer="yes", category="state")]
    with pytest.raises(EfficientEQAError, match="explores the HM3D scenes") as err:
        run_eval(spec("efficienteqa"), hm3d, tmp_path)
    assert "--scene.env habitat --scene.hm3d-root" in err.value.fix
    monkeypatch.setitem(sys.modules, "habitat_sim", None)  # not installed
    with pytest.raises(EfficientEQAError, match="Habitat-Sim is not installed"):
        run_eval(spec("efficienteqa", env="habitat", hm3d_root=str(tmp_path)), hm3d, tmp_path / "b")
    assert not (tmp_path / EPISODES_FILE).exists() and not (tmp_path / "b" / EPISODES_FILE).exists()


def test_rejudging_a_run_replaces_each_grade_once_and_names_the_judge(tmp_path, monkeypatch):
    from efficienteqa.eval import runner
    from efficienteqa.eval.judge import LLMMatchJudge
    from efficienteqa.models.stub import StubChatModel

    monkeypatch.setenv("EQA_STUB_FAIL", "toy/001")
    monkeypatch.setenv("EQA_STUB_ANSWER", "a teapot")  # not the reference: the model must grade
    run_eval(spec(), questions(3), tmp_path, prepare=False)
    stub = StubChatModel(lambda messages: '{"score": 2}', name="stub-judge")
    monkeypatch.setattr(runner, "build_judge", lambda spec, mode: LLMMatchJudge(
        stub, cache_path=tmp_path / "j.sqlite", mode=mode))
    n, score = runner.rejudge(tmp_path, "local:stub-judge", "grade")
    # Grade 2 -> 25 each; the failed episode is not graded and scores 0, as in the report.
    assert n == 2 and score == pytest.approx(50 / 3) and len(stub.requests) == 2
    rows = read_episodes(tmp_path / EPISODES_FILE).by_id
    assert len(rows) == 3 and rows["toy/001"]["status"] == "failed"
    assert rows["toy/000"]["judge"]["judge"] == "stub-judge" and rows["toy/000"]["judge"]["score"] == 2
    again = runner.rejudge(tmp_path, "local:stub-judge", "grade")
    assert again == (n, score) and len(stub.requests) == 2  # the grades came from the cache
    assert len(read_episodes(tmp_path / EPISODES_FILE).by_id) == 3
    assert len(lines(tmp_path)) == 3  # compacted: a regrade does not grow the file
    manifest = json.loads((tmp_path / "run.json").read_text())
    assert (manifest["judge"], manifest["judge_mode"]) == ("local:stub-judge", "grade")


def test_compacting_keeps_the_winning_line_of_each_episode_and_drops_torn_ones(tmp_path):
    from efficienteqa.eval.records import append_episode, compact_episodes

    path = tmp_path / EPISODES_FILE
    append_episode(path, {"id": "a", "status": "failed"})
    append_episode(path, {"id": "b", "status": "done", "answer": "x"})
    append_episode(path, {"id": "a", "status": "done", "answer": "y"})
    with path.open("a") as f:
        f.write('{"id": "c", "sta')  # a writer killed mid-line
    assert compact_episodes(path) == 2
    assert [(r["id"], r["status"]) for r in map(json.loads, path.read_text().splitlines())] == [
        ("b", "done"), ("a", "done")]
    assert read_episodes(path).torn == 0 and not (tmp_path / (EPISODES_FILE + ".tmp")).exists()


def test_a_users_method_is_not_told_the_answer(tmp_path):
    """module:function methods get the question without its reference, alternatives, accepted
    answers, oracle steps or answer-bearing source fields (HM-EQA's letter, the evidence)."""
    q = EvalQuestion(id="toy/peek", dataset="toy", scene="synthetic:0", question="Is the lamp on?",
                     answer="yes", category="state", alternatives=("yes, it is on",),
                     accepted=("yes", "on"), oracle_steps=3,
                     source={"house_seed": 0, "letter": "A", "evidence": [4], "oracle_pose": [1, 2, 0]})
    run_eval(spec("eval_stubs:peek"), [q], tmp_path, prepare=False)
    (row,) = lines(tmp_path)
    assert row["reference"] == "yes"  # the record keeps it; the method did not see it
    assert json.loads(row["answer"]) == {"answer": "", "alternatives": [], "accepted": [],
                                         "oracle_steps": None, "source": ["house_seed"]}


def test_every_default_is_a_value_but_those_whose_none_is_one_of_its_own():
    """Typing a default is the same run (run.json records values, DESIGN 6): no setting is None
    for "a default decided elsewhere"; a default that follows something else is a named value
    ("auto": the relevancy device, the image format of the server). A None left is a value of
    its own: ``max_steps``, the scene's budget; the server's timeout, retries and key variable
    and the image detail, not sent (the back-end's own); the relevancy weights' folder and the
    capabilities file, not given (the server is probed). A new setting gets a value; runs
    recorded before it are read by records.upgrade."""
    import dataclasses

    from efficienteqa.stop.rules import StopConfig

    def none_by_default(cls):
        return {f.name for f in dataclasses.fields(cls)
                if (f.default if f.default is not dataclasses.MISSING else f.default_factory()) is None}

    from efficienteqa.answer.config import AnswerConfig
    from efficienteqa.explore.config import ExploreConfig

    assert none_by_default(AgentConfig) == set()  # its sections
    assert none_by_default(ExploreConfig) == {"max_steps"}
    assert none_by_default(AnswerConfig) == set()
    assert none_by_default(StopConfig) == set()
    assert none_by_default(Stack) == {"timeout_s", "retries", "api_key_env", "image_detail",
                                      "relevancy_weights", "capabilities"}


def test_run_json_records_what_an_agent_methods_episodes_ran_with():
    from efficienteqa.eval.runner import manifest

    white = manifest(spec("explore-eqa"), 3)
    # the options as given: the identity
    assert white["config"]["answer"]["confidence"] == "verbalized"
    assert white["method_config"]["answer"]["confidence"] == "token"
    assert white["method_config"]["stop"]["enabled"] is False
    assert white["method_config"]["answer"]["answer_at"] == "best-step"
    black = manifest(spec("explore-eqa-blackbox"), 3)["method_config"]
    assert black["answer"]["confidence"] == "verbalized"
    assert manifest(spec("blind"), 3)["method_config"] is None
    assert manifest(spec(), 3)["method_config"] is None  # a user's module:function


@pytest.mark.parametrize("relevancy", ["vlm-match", "blip2-itm"])
def test_blind_needs_no_image_relevancy_scorer(tmp_path, monkeypatch, relevancy):
    """Blind answers from the question alone: an image relevancy scorer (vlm-match, or BLIP-2
    without weights here) is not built, so the episode is answered, not failed."""
    from efficienteqa.models.stub import StubChatModel

    monkeypatch.setattr("efficienteqa.models.backends.build_chat_model",
                        lambda backend: StubChatModel(["2; 80"]))
    run_eval(spec("blind", stack=Stack(relevancy=relevancy, perception="rgb")), questions(1),
             tmp_path, prepare=False)
    (row,) = lines(tmp_path)
    assert row["status"] == "done", row.get("error")
    assert row["answer"] == "2"


def test_a_failed_episode_keeps_the_steps_and_the_calls_it_paid_for(tmp_path):
    """An episode that fails at its answer call has explored and called the
    model; its row counts those calls (``usage``) beside the error."""
    run_eval(spec("eval_stubs:fails_late"), questions(1), tmp_path, prepare=False)
    (row,) = lines(tmp_path)
    assert row["status"] == "failed" and "HTTP 400" in row["error"]
    assert row["steps"] == 3
    assert row["usage"]["calls"] == 4 and row["usage"]["prompt_tokens"] == 400


def test_a_folder_with_episodes_but_no_run_json_is_refused(tmp_path):
    """Deleting run.json must not let another configuration adopt the episodes."""
    run_eval(spec(), questions(2), tmp_path, prepare=False)
    (tmp_path / "run.json").unlink()
    with pytest.raises(EfficientEQAError, match="holds episodes but no run.json"):
        run_eval(spec("eval_stubs:peek"), questions(2), tmp_path, prepare=False)


def test_resuming_with_other_houses_or_simulator_is_refused(tmp_path):
    run_eval(spec(assets="builtin"), questions(1), tmp_path, prepare=False)
    with pytest.raises(EfficientEQAError, match="another assets"):
        run_eval(spec(assets="sh3d"), questions(2), tmp_path, prepare=False)
    with pytest.raises(EfficientEQAError, match="another env"):
        run_eval(spec(assets="builtin", env="habitat"), questions(2), tmp_path, prepare=False)
    old = json.loads((tmp_path / "run.json").read_text())  # a run recorded before the keys
    for key in ("assets", "env", "hm3d_root"):
        old.pop(key)
    (tmp_path / "run.json").write_text(json.dumps(old))
    assert run_eval(spec(assets="sh3d"), questions(2), tmp_path, prepare=False).ran == 1


@pytest.mark.parametrize("text", ["[1, 2]", "\"run\"", "null"])
def test_a_run_json_that_is_not_an_object_is_one_line(tmp_path, text):
    (tmp_path / "run.json").write_text(text)
    with pytest.raises(EfficientEQAError, match="is not a run's JSON object"):
        run_eval(spec(), questions(1), tmp_path, prepare=False)


def test_lines_that_are_not_an_episode_are_skipped_and_foreign_ones_left_out(tmp_path):
    from efficienteqa.eval.records import read_run

    run_eval(spec(), questions(2), tmp_path, prepare=False)
    with (tmp_path / EPISODES_FILE).open("a") as f:
        f.write('{"id": ["a", "list"], "status": "done"}\n[1]\n')
        f.write(json.dumps({"id": "x", "method": "blind", "status": "done"}) + "\n")
    assert read_episodes(tmp_path / EPISODES_FILE).torn == 2
    _, episodes = read_run(tmp_path)
    assert sorted(episodes.by_id) == ["toy/000", "toy/001"] and episodes.foreign == 1


def test_lines_of_no_question_of_the_run_are_not_counted(tmp_path):
    """Fault trial 1.11: valid lines whose id is none of the run's questions were counted:
    the report said "3 of 2" and took its accuracy over them. run.json lists the run's
    questions, every command's (a larger --limit adds its own), and only these count; the
    others are skipped and said to be, as torn lines are."""
    from efficienteqa.eval.records import RUN_FILE, read_run
    from efficienteqa.eval.tables import read_summaries

    run_eval(spec(), questions(2), tmp_path, prepare=False)
    with (tmp_path / EPISODES_FILE).open("a") as f:
        for row in ({"id": 5}, {"id": None}, {"id": "synthetic/99999/q0", "status": "done"},
                    {"id": "toy/999", "method": "eval_stubs:echo", "status": "done"}):
            f.write(json.dumps(row) + "\n")
    _, episodes = read_run(tmp_path)
    assert sorted(episodes.by_id) == ["toy/000", "toy/001"]
    assert (episodes.torn, episodes.foreign) == (2, 2)
    (summary,) = read_summaries([tmp_path])
    assert (summary.n, summary.planned, summary.torn) == (2, 2, 4)
    assert run_eval(spec(), questions(3), tmp_path, prepare=False).ran == 1  # --limit 3
    run_eval(spec(), questions(1), tmp_path, prepare=False)  # --limit 1 forgets none
    run = json.loads((tmp_path / RUN_FILE).read_text())
    assert run["question_ids"] == ["toy/000", "toy/001", "toy/002"] and run["questions"] == 3
    (summary,) = read_summaries([tmp_path])
    assert (summary.n, summary.planned, summary.torn) == (3, 3, 4)


def test_the_progress_bar_counts_only_the_questions_asked(tmp_path):
    """Fault trial 1.11: a done line of another id counted as done before, so the bar of a
    resumed run ended at "9/8"."""
    import io

    from rich.console import Console

    from efficienteqa.cli.progress import eval_progress, say_failures

    append_episode(tmp_path / EPISODES_FILE, {"id": "toy/000", "status": "done"})
    append_episode(tmp_path / EPISODES_FILE, {"id": "synthetic/99999/q0", "status": "done"})
    append_episode(tmp_path / EPISODES_FILE, {"id": "other", "status": "failed", "error": "E1"})
    shown = io.StringIO()
    console = Console(file=shown, width=100)
    with eval_progress(console, "echo", ["toy/000", "toy/001"], tmp_path) as on_episode:
        on_episode({"id": "toy/001", "status": "failed", "error": "E2"})
    append_episode(tmp_path / EPISODES_FILE, {"id": "toy/001", "status": "failed", "error": "E2"})
    say_failures(console, tmp_path, 1, ["toy/000", "toy/001"])
    text = shown.getvalue()
    assert "2/2" in text and "3/2" not in text
    assert "1 x E2" in text and "E1" not in text


def test_a_second_run_into_the_same_folder_fails_at_once(tmp_path):
    from efficienteqa.eval.records import run_lock

    with run_lock(tmp_path), pytest.raises(EfficientEQAError, match="another run is writing"):
        run_eval(spec(), questions(1), tmp_path, prepare=False)
    assert run_eval(spec(), questions(1), tmp_path, prepare=False).ran == 1  # released


def test_a_full_disk_is_one_line_and_a_short_write_is_finished(tmp_path, monkeypatch):
    import errno

    from efficienteqa.eval import records

    real, calls = os.write, []

    def short(fd, data):  # the first write takes 5 bytes only
        calls.append(len(data))
        return real(fd, data[:5] if len(calls) == 1 else data)

    monkeypatch.setattr(records.os, "write", short)
    append_episode(tmp_path / "e.jsonl", {"id": "a", "status": "done"})
    assert json.loads((tmp_path / "e.jsonl").read_text()) == {"id": "a", "status": "done"}

    def full(fd, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(records.os, "write", full)
    with pytest.raises(EfficientEQAError, match="No space left on device"):
        append_episode(tmp_path / "e.jsonl", {"id": "b", "status": "done"})


@pytest.mark.parametrize("name", ["run.json", EPISODES_FILE])
def test_a_run_file_that_is_a_folder_is_one_line(tmp_path, name):
    """Fault trial 2.16: ``IsADirectoryError`` tracebacks from eval and report."""
    from efficienteqa.eval.records import read_run

    run_eval(spec(), questions(1), tmp_path, prepare=False)
    (tmp_path / name).unlink()
    (tmp_path / name).mkdir()
    for call in (lambda: run_eval(spec(), questions(2), tmp_path, prepare=False),
                 lambda: read_run(tmp_path)):
        with pytest.raises(EfficientEQAError, match=f"cannot read .*{name}: Is a directory"):
            call()


def _unwritable(monkeypatch, after: int = 0) -> None:
    """``episodes.jsonl`` made unwritable (``chattr +i``) after ``after`` opens. Simulated:
    these tests run as root, which a chmod does not stop, so the open raises as it would."""
    import errno

    from efficienteqa.eval import records

    real, opens = records._open_for_append, []

    def open_for_append(path):
        opens.append(path)
        if len(opens) > after:
            raise PermissionError(errno.EPERM, "Operation not permitted")
        return real(path)

    monkeypatch.setattr(records, "_open_for_append", open_for_append)


def test_an_unwritable_episodes_file_is_refused_before_any_episode(tmp_path, monkeypatch):
    """Fault trial 2.16: an immutable episodes.jsonl on resume ran an episode, then lost its
    result to a ``PermissionError`` traceback. The resume is refused before any episode."""
    from efficienteqa.eval import runner

    run_eval(spec(), questions(1), tmp_path, prepare=False)
    _unwritable(monkeypatch)
    ran = []
    monkeypatch.setattr(runner, "run_episode", lambda *args: ran.append(args))
    with pytest.raises(EfficientEQAError, match="cannot write .*episodes.jsonl: Operation not "
                                                "permitted .make it writable"):
        run_eval(spec(), questions(3), tmp_path, prepare=False)
    assert not ran


def test_a_line_that_cannot_be_written_names_its_episode_and_resumes(tmp_path, monkeypatch):
    """Fault trial 2.16: episodes.jsonl made unwritable during a run. The episode whose line
    could not be written is named in one line, and the same command runs it again."""
    _unwritable(monkeypatch, after=1)  # toy/000's line is written, then no more
    with pytest.raises(EfficientEQAError) as err:
        run_eval(spec(), questions(3), tmp_path, prepare=False)
    message = str(err.value)
    assert "Operation not permitted; the result of episode toy/001 is not saved" in message
    assert "the same command resumes the run" in message and "\n" not in message
    assert [r["id"] for r in lines(tmp_path)] == ["toy/000"]
    monkeypatch.undo()
    again = run_eval(spec(), questions(3), tmp_path, prepare=False)
    assert (again.ran, again.skipped) == (2, 1)
    assert sorted(r["id"] for r in lines(tmp_path)) == [q.id for q in questions(3)]


def test_a_run_resumes_with_another_timeout_or_retries_but_not_another_server(tmp_path):
    run_eval(spec(), questions(1), tmp_path, prepare=False)
    assert run_eval(spec(stack=Stack(timeout_s=5.0, retries=0)), questions(2), tmp_path,
                    prepare=False).ran == 1
    with pytest.raises(EfficientEQAError, match="another stack"):
        run_eval(spec(stack=Stack(image_format="png")), questions(3), tmp_path, prepare=False)


def test_white_box_explore_eqa_is_refused_before_the_first_episode(tmp_path, monkeypatch):
    """Refused once, in one line, not failed per episode."""
    from efficienteqa.models.base import Capabilities
    from efficienteqa.models.stub import StubChatModel

    monkeypatch.setattr("efficienteqa.models.backends.build_chat_model",
                        lambda backend: StubChatModel(["x"], capabilities=Capabilities(
                            images=True, logprobs=False)))
    with pytest.raises(EfficientEQAError, match="does not return token log-probabilities"):
        run_eval(spec("explore-eqa", stack=Stack(perception="rgb", relevancy="vlm-match")),
                 questions(2), tmp_path)
    assert not read_episodes(tmp_path / EPISODES_FILE).by_id  # no episode was run
