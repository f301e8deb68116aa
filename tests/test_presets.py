"""The CLI's one configuration path: options left out take the dataclasses' defaults, a preset
fills only what was left out, and `ask` and `eval` build the same agent from the same options.
Values are named by their dotted path in the configuration tree, or by their flat name."""

from __future__ import annotations

from dataclasses import asdict

import pytest

from efficienteqa.agent import AgentConfig
from efficienteqa.config.knobs import with_leaves
from efficienteqa.config.presets import (
    PRESETS,
    build_config,
    build_run,
    build_stack,
    load_preset,
    resolve,
)
from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.settings import REFUSAL_RETRIES
from efficienteqa.stack import Stack
from efficienteqa.stop import StopConfig
from efficienteqa.stop.rules import GATED_MIN_STEP


def test_options_left_out_take_the_dataclass_defaults():
    assert build_config({}) == AgentConfig()
    assert build_stack({}) == Stack()
    assert build_run({"top_k": None}) == build_run({})  # None is "left out"


def test_given_options_reach_the_dataclasses():
    o = {"stop.z_th": 1.5, "z_gated": 0.5, "min_stop_step": 4, "answer.top_k": 3,
         "max_steps": 12, "seed": 7, "gate": "model",
         "explorer": "random", "relevancy": "overlap", "cache": False, "temperature": 0.5,
         "refusal_retries": 0, "stop_clearance_m": 0.3, "prompts": "paper",
         "answer_probability": "per-token", "token_answer": "verbalized"}
    config = build_config(o)
    a, e = config.answer, config.explore
    assert (a.answer_probability, a.token_answer) == ("per-token", "verbalized")
    assert config.stop == StopConfig(z_th=1.5, z_gated=0.5, min_step=4, gate="model")
    assert (a.top_k, e.max_steps, e.seed, e.explorer) == (3, 12, 7, "random")
    assert (e.refusal_retries, e.stop_clearance_m, e.prompts) == (0, 0.3, "paper")
    stack = build_stack(o)
    assert (stack.relevancy, stack.cache, stack.temperature) == ("overlap", False, 0.5)
    assert stack.vlm == Stack().vlm


def test_no_early_stop_turns_the_stop_off_and_keeps_its_other_values():
    config = build_config({"stop.enabled": False, "z_th": 2.0, "gate": "none"})
    assert config.stop == StopConfig(z_th=2.0, enabled=False, min_step=GATED_MIN_STEP,
                                     gate="none")


def test_a_preset_fills_only_what_was_left_out():
    run = resolve({"top_k": 3, "backends.relevancy": "clip"}, "paper").run
    paper = PRESETS["paper"]
    assert run.answer.top_k == 3 and run.backends.relevancy == "clip"  # given: kept
    # left out: the preset's
    assert run.backends.vlm == paper["backends.vlm"] and run.stop.z_th == paper["stop.z_th"]
    assert (run.eval.dataset, run.eval.limit, run.eval.judge_mode) == ("hm-eqa", 100, "openeqa")
    assert run.explore.seed == 0  # the preset does not name it: the dataclass default applies
    assert run.backends.perception == "rgb"
    e = run.explore  # the paper's stepping: no re-plans, no clearance at a move's end
    assert (e.refusal_retries, e.stop_clearance_m, e.prompts) == (0, 0.0, "paper")
    assert e.exploration == "paper"  # DESIGN 3.2's explorer
    default = build_config({})
    assert default.explore.refusal_retries == REFUSAL_RETRIES  # the default re-plans
    assert run.answer.distinct_views is False and default.answer.distinct_views
    assert run.answer.answer == "paper" and default.answer.answer == "auto"  # DESIGN 3.5
    from efficienteqa.agent import PAPER_CONFIG

    every = resolve({}, "paper").run
    # what tables call "paper configuration" (with ExploreEQA's own weight of step answers)
    assert every.agent == with_leaves(PAPER_CONFIG, step_weight="confident")
    assert every.backends.explore_scorer == "vlm"


def test_an_unknown_preset_is_one_clear_error():
    with pytest.raises(EfficientEQAError, match="unknown preset"):
        resolve({}, "papr")


def test_a_value_the_agent_refuses_is_one_clear_error():
    with pytest.raises(EfficientEQAError, match="prompts must be one of"):
        build_config({"prompts": "bogus"})
    with pytest.raises(EfficientEQAError, match="exploration must be one of"):
        build_config({"exploration": "bogus"})
    with pytest.raises(EfficientEQAError, match="answer must be one of"):
        build_config({"answer": "bogus"})
    with pytest.raises(EfficientEQAError, match="answer_probability must be one of"):
        build_config({"answer_probability": "mean"})
    with pytest.raises(EfficientEQAError, match="token_answer must be one of"):
        build_config({"token_answer": "long"})


def test_images_get_an_image_relevancy_scorer_unless_one_is_named(monkeypatch):
    """``--perception rgb`` alone must not pick MiniLM, which reads text:
    BLIP-2 where its weights are on the machine, else the VLM's own yes/no (vlm-match)."""
    from efficienteqa import stack

    monkeypatch.setattr(stack, "_in_hf_cache", lambda model_id: False)
    assert build_stack({"perception": "rgb"}).relevancy == "vlm-match"
    assert build_stack({"perception": "rgb", "relevancy": "clip"}).relevancy == "clip"
    assert build_stack({"perception": "semantic"}).relevancy == "minilm"
    assert build_stack({}).relevancy == "minilm"
    monkeypatch.setattr(stack, "_in_hf_cache", lambda model_id: model_id.startswith("Salesforce/"))
    assert build_stack({"perception": "rgb"}).relevancy == "blip2-itm"


# The main table's rows as experiments/main_table.sh spelled them out before the presets held
# them once: each preset must set exactly these options.
MAIN_TABLE_ROWS = {
    "default": {"eval.method": "efficienteqa"},
    "explore-eqa": {"eval.method": "explore-eqa", "backends.explore_scorer": "direction-logit"},
    "explore-eqa-blackbox": {"eval.method": "explore-eqa-blackbox",
                             "backends.explore_scorer": "direction-logit"},
    "explore-eqa-verbalized-prompt": {"eval.method": "explore-eqa",
                                      "backends.explore_scorer": "direction-logit",
                                      "answer.token_answer": "verbalized"},
    "explore-eqa-per-token": {"eval.method": "explore-eqa",
                              "backends.explore_scorer": "direction-logit",
                              "answer.answer_probability": "per-token"},
    "frontier-only": {"eval.method": "frontier-only"},
    "random": {"eval.method": "random"},
    "blind": {"eval.method": "blind"},
    "paper-offline": {"eval.method": "efficienteqa", "backends.explore_scorer": "vlm",
                      "stop.rule": "paper", "answer.answer": "paper", "explore.prompts": "paper",
                      "explore.exploration": "paper", "explore.refusal_retries": 0,
                      "explore.stop_clearance_m": 0.0, "answer.distinct_views": False,
                      "stop.gate": "none", "explore.steering": "none", "stop.min_step": 10,
                      "explore.reading": "rules", "explore.matching": "words",
                      "stop.question_words": "asked",
                      # the defaults the paper's algorithm also names
                      "stop.z_th": 3.0, "answer.top_k": 5, "backends.grouping": "llm"},
}
# The rows with pixel perception: the default and paper rows, seeing through the network.
MAIN_TABLE_ROWS["pixels"] = {**MAIN_TABLE_ROWS["default"], "backends.perception": "pixels"}
MAIN_TABLE_ROWS["paper-offline-pixels"] = {**MAIN_TABLE_ROWS["paper-offline"],
                                           "backends.perception": "pixels"}
# What `--preset paper` sets besides the paper's algorithm: its back-ends and question set.
PAPER_BACKENDS = {"eval.dataset": "hm-eqa", "eval.limit": 100, "scene.env": "habitat",
                  "backends.vlm": "openai:gpt-4o-2024-05-13", "backends.temperature": 1.0,
                  "backends.perception": "rgb", "backends.relevancy": "blip2-itm",
                  "eval.judge": "openai:gpt-4o-2024-05-13", "eval.judge_mode": "openeqa",
                  "answer.step_weight": "confident"}


def test_the_presets_are_the_shipped_configuration_files():
    from efficienteqa.config.presets import preset_names

    assert set(preset_names()) == {"paper", *MAIN_TABLE_ROWS}
    for name, options in MAIN_TABLE_ROWS.items():
        assert load_preset(name) == options, name
    assert load_preset("paper") == {**MAIN_TABLE_ROWS["paper-offline"], **PAPER_BACKENDS}
    assert dict(PRESETS["paper"]) == load_preset("paper") and "paper-offline" in PRESETS


def test_paper_offline_is_the_papers_algorithm_on_the_offline_stack():
    """Exactly what ``--preset paper`` sets besides the back-ends: agent.PAPER_CONFIG with the
    VLM's semantic values, on the default (offline) stack, so tables name it "efficienteqa
    paper configuration" as they name the committed run of results/main-heldout/paper-offline."""
    from efficienteqa.agent import PAPER_CONFIG
    from efficienteqa.eval.records import RUN_FORMAT
    from efficienteqa.eval.run_labels import label

    run = resolve({}, "paper-offline").run
    assert run.agent == PAPER_CONFIG
    assert run.backends == Stack(explore_scorer="vlm")
    assert (run.eval.dataset, run.scene.env) == ("synthetic", "synthetic")  # the defaults
    paper = resolve({}, "paper").run
    # the same but for the weight of ExploreEQA's step answers, which the agent's own answer
    # (retrieval) never reads
    assert paper.agent == with_leaves(run.agent, step_weight="confident")
    manifest = {"method": "efficienteqa", "config": asdict(run.agent),
                "stack": {"explore_scorer": "vlm"}, "format": RUN_FORMAT}
    assert label(manifest) == "efficienteqa paper configuration"


def test_a_configuration_file_is_read_and_checked(tmp_path):
    from efficienteqa.config.presets import load_config

    good = tmp_path / "mine.toml"
    good.write_text('base = "explore-eqa"\n# a comment\ntop_k = 3\n[stop]\nz_th = 2\n'
                    '[answer]\ndistinct_views = false\n[scene]\nhm3d_root = "scenes"\n'
                    '[explore.sfe]\nview_gain = false\n[explore.sfe.frontier]\ntemp_free = 1\n'
                    '[explore.target.inspect_m]\ncount = 3.0\n')
    values = load_config(good)
    assert values == {"eval.method": "explore-eqa", "backends.explore_scorer": "direction-logit",
                      "answer.top_k": 3, "stop.z_th": 2.0, "answer.distinct_views": False,
                      "scene.hm3d_root": tmp_path / "scenes", "explore.sfe.view_gain": False,
                      "explore.sfe.frontier.temp_free": 1.0,
                      "explore.target.inspect_m": {"count": 3.0}}
    assert isinstance(values["stop.z_th"], float)
    run = build_run({**values, "stop.gate": "none"})
    assert run.explore.sfe == {"view_gain": False, "frontier": {"temp_free": 1.0}}
    options = run.explore.explorer_options()
    assert options["view_gain"] is False and options["frontier"].temp_free == 1.0
    assert run.explore.target_config().inspect_m == {"count": 3.0}
    for text, message in (('topk = 3\n', "unknown option 'topk' in .*did you mean 'top_k'"),
                          ('[stop]\nzth = 3\n', "unknown option 'stop.zth'.*'stop.z_th'"),
                          ('top_k = "3"\n', "answer.top_k in .* must be an integer, not '3'"),
                          ('top_k = true\n', "answer.top_k in .* must be an integer"),
                          ('z_th = "high"\n', "stop.z_th in .* must be a number"),
                          ('distinct_views = 1\n', "distinct_views in .* must be true or false"),
                          ('vlm = ["a"]\n', "backends.vlm in .* must be a string"),
                          ('[explore.sfe]\nview_gain = 2\n', "view_gain in .* true or false"),
                          ('top_k = \n', "is not valid TOML"),
                          ('base = "papr"\n', "unknown preset 'papr'"),
                          ('base = 3\n', "base in .* must be a preset's name")):
        bad = tmp_path / "bad.toml"
        bad.write_text(text)
        with pytest.raises(EfficientEQAError, match=message):
            load_config(bad)
    with pytest.raises(EfficientEQAError, match="cannot read the configuration"):
        load_config(tmp_path / "missing.toml")
    (tmp_path / "binary.toml").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(EfficientEQAError, match="cannot read the configuration"):
        load_config(tmp_path / "binary.toml")


def test_the_paper_presets_judge_follows_a_vlm_given_on_the_command_line():
    """--preset paper grades with its own GPT-4o; --vlm pointing at another server (and no
    --judge) must not leave the judge, and the user's key, at OpenAI."""
    values = load_preset("paper")
    assert values["eval.judge"] == values["backends.vlm"]
    mine = "openai:qwen2.5-coder-1.5b@http://127.0.0.1:8080/v1"
    assert resolve({"vlm": mine}, "paper").run.eval.judge == mine
    assert resolve({"vlm": mine, "judge": "rule"}, "paper").run.eval.judge == "rule"  # kept
    assert resolve({}, "paper").run.eval.judge == values["eval.judge"]  # nothing given


@pytest.mark.parametrize("gate", ["auto", "rules", "sightings"])
def test_a_z_th_that_cannot_act_is_refused_in_one_line(gate):
    """A gate that judges every frame stops a frame it passes at z_gated, and never one it
    turns down: Z_th decides nothing there."""
    with pytest.raises(EfficientEQAError, match=f"--stop.z-th 2 does not act: the {gate} gate "
                       "judges every frame") as raised:
        resolve({"z_th": 2.0, "gate": gate})
    assert "--stop.z-gated" in str(raised.value) and "\n" not in str(raised.value)
    for acting in ("model", "none"):
        assert resolve({"z_th": 2.0, "gate": acting}).run.stop.z_th == 2.0


@pytest.mark.parametrize("method", ["explore-eqa", "explore-eqa-blackbox"])
def test_the_baselines_in_the_papers_setting_explore_with_the_vlm(method):
    """ExploreEQA's baselines as the paper ran them (--preset paper --method M): the VLM scores
    the directions (the main table's rows use the model-free scorer, config/toml/explore-eqa.toml)."""
    from efficienteqa.eval.methods import method_config
    from efficienteqa.perception.image import ImagePerception
    from efficienteqa.stack import explore_scorer_name

    run = resolve({"method": method}, "paper").run
    config = method_config(method, run.agent)
    assert explore_scorer_name(run.backends, ImagePerception(), config) == "vlm"
    assert resolve({}, method).run.backends.explore_scorer == "direction-logit"
