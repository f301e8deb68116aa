"""From command-line options to the dataclasses of a run: the one configuration path of the CLI.

An option the user leaves out arrives as None. A preset fills the ones it names; whatever is
still None takes the default of the dataclass it belongs to (``Stack``, ``AgentConfig``,
``StopConfig``, ``RunSpec``), so no default is written twice.

``paper``: the set-up of the paper's experiments (its Sec. IV): HM-EQA's first 100 questions
in Habitat-Sim, GPT-4o (gpt-4o-2024-05-13, temperature 1) reading the RGB frames, BLIP-2 ITM
(Salesforce/blip2-itm-vit-g) for relevancy, Z_th = 3 and K = 5. The paper does not name its
LLM-Match judge; the preset uses the same GPT-4o, grading 1-5. In Habitat-Sim the preset runs
ExploreEQA's set-up, the defaults of ``envs.habitat.env.HabitatEnv``: the camera on a body
tilted 30 degrees down (``camera_mount="body-tilt"``), moves set without a navmesh check
(``moves="unchecked"``, so no refused move spends a step) and the step budget from the x-z box
of the whole navmesh (``budget_area="navmesh-bbox"``); docs/habitat.md, "Fidelity to ExploreEQA".
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields, replace
from typing import TYPE_CHECKING, Any

from efficienteqa.errors import EfficientEQAError

if TYPE_CHECKING:
    from efficienteqa.agent import AgentConfig
    from efficienteqa.stack import Stack

PAPER_VLM = "openai:gpt-4o-2024-05-13"

PRESETS: dict[str, dict[str, Any]] = {
    "paper": {
        "dataset": "hm-eqa", "limit": 100, "env": "habitat",
        "vlm": PAPER_VLM, "temperature": 1.0, "perception": "rgb", "relevancy": "blip2-itm",
        "grouping": "llm", "z_th": 3.0, "top_k": 5,
        # SPEC 3.4's z-rule: mean and sample std of the earlier frames, no stop before step 10
        "stop_rule": "paper", "min_stop_step": 10,
        # nothing beyond the paper: no answerability gate, no steering by the question's target
        "gate": "none", "steering": "none",
        # the VLM's verbalized confidence gives the semantic values (SPEC 3.3)
        "explore_scorer": "vlm",
        "judge": PAPER_VLM, "judge_mode": "grade",
        # the paper's stepping: a move ends where the 3 m cut falls, a refused move spends a step
        "refusal_retries": 0, "stop_clearance_m": 0.0,
        # SPEC 3.3's prompt points, 2-10 m away and 1 m apart; SPEC 3.2's frontier explorer
        "prompts": "paper", "exploration": "paper",
        # SPEC 3.5's retrieval: the K most relevant frames, repeats of one view included
        "distinct_views": False,
        # SPEC 3.5's answer: M verbalized guesses, grouped
        "answer": "paper",
    },
}

# Command-line names of StopConfig fields (the others are named as their fields).
_STOP_OPTIONS = {"z_th": "z_th", "min_stop_step": "min_step", "stop_rule": "rule"}


def apply_preset(name: str | None, options: Mapping[str, Any]) -> dict[str, Any]:
    """``options`` with the preset's value for each option left out (None); options the preset
    does not name are kept as they are."""
    if name is None:
        return dict(options)
    if name not in PRESETS:
        raise EfficientEQAError(f"unknown preset {name!r}", fix=f"use one of {', '.join(PRESETS)}")
    values = PRESETS[name]
    return {k: values[k] if v is None and k in values else v for k, v in options.items()}


def given(options: Mapping[str, Any], names: Any) -> dict[str, Any]:
    """The options among ``names`` that are set (not None)."""
    return {k: options[k] for k in names if options.get(k) is not None}


def build_stack(options: Mapping[str, Any]) -> Stack:
    """The back-ends of a run: ``Stack`` fields from the options that are set."""
    from efficienteqa.stack import Stack, default_relevancy

    values = given(options, [f.name for f in fields(Stack)])
    if "relevancy" not in values and values.get("perception") == "rgb":  # a scorer of images
        values["relevancy"] = default_relevancy("rgb", values.get("relevancy_weights"))
    return Stack(**values)


def build_config(options: Mapping[str, Any]) -> AgentConfig:
    """The agent's knobs: ``AgentConfig`` and ``StopConfig`` fields from the options that are
    set; ``no_early_stop`` turns the relevancy stop off."""
    from efficienteqa.agent import AgentConfig

    try:  # the agent's own stop defaults, with the options given
        stop = replace(AgentConfig().stop, **{_STOP_OPTIONS[k]: v
                                              for k, v in given(options, _STOP_OPTIONS).items()})
    except ValueError as exc:  # e.g. --stop-rule bogus
        raise EfficientEQAError(str(exc), fix="see efficienteqa ask --help") from None
    if options.get("no_early_stop"):
        stop = replace(stop, enabled=False)
    agent_fields = [f.name for f in fields(AgentConfig) if f.name != "stop"]
    try:
        return AgentConfig(stop=stop, **given(options, agent_fields))
    except ValueError as exc:  # a value the dataclass refuses, e.g. --prompts bogus
        raise EfficientEQAError(str(exc), fix="see efficienteqa ask --help") from None
