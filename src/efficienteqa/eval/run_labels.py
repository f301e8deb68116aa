"""The settings of a run and the short label a table names it by ("efficienteqa Z_th=2",
"efficienteqa paper configuration K=3").

Kept apart from the run's figures (``eval.summary``) because a label depends only on the run's
manifest: its method, its named configuration and the agent settings it changed against that
configuration (or, for a run that did not record one, against today's defaults).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import asdict
from functools import cache
from typing import Any

from efficienteqa.config.inert import reads_target
from efficienteqa.config.knobs import flatten
from efficienteqa.eval.records import RUN_FORMAT, upgrade

# How a setting that differs from the default is written in a label (the paper's symbols).
LABEL_NAMES = {"z_th": "Z_th", "top_k": "K", "max_steps": "budget", "min_step": "min step",
               "sigma_eps": "sigma_eps", "seed": "seed"}
# Methods that run no agent (the Blind LLM answers the question alone): the agent's settings in
# their run.json change nothing, so their labels leave them out.
AGENTLESS_METHODS = frozenset({"blind"})

# Settings a method sets itself whatever the options say (eval.methods.method_config): not
# worth naming in its label. ExploreEQA never stops early, so its stop settings do nothing.
_EXPLORE_EQA = {"steering", "gate", "min_step", "z_gated"}
METHOD_SETS: dict[str, set[str]] = {"explore-eqa": _EXPLORE_EQA,
                                    "explore-eqa-blackbox": _EXPLORE_EQA,
                                    "frontier-only": {"steering"}, "random": {"steering"}}


def settings(manifest: Mapping[str, Any]) -> dict[str, Any]:
    """The run's configuration as one flat dict (the agent's sections' fields by their own
    names, which are unique; the stack; the judge): what ablations compare and labels name.
    ``stop.enabled`` becomes ``early_stop``, an override ``sfe.NAME``. An older
    run's settings are read as what they meant (``records.upgrade``)."""
    manifest = upgrade(dict(manifest))
    flat: dict[str, Any] = {}
    for section in (manifest.get("config") or {}).values():
        for key, value in dict(section).items():
            if isinstance(value, Mapping):  # overrides: "sfe.view_gain"
                flat.update({f"{key}.{'.'.join(path)}": v for path, v in flatten(value).items()})
            else:
                flat[key] = value
    if "enabled" in flat:
        flat["early_stop"] = flat.pop("enabled")
    flat.update(dict(manifest.get("stack") or {}))
    for key in ("judge", "closed_set", "assets", "noise"):
        if key in manifest:
            flat[key] = manifest[key]
    return flat


@cache
def _default_settings() -> tuple[tuple[str, Any], ...]:
    from efficienteqa.agent import AgentConfig

    return tuple(settings({"config": asdict(AgentConfig()), "format": RUN_FORMAT}).items())


@cache
def _paper_settings() -> tuple[tuple[str, Any], ...]:
    """The settings in which ``agent.PAPER_CONFIG`` differs from the defaults."""
    from efficienteqa.agent import PAPER_CONFIG

    paper = settings({"config": asdict(PAPER_CONFIG), "format": RUN_FORMAT})
    return tuple((k, paper[k]) for k, default in _default_settings() if paper[k] != default)


def _is_paper_configuration(flat: Mapping[str, Any]) -> bool:
    """Every setting of the paper's configuration, and the VLM's semantic values (DESIGN 3.3)."""
    return (all(k in flat and flat[k] == v for k, v in _paper_settings())
            and flat.get("explore_scorer") == "vlm")


def _fmt_setting(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def preset_settings(manifest: Mapping[str, Any]) -> dict[str, Any] | None:
    """The settings (``settings``) of the named configuration the run started from, as the run
    recorded them; None for a run that did not (format 1)."""
    manifest = upgrade(dict(manifest))
    config = manifest.get("preset_config")
    return settings({"config": config, "format": RUN_FORMAT}) if isinstance(config, Mapping) else None


def label(manifest: Mapping[str, Any]) -> str:
    """A short name for tables: the method, the named configuration the run started from, and
    the agent settings the run changed against it ("efficienteqa Z_th=2", "efficienteqa paper
    configuration K=10", "explore-eqa closed-set"). A run that did not record its named
    configuration (format 1) is named by the settings that differ from today's defaults."""
    preset = manifest.get("preset")
    # A setting the run did not record yet is what its time ran with: not a change to name.
    unrecorded = list(upgrade(dict(manifest)).get("unrecorded") or ())
    return settings_label(str(manifest.get("method", "?")), settings(manifest), unrecorded,
                          preset=preset if isinstance(preset, str) else None,
                          baseline=preset_settings(manifest))


# Settings that act only where the steering or a gate reads the question's target.
TARGET_SETTINGS = frozenset({"reading", "matching", "gate_final"})

# How a label names a named configuration: the paper's by this phrase, one named after the
# method or "default" by nothing, any other by its name less the method's ("per-token" for the
# explore-eqa run of config/toml/explore-eqa-per-token.toml).
PRESET_LABELS = {"paper": "paper configuration", "paper-offline": "paper configuration",
                 "default": ""}


def _preset_label(method: str, preset: str | None) -> str:
    if preset is None or preset == method:
        return ""
    return PRESET_LABELS.get(preset, preset.removeprefix(f"{method}-"))


# The order in which a label names settings: the order flat records gave them (settings added
# late first, as ``records.ADDED_SETTINGS`` put them), so an old run's label reads as it did.
LABEL_ORDER = ("reading", "matching", "gate_final", "step_weight", "explorer", "top_k",
               "max_steps", "seed", "confidence", "answer_at", "refusal_retries",
               "stop_clearance_m", "prompts", "distinct_views", "exploration", "answer",
               "answer_every_step", "answer_probability", "token_answer", "gate", "steering",
               "z_th", "min_step", "early_stop", "sigma_eps", "rule", "sigma_floor", "sim_abs",
               "z_gated")


def _label_rank(key: str) -> int:
    return LABEL_ORDER.index(key) if key in LABEL_ORDER else len(LABEL_ORDER)


def settings_label(method: str, flat: Mapping[str, Any], skip: Iterable[str] = (), *,
                   preset: str | None = None, baseline: Mapping[str, Any] | None = None) -> str:
    """``method`` plus the settings in ``flat`` (``settings``) that differ from ``baseline``,
    the run's named configuration ``preset``'s, leaving out ``skip`` (an ablation table names
    its own variable). ``baseline`` None (a format-1 run): against today's defaults, named
    "paper configuration" where it is the paper's."""
    parts = [method]
    skipped = set(skip) | METHOD_SETS.get(method, set())
    if not reads_target(flat.get("steering"), flat.get("gate")):
        skipped |= TARGET_SETTINGS  # nothing reads the target: these cannot act (inert.py)
    if method in AGENTLESS_METHODS:
        against: Iterable[tuple[str, Any]] = ()
    elif baseline is not None:
        parts += [p for p in [_preset_label(method, preset)] if p]
        against = baseline.items()
    else:
        if _is_paper_configuration(flat):
            parts.append("paper configuration")
            skipped |= {k for k, _ in _paper_settings()}
        against = _default_settings()
    for key, default in sorted(against, key=lambda kv: _label_rank(kv[0])):
        if key in flat and key not in skipped and flat[key] != default:
            if key == "early_stop":
                parts.append("no early stop" if not flat[key] else "early stop")
            else:
                parts.append(f"{LABEL_NAMES.get(key, key)}={_fmt_setting(flat[key])}")
    if flat.get("closed_set"):
        parts.append("closed-set")
    if flat.get("noise") not in (None, "none"):  # a robot's imperfections in the houses
        parts.append(f"noise={flat['noise']}")
    return " ".join(parts)
