"""The configuration tree: one nested set of dataclasses owns every knob of a run, and the CLI,
the configuration files and the record are all made from it. Every value is reachable by its
dotted name from the command line and from a file; flat names of before the sections still
read; old records nest to the same tree."""

from __future__ import annotations

import functools
import json
import typing
from dataclasses import asdict, fields
from pathlib import Path

import pytest
import typer

from efficienteqa.agent import AgentConfig
from efficienteqa.cli import app
from efficienteqa.cli.options import given_values, tree_leaves
from efficienteqa.config.knobs import Leaf, build, flat_names, leaves
from efficienteqa.config.presets import load_config
from efficienteqa.config.run import RunConfig

ROOT = Path(__file__).resolve().parents[1]


def _other(leaf: Leaf) -> typing.Any:
    """A value unlike ``leaf``'s default, of its type."""
    if leaf.kind is bool:
        return not leaf.default
    if leaf.kind is int:
        return (leaf.default or 0) + 1
    if leaf.kind is float:
        return (leaf.default or 0.0) + 0.5
    if leaf.kind is dict:
        return {"a": 1.5}
    if leaf.kind is Path:
        return Path("/somewhere")
    return "other"


def _cli(leaf: Leaf, value: typing.Any) -> list[str]:
    flag = "--" + ".".join(p.replace("_", "-") for p in leaf.path)
    if leaf.kind is bool:
        head = flag.rsplit(".", 1)[0]
        off = (leaf.off or "no_" + leaf.path[-1]).replace("_", "-")
        return [flag if value else f"{head}.{off}"]
    return [flag, json.dumps(value) if leaf.kind is dict else str(value)]


def _toml(leaf: Leaf, value: typing.Any) -> str:
    table = ".".join(leaf.path[:-1])
    if leaf.kind is dict:
        return f"[{'.'.join(leaf.path)}]\na = 1.5\n"
    text = (str(value).lower() if leaf.kind is bool else json.dumps(str(value))
            if leaf.kind in (str, Path) else repr(value))
    return f"[{table}]\n{leaf.path[-1]} = {text}\n"


@functools.cache
def _click_app():  # made once: typer builds the whole command tree each time (~40 ms)
    return typer.main.get_command(app)


def _parse(command: str, args: list[str]) -> dict:
    ctx = _click_app().commands[command].make_context(command, [*args, "--out", "x"],  # type: ignore[attr-defined]
                                                   resilient_parsing=False)
    chosen = tree_leaves() if command == "eval" else tree_leaves(
        ("backends", "scene", "explore", "stop", "answer"), {"eval": ("dataset", "hm_eqa_path")})
    return given_values(chosen, dict(ctx.params))


def test_every_value_of_the_tree_is_reachable_by_its_dotted_name_from_cli_and_file(tmp_path):
    every = leaves(RunConfig)
    assert len(every) > 120  # the sfe and target constants included
    for leaf in every:
        value = _other(leaf)
        assert _parse("eval", _cli(leaf, value)) == {leaf.dotted: value}, leaf.dotted
        path = tmp_path / "c.toml"
        path.write_text(_toml(leaf, value))
        assert load_config(path) == {leaf.dotted: value}, leaf.dotted


def test_ask_takes_every_value_but_the_evaluations():
    names = {leaf.dotted for leaf in tree_leaves(("backends", "scene", "explore", "stop",
                                                   "answer"), {"eval": ("dataset",
                                                                        "hm_eqa_path")})}
    assert {"eval.dataset", "stop.z_gated", "explore.sfe.view_gain"} <= names
    assert not names & {"eval.method", "eval.judge", "eval.workers"}
    assert _parse("ask", ["--stop.z-gated", "2"]) == {"stop.z_gated": 2.0}


@pytest.mark.parametrize(("args", "path", "value"), [
    (["--z-th", "2"], "stop.z_th", 2.0), (["--min-stop-step", "4"], "stop.min_step", 4),
    (["--stop-rule", "paper"], "stop.rule", "paper"), (["--no-early-stop"], "stop.enabled", False),
    (["--repeated-views"], "answer.distinct_views", False), (["--top-k", "3"], "answer.top_k", 3),
    (["--no-cache"], "backends.cache", False), (["--vlm", "local:x"], "backends.vlm", "local:x"),
    (["--method", "blind"], "eval.method", "blind"), (["--no-gate-final"], "stop.gate_final", False),
])
def test_the_flat_flags_of_before_the_sections_still_read(args, path, value):
    assert _parse("eval", args) == {path: value}


def test_the_dotted_name_wins_over_its_flat_alias():
    assert _parse("eval", ["--top-k", "3", "--answer.top-k", "7"]) == {"answer.top_k": 7}


def test_flat_names_are_unique_across_sections():
    """A flat name (an old record's key, an alias) reads as one field only."""
    seen: dict[str, str] = {}
    for section in fields(RunConfig):
        for f in fields(typing.get_type_hints(RunConfig)[section.name]):
            for name in filter(None, (f.name, f.metadata.get("alias"))):
                assert name not in seen, f"{name} in {seen.get(name)} and {section.name}"
                seen[name] = section.name
    assert flat_names(RunConfig)["min_stop_step"] == ("stop", "min_step")


def test_every_field_has_help_and_the_gate_threshold_sits_beside_z_th():
    shallow = [leaf for leaf in leaves(RunConfig) if len(leaf.path) == 2]
    assert all(leaf.help for leaf in shallow), [leaf.dotted for leaf in shallow if not leaf.help]
    stop = [leaf.path[1] for leaf in shallow if leaf.path[0] == "stop"]
    assert {"z_th", "z_gated", "gate", "gate_final"} <= set(stop)
    z_th = next(leaf for leaf in shallow if leaf.dotted == "stop.z_th")
    assert "stop.z_gated" in z_th.help  # it says which applies when
    beyond = {leaf.dotted for leaf in shallow if leaf.beyond}
    assert {"stop.gate", "stop.z_gated", "explore.steering"} <= beyond
    assert not beyond & {"stop.z_th", "answer.top_k", "explore.seed"}


def test_every_committed_run_nests_to_a_tree_the_dataclasses_build():
    """Old records (flat, formats 1 and 2) read as the tree's sections, and those build the
    agent's configuration with nothing left over."""
    from efficienteqa.eval.records import upgrade

    runs = sorted((ROOT / "results").rglob("run.json"))
    assert runs
    for path in runs:
        run = upgrade(json.loads(path.read_text()))
        for key in ("config", "method_config", "preset_config"):
            if isinstance(run.get(key), dict):
                assert set(run[key]) <= {"explore", "stop", "answer"}, (path, key)
                config = build(AgentConfig, run[key])
                assert isinstance(config, AgentConfig)
                if key == "config":
                    again = asdict(config)  # the tree round-trips
                    assert all(again[s][k] == v for s in run[key] for k, v in run[key][s].items()
                               if not isinstance(v, dict)), path


def test_ask_help_shows_the_openai_server_form_and_every_section(cli):
    import os

    env = {**os.environ, "COLUMNS": "200", "NO_COLOR": "1", "TERM": "dumb"}
    result = cli("ask", "--help", env=env)
    assert result.returncode == 0, result.said
    out = result.stdout
    assert "openai:MODEL@BASE_URL" in out
    assert "--stop.z-gated" in out and "--help-all" in out
    assert "Beyond the paper." in out
    result = cli("ask", "--help-all", env=env)
    assert result.returncode == 0 and "--explore.sfe.view-gain" in result.stdout


def test_constants_that_cannot_act_are_refused_in_one_line():
    from efficienteqa.config.presets import resolve
    from efficienteqa.errors import EfficientEQAError

    assert resolve({"explore.sfe.view_gain": False}).run.explore.sfe == {"view_gain": False}
    assert resolve({"explore.target.room_tries": 3}).run.explore.target == {"room_tries": 3}
    for given, preset, words in (({"explorer": "random"}, None,
                                  "explore.explorer random does not act: method efficienteqa "
                                  "sets it"),
                                 ({"answer.confidence": "token"}, "default", "sets it"),
                                 ({"explore.sfe.view_gain": False}, "random",
                                  "explores with 'random'"),
                                 ({"explore.target.room_tries": 3, "steering": "none"}, None,
                                  "does not steer"),
                                 ({"explore.target.room_tries": 3}, "explore-eqa",
                                  "explore-eqa never steers")):
        with pytest.raises(EfficientEQAError, match=words) as raised:
            resolve(given, preset)
        assert "\n" not in str(raised.value)
    # ask runs the agent as configured: there the explorer acts, and so do its constants
    run = resolve({"explorer": "frontier-only", "explore.sfe.view_gain": False}, by_method=False)
    assert run.run.explore.explorer == "frontier-only"
    with pytest.raises(EfficientEQAError, match="explores with 'random'"):
        resolve({"explorer": "random", "explore.sfe.view_gain": False}, by_method=False)


@pytest.mark.parametrize("preset", ["default", "paper-offline", "explore-eqa-per-token", "paper"])
def test_config_prints_a_file_that_reads_back_to_the_same_run(tmp_path, preset):
    """`efficienteqa config` shows what a run would use, as a --config file: read back, the same
    run (the method's own settings are comments, as eval refuses them given otherwise)."""
    from efficienteqa.config.presets import resolve, to_toml

    given = {"stop.z_gated": 2.0} if preset == "default" else {"answer.top_k": 3} if (
        preset == "explore-eqa-per-token") else {
        "stop.z_th": 2.0, "explore.sfe.view_gain": False, "explore.sfe.frontier.temp_free": 1.5,
        "backends.vlm": 'openai:m@http://h/v1', "scene.hm3d_root": Path("/data/hm3d")}
    run = resolve(given, preset).run
    path = tmp_path / "run.toml"
    path.write_text(to_toml(run))
    assert resolve({}, config_file=path).run == run


def test_the_config_command_prints_the_run_it_would_make(cli, tmp_path):
    from efficienteqa.config.presets import resolve

    result = cli("config", "--preset", "explore-eqa", "--answer.top-k", "3")
    assert result.returncode == 0, result.said
    out = result.stdout
    assert "[stop]\n" in out and "top_k = 3" in out and "(set by eval.method)" in out
    path = tmp_path / "c.toml"
    path.write_text(out)
    assert resolve({}, config_file=path).run == resolve({"top_k": 3}, "explore-eqa").run


def test_the_cli_makes_its_options_without_loading_the_agent():
    """The configuration's dataclasses are light: making the CLI's options from them loads no
    numba, scipy, rerun or agent code (they are imported when a command runs)."""
    import subprocess
    import sys

    code = ("import sys, efficienteqa.cli, typer.main; typer.main.get_command(efficienteqa.cli.app); "
            "print(sorted(m for m in ('numba', 'scipy', 'torch', 'rerun', 'efficienteqa.agent', "
            "'efficienteqa.stack', 'efficienteqa.report.rerun_log', 'efficienteqa.report.rerun_target') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("given,preset,words", [
    ({"stop.z_gated": 2.0}, "paper-offline", "leaves the stop to Z_th"),
    ({"stop.gate_final": False, "stop.gate": "none"}, None, "does not judge every frame"),
    ({"stop.sigma_floor": 0.2}, "paper-offline", "has no 'floor' part"),
    ({"stop.sim_abs": 0.5, "stop.rule": "lookback"}, None, "has no 'absolute' part"),
    ({"backends.sightings": "model"}, "paper-offline", "nothing reads the question's target"),
    ({"explore.reading": "model"}, "paper-offline", "nothing reads the question's target"),
    ({"backends.grouping": "rules", "answer.answer": "direct"}, None, "nothing to group"),
    ({"stop.z_th": 2.0, "stop.enabled": False, "stop.gate": "none"}, None, "early stop is off"),
])
def test_a_setting_the_run_would_ignore_is_refused_and_shown_as_ignored(given, preset, words):
    """One list says when a setting acts (``inert.inert``): given on the command line where it
    cannot act, it is refused in one line; where a preset sets it, ``config`` says so."""
    from efficienteqa.config.presets import resolve, to_toml
    from efficienteqa.errors import EfficientEQAError

    with pytest.raises(EfficientEQAError, match=words) as raised:
        resolve(given, preset)
    assert "\n" not in str(raised.value) and "does not act" in str(raised.value)
    path, value = next(iter(given.items()))
    shown = to_toml(resolve({k: v for k, v in given.items() if k != path}, preset).run)
    key = path.split(".")[1]
    assert any(line.startswith(f"{key} = ") and "# does not act" in line
               for line in shown.splitlines()), shown


def test_config_marks_what_the_paper_preset_leaves_unused():
    from efficienteqa.config.presets import resolve, to_toml

    shown = to_toml(resolve({}, "paper-offline").run).splitlines()
    ignored = {line.split(" = ")[0] for line in shown if "# does not act" in line}
    assert {"z_gated", "gate_final", "sigma_floor", "sim_abs", "sightings"} <= ignored
    assert not any(line.startswith("z_th = ") and "# does not act" in line for line in shown)


def test_each_constant_says_whether_it_is_the_papers_or_the_projects():
    """``--help-all``: the frontier explorer's constants from ExploreEQA's SFE (DESIGN 3.2) say
    so; the project's own (the options PAPER_SFE turns off, the steering's) are beyond it."""
    from efficienteqa.cli.options import _parameter
    from efficienteqa.config.knobs import leaves
    from efficienteqa.config.run import RunConfig
    from efficienteqa.explore.settings import PAPER_SFE, PAPER_SFE_CONSTANTS

    def help_of(path: str) -> str:
        leaf = next(x for x in leaves(RunConfig) if ".".join(x.path) == path)
        parameter = _parameter(leaf)
        assert parameter is not None
        return str(parameter.default.help)

    assert "The paper's" in help_of("explore.sfe.frontier.temp_free")
    assert "The paper's" in help_of("explore.sfe.backoff_m")
    for name in PAPER_SFE:  # what the paper preset turns off is the project's
        assert name not in PAPER_SFE_CONSTANTS
        assert "Beyond the paper" in help_of(f"explore.sfe.{name}")
    assert "Beyond the paper" in help_of("explore.target.room_tries")
