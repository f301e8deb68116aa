"""The options of an agent run, made from the configuration tree's fields (``knobs.leaves``).

``@run_options(...)`` gives a command one typer option per value of ``config.run.RunConfig``:
``--stop.z-th`` (the flat ``--z-th`` of before the sections stays, hidden, for one release), grouped in
``--help`` by section, each with its field's help and default, options beyond the paper marked;
the explorer's and the steering's constants (``--explore.sfe.*``, ``--explore.target.*``) only
in ``--help-all``.
Left out, an option is None, so a value the user gave is told apart from a default, and
``--config``/``--preset`` fill only what was left out (``presets.resolve``). The command itself
receives ``run: presets.Resolved`` in their place.
"""

from __future__ import annotations

import functools
import inspect
import json
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import click
import typer

from efficienteqa.config.knobs import Leaf, leaves
from efficienteqa.config.run import SECTION_TITLES, RunConfig

PRESET_HELP = ("A named configuration shipped with the package (efficienteqa/config/toml/NAME.toml): "
               "paper (the paper's set-up: HM-EQA's first 100 in Habitat-Sim, GPT-4o at T=1 on "
               "RGB, BLIP-2 ITM, Z_th 3, K 5) | paper-offline (the paper's algorithm on the "
               "offline stack) | a main-table row: default, pixels, paper-offline-pixels, "
               "explore-eqa, explore-eqa-blackbox, explore-eqa-verbalized-prompt, "
               "explore-eqa-per-token, frontier-only, random, blind. Fills only options not given.")
CONFIG_HELP = ("A TOML file with a table per group below, named as the options' first part "
               "(a stop table holding z_th = 2 sets --stop.z-th), and base = \"PRESET\" to start "
               "from a preset. Fills options not given on the command line, before --preset.")
_SEP = "__"  # a path as a Python parameter name: stop__z_th
CONSTANTS_PANEL = ": constants"  # the panel of the constants only --help-all shows
MORE_PANEL = ": more"  # a section's rarer options, also only in --help-all
HELP_ALL_PANELS = (CONSTANTS_PANEL, MORE_PANEL)
# The options --help leaves to --help-all: a server's fine print, the stop rule's and the
# baselines' internals, the map's extent; what a first run needs stays in --help.
MORE = frozenset({
    "backends.image_format", "backends.image_max_side", "backends.image_detail",
    "backends.capabilities", "backends.device", "backends.relevancy_weights",
    "backends.allow_download", "backends.api_key_env", "backends.timeout_s", "backends.retries",
    "backends.cache", "backends.sightings",
    "stop.sigma_eps", "stop.sigma_floor", "stop.sim_abs", "stop.gate_final", "stop.count_from",
    "stop.question_words",
    "answer.answer_probability", "answer.token_answer", "answer.step_weight",
    "answer.answer_every_step", "answer.confidence", "answer.answer_at",
    "explore.map_extent", "explore.map_size_m", "explore.refusal_retries",
    "explore.stop_clearance_m", "explore.exploration", "explore.prompts"})


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _shown(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else json.dumps(value) if isinstance(
        value, dict) else str(value)


def _parameter(leaf: Leaf, alias: bool = False) -> inspect.Parameter | None:
    """The option of ``leaf``: ``--section.name``; with ``alias``, the hidden flat option it
    had before the sections (``--z-th``), or None where it had none."""
    flat = (leaf.alias or leaf.path[-1]) if len(leaf.path) == 2 else None
    if alias and flat is None:
        return None
    dotted = ".".join(part.replace("_", "-") for part in leaf.path)
    deep = len(leaf.path) > 2  # a constant an ``of=`` dict overrides
    help_text = (leaf.help or f"The {'.'.join(leaf.path[1:])} constant.") + _whose(leaf, deep)
    if leaf.default is not None and not alias:
        help_text += f" (default: {_shown(leaf.default)})"
    if leaf.kind is bool:
        off = f"--{dotted.rsplit('.', 1)[0]}." + (leaf.off or "no_" + leaf.path[-1]).replace("_", "-")
        decls = ([f"{_flag(flat)}/{_flag(leaf.off or 'no_' + flat)}"] if alias and flat
                 else [f"--{dotted}/{off}"])
    else:
        decls = [_flag(flat)] if alias and flat else [f"--{dotted}"]
    kind: Any = str if leaf.kind is dict else leaf.kind
    more = ".".join(leaf.path) in MORE
    option = typer.Option(None, *decls, help=help_text, show_default=False,
                          hidden=alias or deep or more,
                          rich_help_panel=SECTION_TITLES[leaf.path[0]] + (
                              CONSTANTS_PANEL if deep else MORE_PANEL if more else ""),
                          metavar="JSON" if leaf.kind is dict else None)
    return inspect.Parameter(("alias" + _SEP if alias else "") + _SEP.join(leaf.path),
                             inspect.Parameter.KEYWORD_ONLY, default=option,
                             annotation=kind | None)


def _help_all(ctx: click.Context, _: click.Parameter, value: bool) -> None:
    """``--help-all``: the help with the options ``--help`` leaves out (the constants and the
    rarer options, whose panels end in HELP_ALL_PANELS), then exit."""
    if not value or ctx.resilient_parsing:
        return
    for p in ctx.command.params:
        if str(getattr(p, "rich_help_panel", "") or "").endswith(HELP_ALL_PANELS):
            p.hidden = False  # type: ignore[attr-defined]
    typer.echo(ctx.get_help(), color=ctx.color)
    ctx.exit()


def _whose(leaf: Leaf, deep: bool) -> str:
    """Whose a setting is, as its help ends: the paper's where it is (the frontier explorer's
    constants from ExploreEQA's SFE, ``PAPER_SFE_CONSTANTS``), else beyond the paper."""
    from efficienteqa.explore.settings import PAPER_SFE_CONSTANTS

    if deep and leaf.path[:2] == ("explore", "sfe"):
        name = ".".join(leaf.path[2:])
        return (" The paper's (ExploreEQA's SFE, DESIGN 3.2)." if name in PAPER_SFE_CONSTANTS
                else " Beyond the paper.")
    return " Beyond the paper." if leaf.beyond or deep else ""


def tree_leaves(sections: Iterable[str] | None = None,
                only: dict[str, tuple[str, ...]] | None = None) -> list[Leaf]:
    """The leaves of ``sections`` (default: all), and of the sections in ``only`` just the
    fields it names."""
    only = only or {}
    return [leaf for leaf in leaves(RunConfig)
            if (sections is None or leaf.path[0] in sections or leaf.path[0] in only)
            and (leaf.path[0] not in only or leaf.path[1] in only[leaf.path[0]])]


def run_options(sections: Iterable[str] | None = None,
                only: dict[str, tuple[str, ...]] | None = None, *, by_method: bool = True) -> Callable:
    """Decorate a command ``f(run, **own)``: its parameters become ``own`` plus ``--preset``,
    ``--config`` and one option per leaf (``tree_leaves``); ``run`` is the resolved tree
    (``by_method``: the command runs the method's configuration, ``presets.resolve``)."""
    chosen = tree_leaves(sections, only)

    def decorate(command: Callable) -> Callable:
        named = [inspect.Parameter("preset", inspect.Parameter.KEYWORD_ONLY, annotation=str | None,
                                   default=typer.Option(None, help=PRESET_HELP, show_default=False,
                                                        rich_help_panel="Configuration")),
                 inspect.Parameter("config_file", inspect.Parameter.KEYWORD_ONLY,
                                   annotation=Path | None,
                                   default=typer.Option(None, "--config", metavar="FILE",
                                                        help=CONFIG_HELP, show_default=False,
                                                        rich_help_panel="Configuration")),
                 inspect.Parameter(
                     "help_all", inspect.Parameter.KEYWORD_ONLY, annotation=bool,
                     default=typer.Option(False, "--help-all", is_eager=True, expose_value=False,
                                          callback=_help_all, rich_help_panel="Configuration",
                                          help="Show every option (the rarer ones, and the "
                                               "explorer's and the steering's constants), and "
                                               "exit."))]
        generated = [p for leaf in chosen for alias in (False, True)
                     if (p := _parameter(leaf, alias)) is not None]

        def call(kwargs: dict[str, Any]) -> Any:
            from efficienteqa.config.presets import resolve

            kwargs.pop("help_all", None)  # acted already, eagerly (_help_all)
            given = given_values(chosen, kwargs)
            run = resolve(given, kwargs.pop("preset"), kwargs.pop("config_file"),
                          by_method=by_method)
            return command(run=run, **kwargs)

        return _with_parameters(command, "run", [*named, *generated], call)

    return decorate


def given_values(chosen: list[Leaf], kwargs: dict[str, Any]) -> dict[str, Any]:
    """The values of ``chosen`` given on the command line, by dotted path, taken out of a
    command's ``kwargs`` (a dotted option wins over its flat alias) and checked."""
    from efficienteqa.config.presets import check_value

    given: dict[str, Any] = {}
    for leaf in chosen:
        value = kwargs.pop(_SEP.join(leaf.path))
        flat = kwargs.pop("alias" + _SEP + _SEP.join(leaf.path), None)
        value = flat if value is None else value
        if value is not None:
            value = _json(value, leaf) if leaf.kind is dict else value
            given[leaf.dotted] = check_value(leaf.dotted, value, "the command line")
    return given


def _json(text: str, leaf: Leaf) -> dict:
    try:
        value = json.loads(text)
    except ValueError:
        value = None
    if not isinstance(value, dict):
        raise click.BadParameter(f"give a JSON object, e.g. '{json.dumps(leaf.default)}'",
                                 param_hint=f"--{leaf.dotted}")
    return value


def job_options(cls: type) -> Callable:
    """Decorate a command ``f(job, **own)``: ``job`` becomes one option per field of the
    dataclass ``cls`` (``--frames-per-house``), with its help and default (a field without one
    is required; a bool is a flag), and ``f`` receives ``cls(**values)``."""
    from dataclasses import MISSING

    chosen = leaves(cls)

    def decorate(command: Callable) -> Callable:
        generated = [inspect.Parameter(
            leaf.path[0], inspect.Parameter.KEYWORD_ONLY,
            annotation=leaf.kind | None if leaf.optional else leaf.kind,
            default=typer.Option(... if leaf.default is MISSING else leaf.default,
                                 _flag(leaf.path[0]), help=leaf.help,
                                 show_default=leaf.default is not None))
            for leaf in chosen]

        def call(kwargs: dict[str, Any]) -> Any:
            job = cls(**{leaf.path[0]: kwargs.pop(leaf.path[0]) for leaf in chosen})
            return command(job=job, **kwargs)

        return _with_parameters(command, "job", generated, call)

    return decorate


def _with_parameters(command: Callable, made: str, added: list[inspect.Parameter],
                     call: Callable[[dict[str, Any]], Any]) -> Callable:
    """``command`` as typer sees it: its own parameters but ``made`` (which ``call`` makes from
    the others), then ``added``; typer's values go to ``call`` as one dict."""
    own = [p for p in inspect.signature(command, eval_str=True).parameters.values()
           if p.name != made]

    @functools.wraps(command)
    def wrapper(**kwargs: Any) -> Any:
        return call(kwargs)

    params = [*own, *added]
    wrapper.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
    wrapper.__annotations__ = {p.name: p.annotation for p in params}
    return wrapper
