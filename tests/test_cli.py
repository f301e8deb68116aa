import importlib.util
import json
import sys

import pytest

from conftest import needs_egl, needs_small_model
from efficienteqa.errors import EfficientEQAError


@needs_egl
def test_scenes_generate_writes_every_file(cli, tmp_path):
    result = cli("scenes", "generate", "--seed", "5", "--out", str(tmp_path), "--assets", "builtin")
    assert result.returncode == 0, result.stderr
    house = json.loads((tmp_path / "house.json").read_text())
    assert house["seed"] == 5 and house["objects"]
    lines = (tmp_path / "questions.jsonl").read_text().splitlines()
    assert len(lines) >= 5 and all(json.loads(line)["answer"] for line in lines)
    assert (tmp_path / "map.png").read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "views.png").read_bytes()[:4] == b"\x89PNG"


def test_missing_furniture_is_one_line_naming_the_fix(cli, tmp_path):
    import os

    env = {**os.environ, "EFFICIENTEQA_FURNITURE_DIR": str(tmp_path / "none"),
           "EFFICIENTEQA_CACHE": str(tmp_path / "cache")}
    result = cli("scenes", "generate", "--out", str(tmp_path / "out"), env=env)
    assert result.returncode == 1
    assert "apt-get install sweethome3d-furniture" in result.stdout
    assert "Traceback" not in result.stdout + result.stderr
    assert len(result.stdout.strip().splitlines()) == 1


def test_models_install_refuses_an_unknown_model_before_anything_slow(cli, tmp_path):
    """Checked before the llama.cpp runtime is built or any weights are downloaded."""
    import os

    cache = tmp_path / "cache"
    result = cli("models", "install", "no-such-model", env={**os.environ, "EFFICIENTEQA_CACHE": str(cache)})
    assert result.returncode == 1 and "unknown local model 'no-such-model'" in result.stdout
    assert "Traceback" not in result.stdout + result.stderr
    assert not (cache / "wheels").exists() and not (cache / "models").exists()


def test_ask_with_a_bad_scene_start_or_model_is_one_line(cli):
    for args, message in ((["--scene", "hm3d:00800"], "needs Habitat-Sim"),
                          (["--scene", "mp3d:17DRP5sb8fy"], "unknown scene"),
                          (["--scene", "synthetic:1", "--env", "habitat"], "not a Habitat scene"),
                          (["--episode", "x", "--dataset", "synthetic"], "no question 'x'"),
                          (["--scene", "synthetic:x"], "needs an integer seed"),
                          (["--start", "1,2"], "cannot read the start pose"),
                          (["--start", "nan,0,0"], "is not finite"),
                          (["--scene", "synthetic:-1"], "integer seed of 0 or more"),
                          (["--start", "100,100,0", "--assets", "builtin"], "is not on the floor"),
                          (["--vlm", "gpt-4o", "--assets", "builtin"], "cannot read --backends.vlm")):
        result = cli("ask", "Where is the sofa?", *args)
        assert result.returncode == 1, (args, result.stdout, result.stderr)
        assert message in result.stdout and "Traceback" not in result.stdout + result.stderr


@pytest.mark.trial("N.15")
@pytest.mark.parametrize("command", ["ask", "eval"])
def test_relevancy_weights_that_do_not_exist_fail_at_once(cli, command, tmp_path):
    """Fault trial N.15: a traceback after 16 s of loading MiniLM; now one line before any
    scene, model or output folder."""
    question = ["Where is the sofa?"] if command == "ask" else ["--limit", "1"]
    result = cli(command, *question, "--backends.relevancy", "minilm",
                  "--backends.relevancy-weights", "/nonexistent", "--out", str(tmp_path / "out"))
    assert result.returncode == 1, result.stdout + result.stderr
    assert "relevancy weights '/nonexistent' are not a folder" in result.stdout
    assert len(result.stdout.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()


def test_the_paper_preset_fills_what_is_not_given(cli, tmp_path, hm_eqa_dir):
    """``--preset paper``: HM-EQA's first 100 in Habitat-Sim with GPT-4o at T = 1, BLIP-2 and
    Z_th 3; an option given on the command line wins. Without Habitat-Sim the run stops before
    its first episode with the conda line."""
    import os

    env = {**os.environ, "EFFICIENTEQA_CACHE": str(tmp_path / "cache")}
    result = cli("eval", "--preset", "paper", "--top-k", "3", "--hm-eqa-path", str(hm_eqa_dir),
                  "--hm3d-root", str(tmp_path), "--out", str(tmp_path / "run"), env=env)
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert (run["dataset"], run["questions"], run["env"]) == ("hm-eqa", 100, "habitat")
    assert run["stack"]["vlm"] == "openai:gpt-4o-2024-05-13" and run["stack"]["temperature"] == 1.0
    assert (run["stack"]["perception"], run["stack"]["relevancy"]) == ("rgb", "blip2-itm")
    assert run["config"]["stop"]["z_th"] == 3.0 and run["config"]["answer"]["top_k"] == 3
    assert run["judge_mode"] == "openeqa"
    if importlib.util.find_spec("habitat_sim") is None:
        assert result.returncode == 1 and "conda install" in result.stdout



def test_ask_with_the_paper_preset_asks_hm_eqa_in_habitat(cli, tmp_path, hm_eqa_dir):
    """``ask --dataset`` had a literal default the preset could not fill, so
    ``--preset paper --episode 0`` opened a synthetic house and failed as "not a Habitat scene".
    It is HM-EQA's episode 0 in Habitat-Sim; without habitat_sim, one line naming what is needed."""
    import os

    env = {**os.environ, "EFFICIENTEQA_CACHE": str(tmp_path / "cache")}
    args = ("ask", "--preset", "paper", "--episode", "0", "--hm-eqa-path", str(hm_eqa_dir),
            "--out", str(tmp_path / "out"))
    no_scenes = cli(*args, env=env)
    assert no_scenes.returncode == 1, no_scenes.stdout + no_scenes.stderr
    assert "not a Habitat scene" not in no_scenes.stdout
    assert "hm3d:" in no_scenes.stdout and "needs Habitat-Sim" in no_scenes.stdout
    assert len(no_scenes.stdout.strip().splitlines()) == 1
    if importlib.util.find_spec("habitat_sim") is None:
        result = cli(*args, "--hm3d-root", str(tmp_path), env=env)
        assert result.returncode == 1, result.stdout + result.stderr
        assert "Habitat-Sim is not installed" in result.stdout and "conda install" in result.stdout
        assert len(result.stdout.strip().splitlines()) == 1
        assert "Traceback" not in result.stdout + result.stderr

@needs_egl
@needs_small_model
@pytest.mark.slow
def test_ask_runs_an_episode_with_the_small_real_model(cli, tmp_path, small_model_cache):
    try:
        result = cli("ask", "What colour is the desk in the office?", "--scene", "synthetic:4",
                      "--assets", "builtin", "--max-steps", "2", "--vlm", "local:smollm2-135m",
                      "--relevancy", "overlap", "--grouping", "rules", "--out", str(tmp_path / "out"))
    finally:
        cli("models", "stop", "smollm2-135m")
    assert result.returncode == 0, result.stdout + result.stderr
    assert "answer:" in result.stdout and "steps: 2 of 2" in result.stdout
    assert "reference answer: black" in result.stdout and "report.html" in result.stdout
    record = json.loads((tmp_path / "out" / "episode.json").read_text())
    assert record["backends"]["vlm"] == "smollm2-135m" and record["backends"]["relevancy"] == "word-overlap"
    replies = [e["reply"] for e in record["model"]["exchanges"]]  # real replies, all the way
    assert replies and all(isinstance(t, str) for t in replies)
    assert record["model"]["completion_tokens"] > 0 and 0.0 <= record["confidence"] <= 1.0
    assert (tmp_path / "out" / "report.html").stat().st_size > 10_000


def test_eval_exits_non_zero_when_an_episode_failed_and_a_re_run_resumes_it(cli, tmp_path):
    import os
    from pathlib import Path

    from efficienteqa.datasets import load_dataset

    first = load_dataset("synthetic", limit=2)[0].id
    tests = str(Path(__file__).parent)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([tests, os.environ.get("PYTHONPATH", "")]),
           "EQA_STUB_FAIL": first}
    args = ("eval", "--method", "eval_stubs:echo", "--limit", "2", "--judge", "none",
            "--out", str(tmp_path / "run"))
    failed = cli(*args, env=env)
    assert failed.returncode == 1, failed.stdout + failed.stderr
    assert "1 episode(s) failed" in failed.stdout and "Traceback" not in failed.stdout
    assert "1 x RuntimeError: scripted failure of" in failed.stdout  # why, grouped
    del env["EQA_STUB_FAIL"]
    resumed = cli(*args, env=env)
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    assert "1 episodes run, 1 already done, 0 failed" in resumed.stdout


@pytest.mark.parametrize("command", ["ask", "eval"])
def test_an_unwritable_out_folder_fails_before_the_work(cli, command, tmp_path):
    """The episode used to be explored, then lost to a traceback."""
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    question = ["Where is the sofa?"] if command == "ask" else ["--limit", "1"]
    result = cli(command, *question, "--out", str(blocker / "out"))
    assert result.returncode == 1, result.stdout + result.stderr
    assert "cannot write to" in result.stdout and "Traceback" not in result.stdout + result.stderr
    assert "exploring" not in result.stdout


def test_ask_does_not_replace_another_questions_episode_nor_run_beside_another(cli, tmp_path,
                                                                              monkeypatch):
    """Fault trial N.11: two asks into one --out both succeeded and the folder kept only the
    second. A folder that another ask holds is refused at once (its lock, as eval's), and one
    that holds another question's episode unless --overwrite; the same question replaces its
    own, and the default folder (out/ask) is a scratch folder each ask replaces. A bad seed
    stops each run that gets past these checks, before any scene or model."""
    from efficienteqa.eval.records import run_lock

    monkeypatch.chdir(tmp_path)

    def ask(*args):
        result = cli("ask", *args, "--scene", "synthetic:x")
        assert result.returncode == 1 and "Traceback" not in result.stdout + result.stderr
        assert len(result.stdout.strip().splitlines()) == 1, result.stdout
        return result.stdout

    for folder in (tmp_path / "named", tmp_path / "out" / "ask"):
        folder.mkdir(parents=True)
        (folder / "episode.json").write_text(json.dumps({"question": "What is on the desk?"}))
    named = str(tmp_path / "named")
    assert "named holds the episode of another question: 'What is on the desk?'" in ask(
        "Where is the sofa?", "--out", named)
    passed = "needs an integer seed"
    assert passed in ask("Where is the sofa?", "--out", named, "--overwrite")
    assert passed in ask("what is on the  DESK?", "--out", named)  # the same question
    assert passed in ask("Where is the sofa?")  # out/ask
    with run_lock(tmp_path / "named"):
        assert f"another run is writing to {named}" in ask("What is on the desk?", "--out", named)
    assert json.loads((tmp_path / "named" / "episode.json").read_text())["question"] == \
        "What is on the desk?"


def test_an_ask_folder_whose_files_cannot_be_written_is_refused_before_the_work(tmp_path):
    """Fault trial 2.16 for ask: episode.json or report.html a folder was found only when the
    explored episode was written; an episode.json that cannot be read is nobody's known
    question, so it is not replaced without --overwrite."""
    from efficienteqa.ask_plan import check_ask_folder

    for name in ("episode.json", "report.html"):
        (tmp_path / name).mkdir()
        with pytest.raises(EfficientEQAError, match=f"{name} is a folder"):
            check_ask_folder(tmp_path, "Where is the sofa?", overwrite=True)
        (tmp_path / name).rmdir()
    (tmp_path / "episode.json").write_text("[1, 2")
    with pytest.raises(EfficientEQAError, match="holds the episode of another question .use"):
        check_ask_folder(tmp_path, "Where is the sofa?", overwrite=False)
    check_ask_folder(tmp_path, "Where is the sofa?", overwrite=True)
    check_ask_folder(tmp_path / "new", "Where is the sofa?", overwrite=False)


def _stub_env():
    import os
    from pathlib import Path

    tests = str(Path(__file__).parent)
    return {**os.environ, "PYTHONPATH": os.pathsep.join([tests, os.environ.get("PYTHONPATH", "")])}


@pytest.mark.parametrize("name", ["run.json", "episodes.jsonl"])
def test_a_run_file_that_is_a_folder_is_one_line_before_the_work(cli, name, tmp_path):
    """Fault trial 2.16: ``IsADirectoryError`` tracebacks; now one line from eval and report."""
    (tmp_path / "run" / name).mkdir(parents=True)
    if name == "episodes.jsonl":
        (tmp_path / "run" / "run.json").write_text("{}")  # a run for report to read
    for args in (("eval", "--method", "eval_stubs:echo", "--limit", "1", "--judge", "none",
                  "--out", str(tmp_path / "run")), ("report", str(tmp_path / "run"))):
        result = cli(*args, env=_stub_env())
        assert result.returncode == 1, result.stdout + result.stderr
        assert f"{name}: Is a directory" in result.stdout, result.stdout
        assert "Traceback" not in result.stdout + result.stderr
        assert "episodes run" not in result.stdout


def test_paper_offline_runs_the_papers_configuration_on_the_offline_stack(cli, tmp_path):
    """``--preset paper-offline``: agent.PAPER_CONFIG with the VLM's semantic values on the
    synthetic questions and the default stack; tables name it as the committed paper row."""
    from dataclasses import asdict

    from efficienteqa.agent import PAPER_CONFIG
    from efficienteqa.eval.run_labels import settings, settings_label
    from efficienteqa.stack import Stack

    result = cli("eval", "--preset", "paper-offline", "--method", "eval_stubs:echo", "--limit", "1",
                  "--judge", "none", "--out", str(tmp_path / "run"), env=_stub_env())
    assert result.returncode == 0, result.stdout + result.stderr
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["config"] == json.loads(json.dumps(asdict(PAPER_CONFIG)))
    assert (run["dataset"], run["env"]) == ("synthetic", "synthetic")
    assert run["stack"] == {**json.loads(json.dumps(asdict(Stack()))), "explore_scorer": "vlm"}
    assert settings_label("efficienteqa", settings(run)) == "efficienteqa paper configuration"


def test_a_configuration_file_fills_what_the_command_line_leaves_out(cli, tmp_path):
    config = tmp_path / "mine.toml"
    config.write_text('base = "paper-offline"\ntop_k = 3\nz_th = 2\nassets = "builtin"\n'
                      'method = "eval_stubs:echo"\nlimit = 1\njudge = "none"\ndataset = "synthetic:4"\n')
    result = cli("eval", "--config", str(config), "--top-k", "4", "--out", str(tmp_path / "run"),
                  env=_stub_env())
    assert result.returncode == 0, result.stdout + result.stderr
    run = json.loads((tmp_path / "run" / "run.json").read_text())
    assert run["method"] == "eval_stubs:echo" and run["questions"] == 1
    assert run["config"]["answer"]["top_k"] == 4  # the command line wins
    assert run["config"]["stop"]["z_th"] == 2.0 and run["config"]["stop"]["rule"] == "paper"
    assert run["assets"] == "builtin"  # an option with a default of its own is filled too
    given = cli("eval", "--config", str(config), "--assets", "sh3d", "--out", str(tmp_path / "b"),
                 env=_stub_env())
    assert given.returncode == 0, given.stdout + given.stderr
    assert json.loads((tmp_path / "b" / "run.json").read_text())["assets"] == "sh3d"


@pytest.mark.parametrize("command", ["ask", "eval"])
def test_a_bad_configuration_is_one_line_before_any_work(cli, command, tmp_path):
    question = ["Where is the sofa?"] if command == "ask" else ["--limit", "1"]
    bad = tmp_path / "bad.toml"
    for text, message in (("topk = 3\n", "unknown option 'topk'"),
                          ('top_k = "3"\n', "must be an integer"),
                          ("top_k = \n", "is not valid TOML"),
                          (None, "cannot read the configuration")):
        if text is None:
            bad.unlink()
        else:
            bad.write_text(text)
        result = cli(command, *question, "--config", str(bad), "--out", str(tmp_path / "out"))
        assert result.returncode == 1, (text, result.stdout, result.stderr)
        assert message in result.stdout and "Traceback" not in result.stdout + result.stderr
        assert len(result.stdout.strip().splitlines()) == 1
        assert not (tmp_path / "out").exists()
    result = cli(command, *question, "--preset", "papr", "--out", str(tmp_path / "out"))
    assert result.returncode == 1 and "unknown preset 'papr'" in result.stdout


def test_ask_refuses_a_configuration_of_another_method(cli, tmp_path):
    result = cli("ask", "Where is the sofa?", "--preset", "explore-eqa", "--out", str(tmp_path / "o"))
    assert result.returncode == 1 and "method 'explore-eqa' is for eval" in result.stdout


@pytest.mark.parametrize("command", ["ask", "eval"])
def test_help_groups_the_options_in_panels(cli, command):
    """``--help-all`` in panels, in this order: what is asked, the method, its back-ends,
    the options beyond the paper, where the output goes (``--help`` leaves out the constants'
    panel)."""
    import os
    import re

    result = cli(command, "--help-all", env={**os.environ, "COLUMNS": "200", "NO_COLOR": "1",
                                          "TERM": "dumb"})
    assert result.returncode == 0, result.stderr
    panels: dict[str, list[str]] = {}
    current = ""
    for line in result.stdout.splitlines():
        title = re.match(r"^╭─ (.+?) ─", line)
        if title:
            current = title.group(1)
            panels[current] = []
        option = re.match(r"^│ [* ]*(--[a-z0-9.-]+)", line)
        if option and current:
            panels[current].append(option.group(1))
    names = [p for p in panels if p not in ("Arguments", "Options")]
    sections = ["Configuration", "Back-ends", "Back-ends: more", "Scene",
                "Explore (DESIGN 3.2-3.3)", "Explore (DESIGN 3.2-3.3): more",
                "Explore (DESIGN 3.2-3.3): constants", "Stop (DESIGN 3.4) and its gate",
                "Stop (DESIGN 3.4) and its gate: more", "Answer (DESIGN 3.5)",
                "Answer (DESIGN 3.5): more", "Evaluation"]
    own = ["Question", "Output"] if command == "ask" else ["Output"]
    assert sorted(names) == sorted(own + sections)
    where = {option: panel for panel, options in panels.items() for option in options}
    expected = {"--eval.dataset": "Evaluation", "--preset": "Configuration",
                "--config": "Configuration", "--stop.z-th": "Stop (DESIGN 3.4) and its gate",
                "--stop.z-gated": "Stop (DESIGN 3.4) and its gate",
                "--stop.gate": "Stop (DESIGN 3.4) and its gate",
                "--answer.top-k": "Answer (DESIGN 3.5)",
                "--backends.explore-scorer": "Back-ends", "--backends.vlm": "Back-ends",
                "--backends.relevancy": "Back-ends", "--scene.env": "Scene",
                "--explore.steering": "Explore (DESIGN 3.2-3.3)",
                "--explore.refusal-retries": "Explore (DESIGN 3.2-3.3): more",
                "--explore.sfe.view-gain": "Explore (DESIGN 3.2-3.3): constants",
                "--explore.target.room-tries": "Explore (DESIGN 3.2-3.3): constants",
                "--out": "Output"}
    expected.update({"--episode": "Question"} if command == "ask" else
                    {"--eval.method": "Evaluation", "--eval.limit": "Evaluation",
                     "--eval.judge": "Evaluation", "--eval.reports": "Evaluation"})
    assert {option: where.get(option) for option in expected} == expected
    assert "--z-th" not in where  # the flat names of before the sections work, unlisted


def test_judge_grades_with_evals_default_judge_unless_told(tmp_path, monkeypatch):
    """`efficienteqa judge` had its own literal default judge; it is eval's and RunSpec's
    (eval.judge_prompts.DEFAULT_JUDGE), in the mode eval gives it (DEFAULT_JUDGE_MODE, auto: yes-prob
    for a local model)."""
    from typer.testing import CliRunner

    from efficienteqa import cli
    from efficienteqa.eval import judge_prompts, methods, runner
    from efficienteqa.eval.methods import RunSpec, default_judge

    calls = []
    monkeypatch.setattr(runner, "rejudge", lambda run, judge, mode: calls.append((judge, mode)) or (0, 0.0))
    monkeypatch.setattr(judge_prompts, "DEFAULT_JUDGE", "local:smollm2-135m")  # whatever the default is
    monkeypatch.setattr(methods, "DEFAULT_JUDGE", "local:smollm2-135m")  # as imported there
    result = CliRunner().invoke(cli.app, ["judge", str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert default_judge("hm-eqa") == "local:smollm2-135m"
    result = CliRunner().invoke(cli.app, ["judge", str(tmp_path), "--judge", "openai:gpt-4o"])
    assert result.exit_code == 0, result.output
    assert calls == [("local:smollm2-135m", "yes-prob"), ("openai:gpt-4o", "grade")]
    # RunSpec, made without the CLI, resolves the same default mode for the same judges.
    assert [RunSpec.of("blind", "hm-eqa", judge=j).judge_mode for j in ("local:m", "openai:gpt-4o")] == [
        "yes-prob", "grade"]


def test_an_errors_brackets_are_printed_as_text(tmp_path, monkeypatch, capsys):
    """The one-line error is plain text: rich read "[section]" (or 'efficienteqa[ray]') in a
    fix as markup and dropped it."""
    from efficienteqa import cli

    monkeypatch.setattr(sys, "argv", ["efficienteqa", "config", "--config", str(tmp_path / "no.toml")])
    with pytest.raises(SystemExit) as exited:
        cli.main()
    assert exited.value.code == 1
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 1 and "give a TOML file of [section] tables" in lines[0], lines
