"""run.json's format: every default is a value, so typing it is the same run; a published
format-1 run (None for "the default") resumes with the command that made it; a run's table
label is read against the named configuration it recorded, not against today's files."""

from __future__ import annotations

import json
import shutil
from dataclasses import asdict, replace
from pathlib import Path

import pytest

from conftest import needs_default_model, needs_egl
from efficienteqa.agent import AgentConfig
from efficienteqa.config import presets
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval import run_labels
from efficienteqa.eval.judge_prompts import DEFAULT_JUDGE
from efficienteqa.eval.methods import RunSpec
from efficienteqa.eval.records import RUN_FILE, RUN_FORMAT, open_run, read_run, upgrade
from efficienteqa.eval.run_labels import label
from efficienteqa.eval.runner import manifest
from efficienteqa.stack import Stack, parse_vlm

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED = ROOT / "results" / "main-heldout"
# Format-1 run.json files of two runs that left results/ (made by uncommitted trees): the
# default of 9bccb3c and white-box ExploreEQA reading per-token probabilities, at 6ade1d2.
FORMAT_1 = ROOT / "tests" / "data" / "format-1"
# The settings whose default format 1 recorded as None, each typed as its documented default.
TYPED_DEFAULTS = {"answer_every_step": False, "answer_probability": "product",
                  "token_answer": "short", "refusal_retries": 3, "stop_clearance_m": 0.45}


def format_1(row: str) -> Path:
    return FORMAT_1 / f"{row}.{RUN_FILE}"


def published_copy(tmp_path: Path, row: str) -> Path:
    """A copy of a format-1 run.json in a folder of its own."""
    folder = tmp_path / row
    folder.mkdir()
    shutil.copy(format_1(row), folder / RUN_FILE)
    return folder


def main_table_spec(row: str, **config: object) -> RunSpec:
    """The RunSpec `efficienteqa eval --preset ROW --judge local:qwen2.5-coder-1.5b` builds
    (experiments/main_table.sh), with ``config`` typed on top."""
    resolved = presets.resolve(config, row)
    run = resolved.run
    return RunSpec(replace(run, eval=replace(run.eval, dataset="synthetic")), judge=DEFAULT_JUDGE,
                   preset=resolved.preset, preset_agent=resolved.preset_run.agent)


def published_spec(**config: object) -> RunSpec:
    """The command that made the default of 9bccb3c (``format_1("default-v2")``): the default
    row as it was, its question read by rules and matched as words."""
    return main_table_spec("default", reading="rules", matching="words", gate_final=False,
                           map_extent="scene", count_from="views", question_words="asked",
                           **config)


def resume(folder: Path, spec: RunSpec) -> None:
    open_run(folder, manifest(spec, 48))


def test_the_published_format_1_run_is_none_where_a_default_was_meant():
    """The premise: format-1 runs recorded None for these settings."""
    run = json.loads(format_1("default-v2").read_text())
    assert "format" not in run and run["stack"]["temperature"] is None
    assert all(run["config"][k] is None for k in TYPED_DEFAULTS)


def test_a_published_format_1_run_resumes_with_the_same_command(tmp_path):
    folder = published_copy(tmp_path, "default-v2")
    resume(folder, published_spec())
    assert "format" not in json.loads((folder / RUN_FILE).read_text())  # left as it was


def test_typing_the_documented_defaults_is_the_same_run(tmp_path):
    folder = published_copy(tmp_path, "default-v2")
    typed = published_spec(**TYPED_DEFAULTS, temperature=0.0)
    assert typed.config == published_spec().config
    assert typed.stack == published_spec().stack
    resume(folder, typed)


@pytest.mark.parametrize("other", [{"answer_probability": "per-token"}, {"refusal_retries": 0},
                                   {"answer_every_step": True}, {"temperature": 1.0}])
def test_another_value_than_the_one_a_format_1_run_meant_is_another_run(tmp_path, other):
    folder = published_copy(tmp_path, "default-v2")
    with pytest.raises(EfficientEQAError, match="holds a run with another (config|stack)"):
        resume(folder, published_spec(**other))


def test_a_format_1_run_reads_as_the_values_it_ran_with():
    run = upgrade(json.loads(format_1("explore-eqa-per-token").read_text()))
    assert run["format"] == RUN_FORMAT and run["stack"]["temperature"] == 0.0
    answer, explore = run["config"]["answer"], run["config"]["explore"]  # the tree's sections
    assert (answer["answer_probability"], answer["token_answer"]) == ("per-token", "short")
    assert (explore["refusal_retries"], explore["stop_clearance_m"]) == (3, 0.45)
    # Recorded before the gate and the steering existed: it ran without them.
    assert (run["config"]["stop"]["gate"], explore["steering"], answer["answer_every_step"]) == (
        "none", "none", False)
    paper = upgrade(json.loads((PUBLISHED / "paper-offline" / RUN_FILE).read_text()))["config"]
    # recorded values stay
    assert (paper["explore"]["refusal_retries"], paper["explore"]["stop_clearance_m"]) == (0, 0.0)


def test_a_judge_mode_counts_only_with_a_judge(tmp_path):
    """A run without a judge model resumes whatever mode was recorded beside no judge."""
    folder = published_copy(tmp_path, "default-v2")
    run = json.loads((folder / RUN_FILE).read_text())
    (folder / RUN_FILE).write_text(json.dumps({**run, "judge": None, "judge_mode": "grade"}))
    resume(folder, replace(published_spec(), judge=None))
    with pytest.raises(EfficientEQAError, match="another judge"):
        resume(folder, published_spec())


def test_a_new_run_records_its_format_and_its_named_configuration(tmp_path):
    spec = main_table_spec("explore-eqa-per-token")
    resume(tmp_path, spec)
    run, _ = read_run(tmp_path)
    assert run["format"] == RUN_FORMAT and run["preset"] == "explore-eqa-per-token"
    assert run["preset_config"] == asdict(spec.preset_config)
    assert run["preset_config"]["answer"]["answer_probability"] == "per-token"
    assert run["judge_mode"] == "yes-prob"  # "auto" for a local judge, recorded as resolved


def test_labels_come_from_the_named_configuration_the_run_recorded(tmp_path):
    def made(row: str, **config: object) -> str:
        folder = tmp_path / f"{row}-{len(list(tmp_path.iterdir()))}"
        resume(folder, main_table_spec(row, **config))
        return label(read_run(folder)[0])

    assert made("default") == "efficienteqa"
    assert made("default", z_gated=2.0) == "efficienteqa z_gated=2"
    assert made("default", gate="model", z_th=2.0) == "efficienteqa gate=model Z_th=2"
    assert made("paper-offline") == "efficienteqa paper configuration"
    assert made("paper-offline", top_k=10) == "efficienteqa paper configuration K=10"
    assert made("explore-eqa") == "explore-eqa"
    assert made("explore-eqa-per-token") == "explore-eqa per-token"
    assert made("explore-eqa-per-token", answer_probability="product") == (
        "explore-eqa per-token answer_probability=product")


def test_a_changed_preset_file_does_not_relabel_a_run_recorded_before(tmp_path, monkeypatch):
    """A run made with the paper's Z_th = 3 keeps its label when paper-offline's file later says
    Z_th = 2; a run made after the change with --z-th 3 is named by that change."""
    before = tmp_path / "before"
    resume(before, main_table_spec("paper-offline"))
    assert label(read_run(before)[0]) == "efficienteqa paper configuration"

    load = presets.load_preset

    def changed(name: str, *args: object, **kwargs: object) -> dict:
        values = load(name, *args, **kwargs)  # type: ignore[arg-type]
        return {**values, "stop.z_th": 2.0} if name == "paper-offline" else values

    monkeypatch.setattr(presets, "load_preset", changed)
    assert label(read_run(before)[0]) == "efficienteqa paper configuration"
    after = tmp_path / "after"
    resume(after, main_table_spec("paper-offline", z_th=3.0))
    assert label(read_run(after)[0]) == "efficienteqa paper configuration Z_th=3"


def test_a_changed_default_does_not_relabel_a_run_recorded_before(tmp_path, monkeypatch):
    """Today's defaults are not what a format-2 run is compared with: its recorded ones are."""
    folder = tmp_path / "run"
    resume(folder, RunSpec.of(method="efficienteqa", dataset="synthetic", judge=None))
    run = read_run(folder)[0]
    assert label(run) == "efficienteqa"
    # As if the default K had become 10 since: the run, at K = 5 then, is still "efficienteqa".
    paper = run_labels._paper_settings()  # cached: computed against the defaults of today
    monkeypatch.setattr(run_labels, "_paper_settings", lambda: paper)
    monkeypatch.setattr(run_labels, "_default_settings",
                        lambda: tuple({**dict(_settings(AgentConfig())), "top_k": 10}.items()))
    assert label(run) == "efficienteqa"
    format_1 = {k: v for k, v in run.items() if k not in ("format", "preset", "preset_config")}
    assert label(format_1) == "efficienteqa K=5"  # a format-1 run still reads against today's


def _settings(config: AgentConfig) -> dict:
    return run_labels.settings({"config": asdict(config)})


def test_a_stack_left_to_its_defaults_is_the_one_typed_out():
    assert Stack() == Stack(temperature=0.0)


# The stack's settings whose default was None ("the default decided elsewhere") until they
# became values, each as the value it meant.
STACK_DEFAULTS = {"device": "auto", "allow_download": False, "image_max_side": 512,
                  "image_format": "auto"}


def test_the_stacks_defaults_are_values_a_user_can_type():
    assert Stack() == Stack(temperature=0.0, **STACK_DEFAULTS)  # type: ignore[arg-type]
    assert presets.build_run(STACK_DEFAULTS).backends == presets.build_run({}).backends
    # "auto" leaves the format to the back-end: JPEG for an openai: server, PNG for the local one.
    openai = Stack(vlm="openai:gpt-4o", perception="rgb")
    assert parse_vlm(openai.vlm, images=True, **openai.server_options()).image_format is None
    with pytest.raises(EfficientEQAError, match=r"auto \| png \| jpeg"):
        parse_vlm(openai.vlm, images=True, image_format="webp")


def test_a_format_1_run_that_did_not_record_the_stacks_defaults_reads_as_them(tmp_path):
    run = json.loads(format_1("default-v2").read_text())
    assert not set(STACK_DEFAULTS) & set(run["stack"])  # the premise: recorded before they existed
    assert upgrade(run)["stack"] == {**run["stack"], "temperature": 0.0, "sightings": "auto",
                                     **STACK_DEFAULTS}
    typed = published_spec(**STACK_DEFAULTS)
    assert typed.stack == published_spec().stack
    resume(published_copy(tmp_path, "default-v2"), typed)


@pytest.mark.parametrize("other", [{"device": "cpu"}, {"allow_download": True},
                                   {"image_max_side": 256}, {"image_format": "jpeg"}])
def test_another_stack_value_than_a_format_1_run_meant_is_another_run(tmp_path, other):
    folder = published_copy(tmp_path, "default-v2")
    with pytest.raises(EfficientEQAError, match="holds a run with another stack"):
        resume(folder, published_spec(**other))


@pytest.mark.parametrize("form", [{}, {"format": RUN_FORMAT}])
def test_a_run_that_recorded_none_for_the_stacks_defaults_resumes(tmp_path, form):
    """None as format 1 wrote it, and as format 2 was first written (before these four became
    values): both meant the defaults, and resume with the command that made them."""
    spec = main_table_spec("default")
    run = {**manifest(spec, 48), **form}
    run["stack"] = {**run["stack"], **dict.fromkeys(STACK_DEFAULTS)}
    if not form:
        run = {k: v for k, v in run.items() if k not in ("format", "preset", "preset_config")}
    assert upgrade(run)["stack"] == asdict(spec.stack)
    (tmp_path / RUN_FILE).write_text(json.dumps(run))
    resume(tmp_path, spec)
    with pytest.raises(EfficientEQAError, match="another stack"):
        resume(tmp_path, main_table_spec("default", device="cpu"))


def test_an_openai_run_recorded_before_the_image_settings_sent_png():
    """Before the image settings existed an openai: server was sent PNG; today's "auto" sends
    it JPEG, so such a run reads as PNG (typing --image-format png resumes it)."""
    stack = {k: v for k, v in asdict(Stack(vlm="openai:gpt-4o", perception="rgb")).items()
             if k not in STACK_DEFAULTS}
    assert upgrade({"stack": stack})["stack"]["image_format"] == "png"
    assert upgrade({"stack": {**stack, "image_format": None}})["stack"]["image_format"] == "auto"
    local = {k: v for k, v in asdict(Stack()).items() if k not in STACK_DEFAULTS}
    assert upgrade({"stack": local})["stack"]["image_format"] == "auto"  # PNG either way


def test_a_refused_resume_says_what_changed_without_a_urls_password(tmp_path):
    """The server's URL changed: the error names the VLM it was and is, not just "another
    stack", and leaves a password in the URL out."""
    from efficienteqa.eval.records import open_run

    spec = main_table_spec("default")
    run = manifest(spec, 48)
    run["stack"] = {**run["stack"], "vlm": "openai:m@http://alice:s3cret@10.0.0.1:8000/v1"}
    open_run(tmp_path, run)
    moved = {**run, "stack": {**run["stack"], "vlm": "openai:m@http://10.0.0.2:8000/v1"}}
    with pytest.raises(EfficientEQAError) as raised:
        open_run(tmp_path, moved)
    said = str(raised.value)
    assert "another stack (vlm: openai:m@http://10.0.0.1:8000/v1 -> openai:m@http://10.0.0.2:8000/v1)" in said
    assert "s3cret" not in said and "alice" not in said


def test_a_refused_resume_names_each_changed_setting_by_its_path(tmp_path):
    folder = tmp_path / "run"
    resume(folder, main_table_spec("default"))
    with pytest.raises(EfficientEQAError, match=r"another config \(answer\.top_k: 5 -> 3; "
                                                r"stop\.z_gated: 1.0 -> 2.0\)"):
        resume(folder, main_table_spec("default", top_k=3, z_gated=2.0))


@pytest.mark.parametrize("row", ["default", "pixels", "paper-offline", "explore-eqa",
                                 "explore-eqa-blackbox", "frontier-only", "blind"])
def test_a_published_row_runs_again_from_its_own_run_json(tmp_path, row):
    """``--config results/main-heldout/ROW/run.json`` is the run the row recorded: the tree it
    reads back makes a RunSpec whose record the published run accepts as its own (a resume),
    whatever format the row was written in."""
    published = PUBLISHED / row / RUN_FILE
    from efficienteqa.eval.plan import plan_run

    resolved = presets.resolve({}, config_file=published)
    run = resolved.run
    spec = plan_run(run, resolved.preset, resolved.preset_run.agent)  # as eval makes it
    recorded = json.loads(published.read_text())
    assert run.eval.limit == recorded["questions"]
    folder = tmp_path / row
    folder.mkdir()
    shutil.copy(published, folder / RUN_FILE)
    open_run(folder, manifest(spec, recorded["questions"]))  # raises where it is another run


def test_a_format_5_run_records_the_tree_it_was_made_from_and_reads_back_as_it(tmp_path):
    """run.json holds the whole tree (``run``, format 5); ``--config run.json`` gives that tree
    back, every section (the scene's, the evaluation's) included."""
    from efficienteqa.eval.plan import plan_run
    from efficienteqa.records import write_json

    run = presets.run_config("paper-offline", {"stop.z_th": 2.0, "eval.limit": 3,
                                               "scene.hm3d_root": Path("/data/hm3d"),
                                               "backends.vlm": "openai:m@http://u:secret@h/v1"})
    spec = plan_run(run, "paper-offline", run.agent)
    record = manifest(spec, 3)
    assert record["format"] == RUN_FORMAT == 5 and record["run"]["stop"]["z_th"] == 2.0
    write_json(tmp_path / RUN_FILE, record)
    assert "secret" not in (tmp_path / RUN_FILE).read_text()  # the URL's password is ***
    back = presets.resolve({}, config_file=tmp_path / RUN_FILE).run
    assert back.agent == run.agent and back.eval == run.eval and back.scene == run.scene
    assert back.backends.vlm == "openai:m@http://u:***@h/v1"  # as recorded, redacted


@needs_egl
@needs_default_model
def test_the_default_row_run_again_from_its_run_json_gives_its_answers(cli, tmp_path, monkeypatch):
    """``eval --config results/main-heldout/default/run.json`` on the row's first 3 questions, on
    the real default model with an empty response cache: the published answers, in the published
    steps. (A change of behaviour fails here: the row is then to be run again.)"""
    from efficienteqa.cache import cache_path

    cache = tmp_path / "cache"  # the installed models and furniture, but no response cached
    cache.mkdir()
    for shared in ("models", "furniture", "datasets", "wheels"):
        if cache_path(shared).exists():
            (cache / shared).symlink_to(cache_path(shared))
    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(cache))
    try:
        result = cli("eval", "--config", str(PUBLISHED / "default" / RUN_FILE), "--eval.limit", "3",
                     "--eval.judge", "rule", "--out", str(tmp_path / "again"))
    finally:
        cli("models", "stop")
    assert result.returncode == 0, result.stdout + result.stderr

    def answers(folder: Path) -> dict[str, tuple[str, int]]:
        rows = [json.loads(line) for line in (folder / "episodes.jsonl").read_text().splitlines()]
        return {r["id"]: (r["answer"], r["steps"]) for r in rows}

    again, published = answers(tmp_path / "again"), answers(PUBLISHED / "default")
    assert len(again) == 3 and again == {k: published[k] for k in again}
