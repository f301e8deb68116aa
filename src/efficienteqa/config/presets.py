"""From what the user gave to the run's configuration tree: the one configuration path of the CLI.

Values are keyed by their dotted path in ``config.run.RunConfig`` (``"stop.z_th"``). A run's
values come from three sources, each filling only what the ones before it left out: the command
line, ``--config FILE``, ``--preset NAME``; whatever is still left out keeps the default of its
dataclass, so no default is written twice (``resolve``).

A configuration is a TOML file with one table per section::

    base = "paper-offline"   # optional: the preset it starts from
    [stop]
    z_th = 2.0
    [explore.sfe]
    view_gain = false

A top-level key may also be a field's flat name from before the sections (``top_k = 3``,
``min_stop_step = 10``): it is read as the field it names. The presets are the files
``config/toml/NAME.toml`` shipped in the package, each saying what it holds: ``paper`` (the paper's
experiments: HM-EQA in Habitat-Sim, GPT-4o, BLIP-2 ITM), ``paper-offline`` (the paper's
algorithm, ``agent.PAPER_CONFIG``, on the offline default stack) and one per row of
experiments/main_table.sh.
"""

from __future__ import annotations

import difflib
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from efficienteqa.config.knobs import Leaf, build, flat_names, leaves, nest
from efficienteqa.config.run import RunConfig
from efficienteqa.errors import EfficientEQAError

if TYPE_CHECKING:
    from efficienteqa.agent import AgentConfig
    from efficienteqa.stack import Stack

_TYPE_NAMES = {bool: "true or false", int: "an integer", float: "a number", str: "a string",
               Path: "a path (a string)", dict: "a table"}


@cache
def leaf_index() -> dict[str, Leaf]:
    """Every settable value of a run, by its dotted path."""
    return {leaf.dotted: leaf for leaf in leaves(RunConfig)}


@cache
def _flat() -> dict[str, str]:
    return {name: ".".join(path) for name, path in flat_names(RunConfig).items()}


def dotted(name: str) -> str:
    """A value's dotted path from its dotted path or its flat name (``top_k``)."""
    return name if name in leaf_index() else _flat().get(name, name)


def _configs() -> Any:
    return resources.files("efficienteqa") / "config" / "toml"


def preset_names() -> list[str]:
    """The presets shipped with the package: ``config/toml/*.toml``."""
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
                                fix="write [section] tables of name = value lines, as "
                                "config/toml/paper.toml does") from None


def _unknown(key: str, where: str) -> EfficientEQAError:
    near = difflib.get_close_matches(key, [*leaf_index(), *_flat()], n=1)
    return EfficientEQAError(f"unknown option {key!r} in {where}",
                             fix=f"did you mean {near[0]!r}?" if near else
                             "use the sections of `efficienteqa ask --help`, e.g. [stop] z_th = 2")


def check_value(path: str, value: Any, where: str, folder: Path | None = None) -> Any:
    """``value`` as the leaf at ``path`` takes it (ints are numbers too; a path is relative to
    ``folder``, its file's own), or one error naming the option and what it must be."""
    leaf = leaf_index()[path]
    kind = leaf.kind
    ok = (isinstance(value, bool) if kind is bool else
          isinstance(value, (int, float)) and not isinstance(value, bool) if kind is float else
          isinstance(value, int) and not isinstance(value, bool) if kind is int else
          isinstance(value, Mapping) if kind is dict else
          isinstance(value, (str, Path)) if kind is Path else isinstance(value, str))
    if not ok:
        name = path.rsplit(".", 1)[-1]
        example = {bool: f"{name} = true", int: f"{name} = 5", float: f"{name} = 3.0",
                   dict: f"[{path}] key = 1.0"}.get(kind, f'{name} = "text"')
        raise EfficientEQAError(f"{path} in {where} must be {_TYPE_NAMES.get(kind, kind)}, not "
                                f"{value!r}", fix=f"e.g. {example}")
    if kind is float:
        return float(value)
    if kind is Path:
        value = Path(value).expanduser()
        return folder / value if folder is not None and not value.is_absolute() else value
    return dict(value) if kind is dict else value


def _values(raw: Mapping[str, Any], where: str, folder: Path | None,
            prefix: str = "") -> dict[str, Any]:
    """A TOML document's values by dotted path (sections as tables, flat names at the top)."""
    index = leaf_index()
    out: dict[str, Any] = {}
    for key, value in raw.items():
        path = f"{prefix}{key}"
        if path not in index and not prefix and not isinstance(value, Mapping):
            path = _flat().get(key, path)  # a flat name of before the sections
        section = any(p.startswith(path + ".") for p in index)
        if path in index:
            out[path] = check_value(path, value, where, folder)
        elif section and isinstance(value, Mapping):
            out.update(_values(value, where, folder, path + "."))
        elif section:  # ``stop = 3``: not an unknown option (nor a misspelt top_k)
            shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:40] + "..."
            raise EfficientEQAError(f"{path} in {where} is a section, so it must be a table, not "
                                    f"{shown}", fix=f"write [{path}] and name = value lines under "
                                    "it, as efficienteqa config prints them")
        else:
            raise _unknown(path, where)
    return out


def _resolve(text: str, where: str, folder: Path | None, seen: tuple[str, ...]) -> dict[str, Any]:
    raw = _read_toml(text, where)
    base = raw.pop("base", None)
    values = _values(raw, where, folder)
    if base is None:
        return values
    if not isinstance(base, str):
        raise EfficientEQAError(f"base in {where} must be a preset's name, not {base!r}",
                                fix=f"use one of {', '.join(preset_names())}")
    return {**load_preset(base, seen=(*seen, where)), **values}


def load_preset(name: str, *, seen: tuple[str, ...] = ()) -> dict[str, Any]:
    """The values the preset ``config/toml/NAME.toml`` sets, its base's included, by dotted path."""
    names = preset_names()
    if name not in names:
        raise EfficientEQAError(f"unknown preset {name!r}", fix=f"use one of {', '.join(names)}")
    where = f"config/toml/{name}.toml"
    if where in seen:
        raise EfficientEQAError(f"the presets' bases go round in a circle: {' -> '.join(seen)}",
                                fix="give the file a base that does not lead back to it")
    return _resolve((_configs() / f"{name}.toml").read_text(encoding="utf-8"), where, None, seen)


def load_config(path: Path) -> dict[str, Any]:
    """The values a configuration file sets (``base`` included); paths in it are relative to
    the file's folder. Unreadable, not TOML, an unknown option or a wrong type: one error. A
    run's own record (``run.json``, any format) gives the tree it ran with (``run_values``), so
    ``--config results/.../run.json`` runs a published row again."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise EfficientEQAError(f"cannot read the configuration {path}: {reason}",
                                fix="give a TOML file of [section] tables, e.g. a copy of a "
                                "preset (efficienteqa/config/toml/*.toml)") from None
    if Path(path).suffix == ".json":
        return run_values(text, str(path))
    return _resolve(text, str(path), Path(path).resolve().parent, ())


# Where a run's record keeps the tree's eval and scene settings (run.json's top-level keys).
_RECORD_KEYS = {"eval.method": "method", "eval.dataset": "dataset",
                "eval.closed_set": "closed_set", "eval.judge": "judge",
                "eval.judge_mode": "judge_mode", "eval.limit": "questions",
                "scene.env": "env", "scene.assets": "assets", "scene.hm3d_root": "hm3d_root",
                "scene.noise": "noise"}


def run_values(text: str, where: str) -> dict[str, Any]:
    """The tree's values a run's ``run.json`` recorded, by dotted path: from format 5 the tree
    itself (``run``); before, its options as given (``config``, read in today's format by
    ``eval.records.upgrade``), its back-ends (``stack``) and its method, dataset, judge,
    question count and scene settings. A value the record left as None keeps the default."""
    import json

    from efficienteqa.eval.records import upgrade

    try:
        record = json.loads(text)
    except ValueError as exc:
        raise EfficientEQAError(f"{where} is not JSON: {exc}",
                                fix="give a run's run.json or a TOML file") from None
    if not isinstance(record, dict) or not isinstance(record.get("config"), dict):
        raise EfficientEQAError(f"{where} is no run record (no config in it)",
                                fix="give the run.json of a run folder, or a TOML file")
    tree = record.get("run") if isinstance(record.get("run"), dict) else None
    record = upgrade(record)
    index = leaf_index()
    values: dict[str, Any] = {}

    def take(path: str, value: Any) -> None:
        if value is None or path not in index:
            return  # left to the default; a setting of an older release that is gone
        values[path] = check_value(path, value, where)

    for section, fields in (tree or record["config"]).items():  # format 5: the tree itself
        for name, value in (fields.items() if isinstance(fields, dict) else ()):
            if f"{section}.{name}" not in METHOD_SET:  # the method's own, set by it again
                take(f"{section}.{name}", value)
    if tree is not None:
        return values
    for name, value in (record.get("stack") or {}).items():
        take(f"backends.{name}", value)
    for path, key in _RECORD_KEYS.items():
        take(path, record.get(key))
    return values


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


def build_run(values: Mapping[str, Any] = {}) -> RunConfig:  # noqa: B006 - read only
    """The run's tree from values by dotted path or flat name, over the defaults. The one
    default that depends on another value: with ``backends.perception`` rgb and no relevancy
    given, the relevancy is an image scorer (``stack.default_relevancy``). A value a dataclass
    refuses (``top_k = 0``) is one error."""
    from efficienteqa.stack import default_relevancy

    given = {dotted(k): v for k, v in values.items() if v is not None}
    for key in given:
        if key not in leaf_index() and not any(p.startswith(key + ".") for p in leaf_index()):
            raise _unknown(key, "the options")
    if "backends.relevancy" not in given and given.get("backends.perception") == "rgb":
        given["backends.relevancy"] = default_relevancy("rgb", given.get(
            "backends.relevancy_weights"))
    try:
        return build(RunConfig, nest({tuple(k.split(".")): v for k, v in given.items()}))
    except ValueError as exc:  # e.g. --stop.rule bogus, --answer.top-k 0
        raise EfficientEQAError(str(exc), fix="see efficienteqa ask --help") from None


@dataclass(frozen=True)
class Resolved:
    """A run's tree, and the named configuration it started from: its name (the ``--config``
    file's stem, else the preset's; None for neither) and the tree of that alone, which a run
    records (``RunSpec.preset``, ``preset_config``) so its table label names what it changed."""

    run: RunConfig
    preset: str | None
    preset_run: RunConfig


def resolve(given: Mapping[str, Any], preset: str | None = None,
            config_file: Path | None = None, *, by_method: bool = True) -> Resolved:
    """The run of the values ``given`` on the command line, filled from ``config_file`` then
    ``preset``. Where the named configuration grades with its own VLM (the paper preset's "the
    same GPT-4o grades") and the command line names another VLM but no judge, the judge follows
    that VLM, so the user's server grades too and no key goes to the configuration's server
    unasked. A value given on the command line that the run would not use is refused in one line
    (``_check_acts``, ``inert.inert``; ``by_method``: the run's episodes are the method's
    configuration, as ``eval`` runs them; ``ask`` runs the agent as configured); one a preset or
    a file sets is marked where ``config`` prints the run (``to_toml``)."""
    named: dict[str, Any] = {}
    if preset is not None:
        named.update(load_preset(preset))
    if config_file is not None:
        named.update(load_config(config_file))
    named = {dotted(k): v for k, v in named.items()}
    given = {dotted(k): v for k, v in given.items() if v is not None}
    values = {**named, **given}
    if (named.get("eval.judge") is not None and named.get("eval.judge") == named.get(
            "backends.vlm") and "backends.vlm" in given and "eval.judge" not in given):
        values["eval.judge"] = given["backends.vlm"]
    run = build_run(values)
    _check_acts(run, values, given, by_method)
    name = Path(config_file).stem if config_file is not None else preset
    return Resolved(run, name, build_run(named))


def run_config(preset: str | None = None, values: Mapping[str, Any] | None = None, *,
               config_file: Path | None = None) -> RunConfig:
    """The whole configuration of a run, for a library call (``ask(..., run=)``): ``preset``'s
    (``config/toml/NAME.toml``) and ``config_file``'s, with ``values`` by dotted path on top
    (``{"stop.z_th": 2.0, "backends.vlm": "openai:gpt-4o"}``), checked as the command line
    checks its options: a bad value, or one that would not act, raises ``EfficientEQAError``
    in one line. It runs the agent as configured (``ask``'s sense)."""
    return resolve(values or {}, preset, config_file, by_method=False).run


# What a method sets on the agent (``eval.methods.method_config``): given otherwise to ``eval``,
# refused; in a configuration ``config`` prints, a comment.
METHOD_SET = ("explore.explorer", "answer.confidence", "answer.answer_at")


# How to make a refused setting act, where there is more to say than "leave it out".
_ACTS_WITH = {
    "stop.z_th": "use --stop.z-gated, or --stop.gate model or none (Z_th then decides)",
    "stop.z_gated": "use --stop.z-th, or a gate that judges every frame (--stop.gate rules)",
    "explore.sfe": "leave them out, or use a frontier explorer (sfe, frontier-only)",
    "explore.target": "leave them out, or use --explore.steering target with --eval.method "
                      "efficienteqa",
}


def _check_acts(run: RunConfig, values: Mapping[str, Any], asked: Mapping[str, Any],
                by_method: bool) -> None:
    """What the method sets (its explorer, confidence reading and answer source) is refused
    when given otherwise, and a setting ``asked`` for on the command line that the run would not
    use (``inert.inert``) is refused in one line rather than ignored."""
    from efficienteqa.config.inert import inert
    from efficienteqa.eval.methods import effective_config

    method = run.eval.method
    agent = (effective_config(method, run.agent) if by_method else None) or run.agent
    for path in METHOD_SET if by_method else ():
        section, name = path.split(".")
        ran = getattr(getattr(agent, section), name)
        if path in values and values[path] != ran:
            raise EfficientEQAError(f"--{path.replace('_', '-')} {values[path]} does not act: "
                                    f"method {method} sets it ({ran})",
                                    fix="choose the method instead (--eval.method; efficienteqa, "
                                    "explore-eqa, explore-eqa-blackbox, frontier-only, random)")
    idle = inert(run, agent)
    for path, value in asked.items():
        group = next((s for s in ("explore.sfe", "explore.target")
                        if path == s or path.startswith(s + ".")), None)
        why = idle.get(group or path)
        if why is None:
            continue
        if group is not None:
            if group == "explore.target" and agent.explore.steering != run.explore.steering:
                why += f" (explore.steering none; {method} never steers)"
            raise EfficientEQAError(f"--{group}.* sets constants that do not act: {why}",
                                    fix=_ACTS_WITH[group])
        shown = f"{value:g}" if isinstance(value, float) else value
        raise EfficientEQAError(f"--{path.replace('_', '-')} {shown} does not act: {why}",
                                fix=_ACTS_WITH.get(path, "leave it out"))


def build_config(values: Mapping[str, Any] = {}) -> AgentConfig:  # noqa: B006 - read only
    """The agent's configuration of ``values`` (``build_run``'s)."""
    return build_run(values).agent


def build_stack(values: Mapping[str, Any] = {}) -> Stack:  # noqa: B006 - read only
    """The back-ends of ``values`` (``build_run``'s)."""
    return build_run(values).backends


def to_toml(run: RunConfig) -> str:
    """``run`` as a ``--config`` file: one table per section, every value (a None, which TOML
    cannot hold, as a comment; a value the run would not use, ``inert.inert``, with a comment
    that says so), the overrides of ``explore.sfe``/``explore.target`` as tables of their own; ``load_config``
    reads it back to the same run."""
    import json
    from dataclasses import asdict

    from efficienteqa.config.inert import inert
    from efficienteqa.eval.methods import effective_config

    idle = inert(run, effective_config(run.eval.method, run.agent) or run.agent)

    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, Mapping):
            return "{" + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + "}"
        return json.dumps(str(v), ensure_ascii=False)  # a TOML basic string

    lines: list[str] = []
    tables: list[tuple[str, Mapping[str, Any]]] = []

    def table(name: str, values: Mapping[str, Any]) -> None:
        lines.append(f"[{name}]")
        for key, v in values.items():
            leaf = leaf_index().get(f"{name}.{key}")
            if isinstance(v, Mapping) and (leaf is None or leaf.kind is not dict):
                if v:
                    tables.append((f"{name}.{key}", v))
            elif v is None:
                lines.append(f"# {key} = (left to its default)")
            elif f"{name}.{key}" in METHOD_SET:
                lines.append(f"# {key} = {value(v)}  (set by eval.method)")
            elif (why := idle.get(f"{name}.{key}", idle.get(name))) is not None:
                lines.append(f"{key} = {value(v)}  # does not act: {why}")
            else:
                lines.append(f"{key} = {value(v)}")
        lines.append("")

    for section, values in asdict(run).items():
        table(section, values)
    while tables:
        table(*tables.pop(0))
    return "\n".join(lines)
