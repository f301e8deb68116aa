"""The CLI's one configuration path: options left out take the dataclasses' defaults, a preset
fills only what was left out, and `ask` and `eval` build the same agent from the same options."""

from __future__ import annotations

from dataclasses import replace

import pytest

from efficienteqa.agent import AgentConfig
from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.module import REFUSAL_RETRIES
from efficienteqa.presets import PRESETS, apply_preset, build_config, build_stack, load_preset
from efficienteqa.stack import Stack
from efficienteqa.stop import StopConfig
from efficienteqa.stop.rules import GATED_MIN_STEP

NOTHING_GIVEN = {"step_weight": None, "z_th": None, "z_gated": None, "min_stop_step": None,
                 "no_early_stop": False, "top_k": None,
                 "max_steps": None, "seed": None, "explorer": None, "vlm": None,
                 "temperature": None, "perception": None, "relevancy": None, "grouping": None,
                 "cache": None, "dataset": None, "limit": None, "env": None, "judge": None,
                 "judge_mode": None, "refusal_retries": None, "stop_clearance_m": None,
                 "prompts": None, "exploration": None, "distinct_views": None, "answer": None,
                 "answer_probability": None, "token_answer": None, "gate": None,
                 "steering": None, "reading": None, "matching": None,
                 "gate_final": None}


def test_options_left_out_take_the_dataclass_defaults():
    assert build_config(NOTHING_GIVEN) == AgentConfig()
    assert build_stack(NOTHING_GIVEN) == Stack()


def test_given_options_reach_the_dataclasses():
    o = {**NOTHING_GIVEN, "z_th": 1.5, "z_gated": 0.5, "min_stop_step": 4, "top_k": 3,
         "max_steps": 12, "seed": 7, "gate": "model",
         "explorer": "random", "relevancy": "overlap", "cache": False, "temperature": 0.5,
         "refusal_retries": 0, "stop_clearance_m": 0.3, "prompts": "paper",
         "answer_probability": "per-token", "token_answer": "verbalized"}
    config = build_config(o)
    assert (config.answer_probability, config.token_answer) == ("per-token", "verbalized")
    assert config.stop == StopConfig(z_th=1.5, z_gated=0.5, min_step=4)
    assert (config.top_k, config.max_steps, config.seed, config.explorer) == (3, 12, 7, "random")
    assert (config.refusal_retries, config.stop_clearance_m, config.prompts) == (0, 0.3, "paper")
    stack = build_stack(o)
    assert (stack.relevancy, stack.cache, stack.temperature) == ("overlap", False, 0.5)
    assert stack.vlm == Stack().vlm


def test_no_early_stop_turns_the_stop_off_and_keeps_its_other_values():
    config = build_config({**NOTHING_GIVEN, "no_early_stop": True, "z_th": 2.0, "gate": "none"})
    assert config.stop == StopConfig(z_th=2.0, enabled=False, min_step=GATED_MIN_STEP)


def test_a_preset_fills_only_what_was_left_out():
    o = apply_preset("paper", {**NOTHING_GIVEN, "top_k": 3, "relevancy": "clip"})
    paper = PRESETS["paper"]
    assert o["top_k"] == 3 and o["relevancy"] == "clip"  # given: kept
    assert o["vlm"] == paper["vlm"] and o["z_th"] == paper["z_th"]  # left out: the preset's
    assert o["dataset"] == "hm-eqa" and o["limit"] == 100 and o["judge_mode"] == "openeqa"
    assert o["seed"] is None  # the preset does not name it: the dataclass default applies
    assert build_stack(o).perception == "rgb"
    config = build_config(o)  # the paper's stepping: no re-plans, no clearance at a move's end
    assert (config.refusal_retries, config.stop_clearance_m, config.prompts) == (0, 0.0, "paper")
    assert config.exploration == "paper"  # DESIGN 3.2's explorer
    assert build_config(NOTHING_GIVEN).refusal_retries == REFUSAL_RETRIES  # the default re-plans
    assert config.distinct_views is False and build_config(NOTHING_GIVEN).distinct_views
    assert config.answer == "paper" and build_config(NOTHING_GIVEN).answer == "auto"  # DESIGN 3.5
    from efficienteqa.agent import PAPER_CONFIG

    every = apply_preset("paper", {**NOTHING_GIVEN, "stop_rule": None, "explore_scorer": None})
    # what tables call "paper configuration" (with ExploreEQA's own weight of step answers)
    assert build_config(every) == replace(PAPER_CONFIG, step_weight="confident")
    assert build_stack(every).explore_scorer == "vlm"


def test_an_unknown_preset_is_one_clear_error():
    with pytest.raises(EfficientEQAError, match="unknown preset"):
        apply_preset("papr", NOTHING_GIVEN)


def test_a_value_the_agent_refuses_is_one_clear_error():
    with pytest.raises(EfficientEQAError, match="prompts must be one of"):
        build_config({**NOTHING_GIVEN, "prompts": "bogus"})
    with pytest.raises(EfficientEQAError, match="exploration must be one of"):
        build_config({**NOTHING_GIVEN, "exploration": "bogus"})
    with pytest.raises(EfficientEQAError, match="answer must be one of"):
        build_config({**NOTHING_GIVEN, "answer": "bogus"})
    with pytest.raises(EfficientEQAError, match="answer_probability must be one of"):
        build_config({**NOTHING_GIVEN, "answer_probability": "mean"})
    with pytest.raises(EfficientEQAError, match="token_answer must be one of"):
        build_config({**NOTHING_GIVEN, "token_answer": "long"})


def test_images_get_an_image_relevancy_scorer_unless_one_is_named(monkeypatch):
    """``--perception rgb`` alone must not pick MiniLM, which reads text:
    BLIP-2 where its weights are on the machine, else the VLM's own yes/no (vlm-match)."""
    from efficienteqa import stack
    from efficienteqa.presets import build_stack

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
    "default": {"method": "efficienteqa"},
    "explore-eqa": {"method": "explore-eqa", "explore_scorer": "direction-logit"},
    "explore-eqa-blackbox": {"method": "explore-eqa-blackbox", "explore_scorer": "direction-logit"},
    "explore-eqa-verbalized-prompt": {"method": "explore-eqa", "explore_scorer": "direction-logit",
                                      "token_answer": "verbalized"},
    "explore-eqa-per-token": {"method": "explore-eqa", "explore_scorer": "direction-logit",
                              "answer_probability": "per-token"},
    "frontier-only": {"method": "frontier-only"},
    "random": {"method": "random"},
    "blind": {"method": "blind"},
    "paper-offline": {"method": "efficienteqa", "explore_scorer": "vlm", "stop_rule": "paper",
                      "answer": "paper", "prompts": "paper", "exploration": "paper",
                      "refusal_retries": 0, "stop_clearance_m": 0.0, "distinct_views": False,
                      "gate": "none", "steering": "none", "min_stop_step": 10,
                      "reading": "rules", "matching": "words",
                      # the defaults the paper's algorithm also names
                      "z_th": 3.0, "top_k": 5, "grouping": "llm"},
}
# The rows with pixel perception: the default and paper rows, seeing through the network.
MAIN_TABLE_ROWS["pixels"] = {**MAIN_TABLE_ROWS["default"], "perception": "pixels"}
MAIN_TABLE_ROWS["paper-offline-pixels"] = {**MAIN_TABLE_ROWS["paper-offline"],
                                           "perception": "pixels"}
# What `--preset paper` sets besides the paper's algorithm: its back-ends and question set.
PAPER_BACKENDS = {"dataset": "hm-eqa", "limit": 100, "env": "habitat",
                  "vlm": "openai:gpt-4o-2024-05-13", "temperature": 1.0, "perception": "rgb",
                  "relevancy": "blip2-itm", "judge": "openai:gpt-4o-2024-05-13",
                  "judge_mode": "openeqa", "step_weight": "confident"}


def test_the_presets_are_the_shipped_configuration_files():
    from efficienteqa.presets import load_preset, preset_names

    assert set(preset_names()) == {"paper", *MAIN_TABLE_ROWS}
    for name, options in MAIN_TABLE_ROWS.items():
        assert load_preset(name) == options, name
    assert load_preset("paper") == {**MAIN_TABLE_ROWS["paper-offline"], **PAPER_BACKENDS}
    assert dict(PRESETS["paper"]) == load_preset("paper") and "paper-offline" in PRESETS


def test_paper_offline_is_the_papers_algorithm_on_the_offline_stack():
    """Exactly what ``--preset paper`` sets besides the back-ends: agent.PAPER_CONFIG with the
    VLM's semantic values, on the default (offline) stack, so tables name it "efficienteqa
    paper configuration" as they name the committed run of results/main-heldout/paper-offline."""
    from dataclasses import asdict

    from efficienteqa.agent import PAPER_CONFIG
    from efficienteqa.eval.summary import label

    o = apply_preset("paper-offline", {**NOTHING_GIVEN, "stop_rule": None, "explore_scorer": None})
    assert build_config(o) == PAPER_CONFIG
    assert build_stack(o) == Stack(explore_scorer="vlm")
    assert o["dataset"] is None and o["env"] is None  # the synthetic defaults
    paper = apply_preset("paper", {**NOTHING_GIVEN, "stop_rule": None, "explore_scorer": None})
    # the same but for the weight of ExploreEQA's step answers, which the agent's own answer
    # (retrieval) never reads
    assert build_config(paper) == replace(build_config(o), step_weight="confident")
    manifest = {"method": "efficienteqa", "config": asdict(build_config(o)),
                "stack": {"explore_scorer": "vlm"}}
    assert label(manifest) == "efficienteqa paper configuration"


def test_a_configuration_file_is_read_and_checked(tmp_path):
    from pathlib import Path

    from efficienteqa.presets import load_config

    types = {"top_k": int, "z_th": float, "distinct_views": bool, "vlm": str, "hm3d_root": Path,
             "method": str, "stop_rule": str}
    good = tmp_path / "mine.toml"
    good.write_text('base = "explore-eqa"\n# a comment\ntop_k = 3\nz_th = 2\n'
                    'distinct_views = false\nhm3d_root = "scenes"\n')
    values = load_config(good, {**types, "explore_scorer": str})
    assert values == {"method": "explore-eqa", "explore_scorer": "direction-logit", "top_k": 3,
                      "z_th": 2.0, "distinct_views": False, "hm3d_root": tmp_path / "scenes"}
    assert isinstance(values["z_th"], float)
    for text, message in (('topk = 3\n', "unknown option 'topk' in .*did you mean 'top_k'"),
                          ('top_k = "3"\n', "top_k in .* must be an integer, not '3'"),
                          ('top_k = true\n', "top_k in .* must be an integer"),
                          ('z_th = "high"\n', "z_th in .* must be a number"),
                          ('distinct_views = 1\n', "distinct_views in .* must be true or false"),
                          ('vlm = ["a"]\n', "vlm in .* must be a string"),
                          ('top_k = \n', "is not valid TOML"),
                          ('base = "papr"\n', "unknown preset 'papr'"),
                          ('base = 3\n', "base in .* must be a preset's name")):
        bad = tmp_path / "bad.toml"
        bad.write_text(text)
        with pytest.raises(EfficientEQAError, match=message):
            load_config(bad, types)
    with pytest.raises(EfficientEQAError, match="cannot read the configuration"):
        load_config(tmp_path / "missing.toml", types)
    (tmp_path / "binary.toml").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(EfficientEQAError, match="cannot read the configuration"):
        load_config(tmp_path / "binary.toml", types)


def test_the_paper_presets_judge_follows_a_vlm_given_on_the_command_line():
    """--preset paper grades with its own GPT-4o; --vlm pointing at another server (and no
    --judge) must not leave the judge, and the user's key, at OpenAI."""
    from efficienteqa.presets import fill, judge_follows_vlm, load_preset

    values = load_preset("paper")
    assert values["judge"] == values["vlm"]
    mine = "openai:qwen2.5-coder-1.5b@http://127.0.0.1:8080/v1"
    options = judge_follows_vlm(fill({"vlm": mine, "judge": None}, values, {"vlm"}), values,
                                {"vlm"})
    assert options["judge"] == mine
    judged = judge_follows_vlm(fill({"vlm": mine, "judge": "rule"}, values, {"vlm", "judge"}),
                               values, {"vlm", "judge"})
    assert judged["judge"] == "rule"  # a judge given is kept
    plain = judge_follows_vlm(fill({"vlm": None, "judge": None}, values, set()), values, set())
    assert plain["judge"] == values["judge"]  # nothing given: the preset's own


@pytest.mark.parametrize("gate", ["auto", "rules", "sightings"])
def test_a_z_th_that_cannot_act_is_refused_in_one_line(gate):
    """A gate that judges every frame stops a frame it passes at z_gated, and never one it
    turns down: Z_th decides nothing there."""
    with pytest.raises(EfficientEQAError, match=f"--z-th 2 does not act with the {gate} gate") \
            as raised:
        build_config({**NOTHING_GIVEN, "z_th": 2.0, "gate": gate})
    assert "--z-gated" in str(raised.value) and "\n" not in str(raised.value)
    for acting in ("model", "none"):
        assert build_config({**NOTHING_GIVEN, "z_th": 2.0, "gate": acting}).stop.z_th == 2.0


@pytest.mark.parametrize("method", ["explore-eqa", "explore-eqa-blackbox"])
def test_the_baselines_in_the_papers_setting_explore_with_the_vlm(method):
    """ExploreEQA's baselines as the paper ran them (--preset paper --method M): the VLM scores
    the directions (the main table's rows use the model-free scorer, configs/explore-eqa.toml)."""
    from efficienteqa.eval.methods import method_config
    from efficienteqa.perception.image import ImagePerception
    from efficienteqa.stack import explore_scorer_name

    o = apply_preset("paper", {**NOTHING_GIVEN, "method": method})
    config = method_config(method, build_config(o))
    assert explore_scorer_name(build_stack(o), ImagePerception(), config) == "vlm"
    row = {**NOTHING_GIVEN, **load_preset(method)}
    assert build_stack(row).explore_scorer == "direction-logit"
