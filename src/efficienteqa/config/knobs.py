"""Knobs: the fields of the configuration dataclasses, walked as one tree.

A run's configuration is a tree of frozen dataclasses (``config.run.RunConfig``: ``backends``,
``scene``, ``explore``, ``stop``, ``answer``, ``eval``). Each field declares itself with
``knob(default, help=...)``: its help text, whether it goes beyond the paper, and the flat name
it had before the tree (one release of aliases). Everything else derives from the fields:

- ``leaves(cls)``: every settable value, by its path (``("stop", "z_th")``), with its type,
  default and help; the CLI's flags (``--stop.z-th``), the TOML sections of ``--config`` and the
  record's tree are all made from these;
- a field whose metadata names a dataclass (``of=SFEConfig``) holds a dict of overrides of that
  dataclass's fields, so its constants are reachable (``--explore.sfe.view-gain``) while the
  dataclass it overrides stays the one the code builds;
- ``build(cls, tree)`` makes the dataclass from a nested dict (left-out fields keep their
  defaults); ``dataclasses.asdict`` is the reverse (the record's form);
- ``flat_names(cls)`` maps the flat names of the sections' own fields (``top_k``, and the
  aliases ``min_stop_step``...) to their paths: how older records and files are read;
- ``with_leaves(obj, top_k=3)`` sets fields by their flat names.

Pure: no I/O, no third-party imports.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, fields, is_dataclass
from pathlib import Path
from typing import Any

Path_ = tuple[str, ...]


def knob(default: Any = MISSING, *, help: str, beyond: bool = False, alias: str | None = None,
         off: str | None = None, of: type | None = None, skip: tuple[str, ...] = (),
         default_factory: Any = MISSING) -> Any:
    """A configuration field: ``help`` for ``--help``; ``beyond``: an option beyond the paper
    (marked so in help); ``alias``: its flat name before the tree, if not its own; ``off``: a
    bool's flat "off" flag (``repeated_views`` for ``distinct_views``); ``of``: the dataclass a
    dict field overrides, less the fields in ``skip`` (set elsewhere)."""
    meta = {"help": help, "beyond": beyond, "alias": alias, "off": off, "of": of, "skip": skip}
    if default_factory is not MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


@dataclass(frozen=True)
class Leaf:
    """One settable value: ``path`` from the root, ``kind`` its type (bool, int, float, str,
    Path or dict), ``optional`` whether None is a value."""

    path: Path_
    kind: type
    optional: bool
    default: Any
    help: str
    beyond: bool
    alias: str | None
    off: str | None

    @property
    def dotted(self) -> str:
        return ".".join(self.path)


def _kind(hint: Any) -> tuple[type, bool]:
    """(the base type, whether None is allowed) of a field's type hint."""
    optional = False
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        optional = len(args) < len(typing.get_args(hint))
        hint = args[0]
        origin = typing.get_origin(hint)
    if origin is typing.Literal:
        return type(typing.get_args(hint)[0]), optional
    if origin in (dict, Mapping) or hint in (dict, Mapping):
        return dict, optional
    if hint in (bool, int, float, str, Path):
        return hint, optional
    return str, optional


def _default(f: dataclasses.Field) -> Any:
    if f.default is not MISSING:
        return f.default
    if f.default_factory is not MISSING:
        return f.default_factory()
    return MISSING


@typing.no_type_check
def leaves(cls: type, prefix: Path_ = (), skip: tuple[str, ...] = (),
           defaults: Any = None) -> list[Leaf]:
    """Every settable value of the dataclass ``cls``, depth first, in field order; a leaf's
    default is ``defaults``' value where given (a section built by a factory), else its
    field's."""
    hints = typing.get_type_hints(cls)
    out: list[Leaf] = []
    for f in fields(cls):
        if f.name in skip:
            continue
        hint, meta = hints[f.name], f.metadata
        default = getattr(defaults, f.name) if defaults is not None else _default(f)
        of = meta.get("of")
        if of is not None:
            out += leaves(of, (*prefix, f.name), meta.get("skip", ()), make(of, default or {}))
            continue
        if is_dataclass(hint):
            out += leaves(hint, (*prefix, f.name), (),
                          default if default is not MISSING else None)
            continue
        kind, optional = _kind(hint)
        out.append(Leaf((*prefix, f.name), kind, optional, default, meta.get("help", ""),
                        bool(meta.get("beyond")), meta.get("alias"), meta.get("off")))
    return out


def _overrides(cls: type, tree: Mapping[str, Any], where: str,
               skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """``tree`` checked against the fields of ``cls`` (nested dataclasses as dicts)."""
    names = {f.name: f for f in fields(cls) if f.name not in skip}
    hints = typing.get_type_hints(cls)
    out: dict[str, Any] = {}
    for key, value in tree.items():
        if key not in names:
            raise KeyError(f"{where}{key}")
        hint = hints[key]
        if is_dataclass(hint) and isinstance(value, Mapping):
            out[key] = _overrides(typing.cast(type, hint), value, f"{where}{key}.")
        else:
            out[key] = value
    return out


def build(cls: type, tree: Mapping[str, Any]) -> Any:
    """The dataclass ``cls`` from a nested dict, over its defaults: a section keeps the fields
    the dict leaves out at its default (the one its parent's factory gives), a field with
    ``of=`` keeps a checked dict of overrides, the rest are values. A key that is no field
    raises ``KeyError`` naming its dotted path; a value the dataclass refuses, its ValueError."""
    return apply(cls(), tree)


def apply(obj: Any, tree: Mapping[str, Any], where: str = "") -> Any:
    """``obj`` (a dataclass) with ``tree``'s values, as ``build`` reads them."""
    names = {f.name: f for f in fields(obj)}
    values: dict[str, Any] = {}
    for key, value in tree.items():
        if key not in names:
            raise KeyError(f"{where}{key}")
        current, of = getattr(obj, key), names[key].metadata.get("of")
        if of is not None and isinstance(value, Mapping):
            values[key] = _overrides(of, value, f"{where}{key}.",
                                     names[key].metadata.get("skip", ()))
        elif is_dataclass(current) and isinstance(value, Mapping):
            values[key] = apply(current, value, f"{where}{key}.")
        else:
            values[key] = value
    return dataclasses.replace(obj, **values)


def make(cls: type, overrides: Mapping[str, Any], base: Any = None) -> Any:
    """``base`` (default ``cls()``) with the overrides of an ``of=`` field applied, nested
    dataclasses included: how a section's ``sfe`` dict becomes the ``SFEConfig`` it overrides."""
    obj = base if base is not None else cls()
    values: dict[str, Any] = {}
    for key, value in overrides.items():
        current = getattr(obj, key)
        values[key] = (make(type(current), value, current)
                       if is_dataclass(current) and isinstance(value, Mapping) else value)
    return dataclasses.replace(obj, **values)


def nest(flat: Mapping[Path_, Any]) -> dict[str, Any]:
    """``{("stop", "z_th"): 2.0}`` as ``{"stop": {"z_th": 2.0}}``."""
    out: dict[str, Any] = {}
    for path, value in flat.items():
        node = out
        for part in path[:-1]:
            node = node.setdefault(part, {})
        node[path[-1]] = value
    return out


def flatten(tree: Mapping[str, Any], prefix: Path_ = ()) -> dict[Path_, Any]:
    """The reverse of ``nest``: every non-dict value by its path."""
    out: dict[Path_, Any] = {}
    for key, value in tree.items():
        if isinstance(value, Mapping) and value:
            out.update(flatten(value, (*prefix, key)))
        elif not isinstance(value, Mapping):
            out[(*prefix, key)] = value
    return out


def flat_names(cls: type) -> dict[str, Path_]:
    """The flat name of each section field of ``cls`` (a leaf two deep, or an ``of=`` dict), and
    of each alias, to its path: ``{"top_k": ("answer", "top_k"), "min_stop_step": ("stop",
    "min_step"), ...}``. Names are unique across sections (a test holds them so)."""
    out: dict[str, Path_] = {}
    for section in fields(cls):
        for f in fields(typing.get_type_hints(cls)[section.name]):
            path = (section.name, f.name)
            out[f.name] = path
            if f.metadata.get("alias"):
                out[f.metadata["alias"]] = path
    return out


def with_leaves(obj: Any, **values: Any) -> Any:
    """``obj`` (a dataclass of sections) with fields set by their flat names (``flat_names``):
    ``with_leaves(config, top_k=10, gate="none")``. A section's own name with a dataclass
    value replaces the whole section first (``stop=StopConfig(rule="paper")``)."""
    index = flat_names(type(obj))
    sections = {f.name for f in fields(obj)}
    whole = {k: v for k, v in values.items() if k in sections and is_dataclass(v)}
    obj = dataclasses.replace(obj, **whole)
    by_section: dict[str, dict[str, Any]] = {}
    for name, value in values.items():
        if name in whole:
            continue
        if name not in index:
            raise TypeError(f"{type(obj).__name__} has no setting {name!r}")
        section, field_name = index[name]
        by_section.setdefault(section, {})[field_name] = value
    return dataclasses.replace(obj, **{s: dataclasses.replace(getattr(obj, s), **v)
                                       for s, v in by_section.items()})
