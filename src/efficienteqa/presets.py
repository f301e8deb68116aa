"""From command-line options to the dataclasses of a run: the one configuration path of the CLI.

An option the user leaves out arrives as None. A named configuration fills the ones it names
(``--config FILE``, then ``--preset NAME``; the command line wins over both); whatever is still
None takes the default of the dataclass it belongs to (``Stack``, ``AgentConfig``,
``StopConfig``, ``RunSpec``), so no default is written twice.

A configuration is a TOML file of ``option = value`` lines, the options' names with
underscores (``min_stop_step = 10`` for ``--min-stop-step``, ``distinct_views = false`` for
``--repeated-views``), and optionally ``base = "NAME"``: a preset it starts from. The presets
are the files ``configs/NAME.toml`` shipped in the package, each saying what it holds:
``paper`` (the paper's experiments: HM-EQA in Habitat-Sim, GPT-4o, BLIP-2 ITM; ExploreEQA's
Habitat set-up, docs/habitat.md, "Fidelity to ExploreEQA"), ``paper-offline`` (the paper's
algorithm, ``agent.PAPER_CONFIG``, on the offline default stack) and one per row of
experiments/main_table.sh.
"""

from __future__ import annotations

import difflib
import sys
from collections.abc import Iterator, Mapping
from dataclasses import fields, replace
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from efficienteqa.errors import EfficientEQAError

if TYPE_CHECKING:
    from efficienteqa.agent import AgentConfig
    from efficienteqa.stack import Stack


# Command-line names of StopConfig fields (the others are named as their fields).
_STOP_OPTIONS = {"z_th": "z_th", "z_gated": "z_gated", "min_stop_step": "min_step",
                 "stop_rule": "rule"}
_TYPE_NAMES = {bool: "true or false", int: "an integer", float: "a number", str: "a string",
               Path: "a path (a string)"}


def _configs() -> Any:
    return resources.files("efficienteqa") / "configs"


def preset_names() -> list[str]:
    """The presets shipped with the package: ``configs/*.toml``."""
    return sorted(f.name[:-5] for f in _configs().iterdir() if f.name.endswith(".toml"))


def _read_toml(text: str, where: str) -> dict[str, Any]:
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        try:
            import tomli as tomllib
        except ImportError:
            raise EfficientEQAError(f"cannot read {where}: TOML needs Python 3.11 or tomli",
                                    fix="pip install tomli") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise EfficientEQAError(f"{where} is not valid TOML: {exc}",
                                fix="write one option = value per line, as configs/paper.toml "
                                "does") from None


def _check(values: Mapping[str, Any], schema: Mapping[str, type] | None, where: str,
           folder: Path | None) -> dict[str, Any]:
    """The values, each of the type ``schema`` gives its option (ints are numbers too; a path
    is relative to ``folder``, the file's own); an unknown key or a wrong type is one error."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        if schema is None:
            out[key] = value
            continue
        if key not in schema:
            near = difflib.get_close_matches(key, list(schema), n=1)
            raise EfficientEQAError(f"unknown option {key!r} in {where}",
                                    fix=f"did you mean {near[0]!r}?" if near else
                                    "use the options' names with underscores, e.g. "
                                    "min_stop_step = 10 for --min-stop-step (see --help)")
        kind = schema[key]
        ok = (isinstance(value, bool) if kind is bool else
              isinstance(value, (int, float)) and not isinstance(value, bool) if kind is float else
              isinstance(value, int) and not isinstance(value, bool) if kind is int else
              isinstance(value, str))
        if not ok:
            raise EfficientEQAError(f"{key} in {where} must be {_TYPE_NAMES.get(kind, kind)}, "
                                    f"not {value!r}", fix="e.g. " + {
                                        bool: f"{key} = true", int: f"{key} = 5",
                                        float: f"{key} = 3.0"}.get(kind, f'{key} = "text"'))
        if kind is float:
            value = float(value)
        elif kind is Path:
            value = Path(value).expanduser()
            if folder is not None and not value.is_absolute():
                value = folder / value
        out[key] = value
    return out


def _resolve(text: str, where: str, schema: Mapping[str, type] | None, folder: Path | None,
             seen: tuple[str, ...]) -> dict[str, Any]:
    raw = _read_toml(text, where)
    base = raw.pop("base", None)
    values = _check(raw, schema, where, folder)
    if base is None:
        return values
    if not isinstance(base, str):
        raise EfficientEQAError(f"base in {where} must be a preset's name, not {base!r}",
                                fix=f"use one of {', '.join(preset_names())}")
    return {**load_preset(base, schema, seen=(*seen, where)), **values}


def load_preset(name: str, schema: Mapping[str, type] | None = None, *,
                seen: tuple[str, ...] = ()) -> dict[str, Any]:
    """The options the preset ``configs/NAME.toml`` sets, its base's included."""
    names = preset_names()
    if name not in names:
        raise EfficientEQAError(f"unknown preset {name!r}", fix=f"use one of {', '.join(names)}")
    where = f"configs/{name}.toml"
    if where in seen:
        raise EfficientEQAError(f"the presets' bases go round in a circle: {' -> '.join(seen)}",
                                fix="give the file a base that does not lead back to it")
    return _resolve((_configs() / f"{name}.toml").read_text(encoding="utf-8"), where, schema,
                    None, seen)


def load_config(path: Path, schema: Mapping[str, type] | None = None) -> dict[str, Any]:
    """The options a configuration file sets (``base`` included); paths in it are relative to
    the file's folder. Unreadable, not TOML, an unknown option or a wrong type: one error."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise EfficientEQAError(f"cannot read the configuration {path}: {reason}",
                                fix="give a TOML file of option = value lines, e.g. a copy of "
                                "a preset (efficienteqa/configs/*.toml)") from None
    return _resolve(text, str(path), schema, Path(path).resolve().parent, ())


class _Presets(Mapping[str, dict[str, Any]]):
    """``PRESETS[name]``: what ``load_preset(name)`` sets, read when asked."""

    def __getitem__(self, name: str) -> dict[str, Any]:
        if name not in preset_names():
            raise KeyError(name)
        return load_preset(name)

    def __iter__(self) -> Iterator[str]:
        return iter(preset_names())

    def __len__(self) -> int:
        return len(preset_names())


PRESETS: Mapping[str, dict[str, Any]] = _Presets()


def fill(options: Mapping[str, Any], values: Mapping[str, Any],
         given: Any = None) -> dict[str, Any]:
    """``options`` with ``values``'s value for each option not ``given`` (default: the options
    left out, None); options ``values`` does not name are kept as they are."""
    return {k: values[k] if k in values and (k not in given if given is not None else v is None)
            else v for k, v in options.items()}


def judge_follows_vlm(options: Mapping[str, Any], values: Mapping[str, Any],
                      given: Any) -> dict[str, Any]:
    """``options`` where a configuration grades with its own VLM (``values``' judge is its vlm:
    the paper preset's "the same GPT-4o grades") and the command line (``given``) names another
    VLM but no judge: the judge follows that VLM, so the user's server grades too and no key
    goes to the configuration's server unasked."""
    out = dict(options)
    if (values.get("judge") is not None and values.get("judge") == values.get("vlm")
            and "vlm" in given and "judge" not in given and "judge" in out):
        out["judge"] = out["vlm"]
    return out


def apply_preset(name: str | None, options: Mapping[str, Any]) -> dict[str, Any]:
    """``options`` with the preset's value for each option left out (None); options the preset
    does not name are kept as they are."""
    return dict(options) if name is None else fill(options, load_preset(name))


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
        config = AgentConfig(stop=stop, **given(options, agent_fields))
    except ValueError as exc:  # a value the dataclass refuses, e.g. --prompts bogus
        raise EfficientEQAError(str(exc), fix="see efficienteqa ask --help") from None
    from efficienteqa.stop.rules import z_th_acts

    if options.get("z_th") is not None and not z_th_acts(config.gate):
        raise EfficientEQAError(
            f"--z-th {options['z_th']:g} does not act with the {config.gate} gate: it judges every "
            f"frame, and a frame it passes stops at --z-gated ({config.stop.z_gated:g}), one it "
            "turns down never", fix="use --z-gated, or --gate model or none (Z_th then decides)")
    return config


def named_configuration(preset: str | None, config_file: Path | None,
                        schema: Mapping[str, type] | None = None) -> tuple[str | None, dict[str, Any]]:
    """The named configuration a run's options start from: its name (the ``--config`` file's,
    without its suffix, else the preset's; None for neither: the defaults) and the options it
    sets (the file's over the preset's, as the command line is filled). A run records both
    (``RunSpec.preset``, ``preset_config``): its table label names what it changed against them."""
    values: dict[str, Any] = {}
    if preset is not None:
        values.update(load_preset(preset, schema))
    if config_file is not None:
        values.update(load_config(config_file, schema))
    return (Path(config_file).stem if config_file is not None else preset), values
