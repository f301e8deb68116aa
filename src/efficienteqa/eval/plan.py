"""What an evaluation run is, decided from the configuration tree before anything slow: the
checks of its back-ends and method, the judge chosen, and the ``RunSpec`` every episode shares.

``efficienteqa eval`` calls ``plan_run``; so can a library caller, with the same refusals in
the same words (a closed-set run on a dataset without choices, a rule judge on HM-EQA, a
misspelt local model), each one line and before a house is built.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Collection
from pathlib import Path
from typing import TYPE_CHECKING

from efficienteqa.agent import AgentConfig
from efficienteqa.ask_plan import check_backends
from efficienteqa.config.run import RunConfig
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.judge_prompts import DEFAULT_JUDGE_MODE, judge_mode
from efficienteqa.eval.methods import METHODS, RunSpec, default_judge, resolve

if TYPE_CHECKING:
    from efficienteqa.datasets.base import EvalQuestion


def judge_of(run: RunConfig) -> str | None:
    """The run's LLM-Match judge (None: the rule judge alone, or none), checked: a closed-set
    run grades its letters, a synthetic dataset is graded by the rule judge for free."""
    from efficienteqa.stack import parse_vlm

    e = run.eval
    spec = e.judge or ("none" if e.closed_set else default_judge(e.dataset))
    if spec == "rule" and not e.dataset.startswith("synthetic"):
        raise EfficientEQAError(f"the rule judge grades synthetic questions only, not {e.dataset}",
                                fix="give a judge model (--eval.judge local:MODEL or "
                                    "openai:MODEL)")
    spec = None if spec in ("none", "rule") else spec
    if spec:
        parse_vlm(spec, images=False, flag="--eval.judge")
    return spec


def mode_of(mode: str | None, judge: str) -> str:
    """The judge's mode, left out: ``eval.judge_prompts.DEFAULT_JUDGE_MODE`` ("auto": token
    probabilities for the small local models, the 1-5 grade otherwise)."""
    return judge_mode(mode or DEFAULT_JUDGE_MODE, judge)


def _check_user_agent(run: RunConfig) -> None:
    """A user's agent class (``eval.agents``) is configured by its own code: the sections that
    configure the built-in agent (explore, stop, answer) would change nothing, so a run that
    sets them is refused."""
    from efficienteqa.eval.agents import is_agent_class, load_method

    if is_agent_class(load_method(run.eval.method)) and run.agent != AgentConfig():
        raise EfficientEQAError(f"{run.eval.method} is your own agent: the explore, stop and "
                                "answer settings configure the built-in one and would not act",
                                fix="leave them out (your agent reads only --backends.vlm, as "
                                    "info['vlm'])")


def plan_run(run: RunConfig, preset: str | None = None,
             preset_agent: AgentConfig | None = None) -> RunSpec:
    """The ``RunSpec`` of ``run`` (its method, dataset, back-ends, agent, judge and scenes),
    after every check that needs no scene: the method exists, the back-ends can be built, the
    closed-set mode fits the dataset and the method. ``preset`` and ``preset_agent``: the named
    configuration the options started from, for the run's table label."""
    e = run.eval
    resolve(e.method)  # an unknown method fails here
    if e.method not in METHODS:
        _check_user_agent(run)
    check_backends(run)
    if e.closed_set and e.dataset != "hm-eqa":
        raise EfficientEQAError(f"--eval.closed-set is HM-EQA's multiple-choice mode; "
                                f"{e.dataset} has no choices",
                                fix="use --eval.dataset hm-eqa, or leave out --eval.closed-set")
    if e.closed_set and e.method in METHODS and e.method != "blind":
        raise EfficientEQAError(f"method {e.method!r} answers open-ended only; --eval.closed-set "
                                "is answered by blind (or a module:function method that sets "
                                "extra['letter'])", fix="use --eval.method blind")
    judge = judge_of(run)
    return RunSpec(run, judge=judge, judge_mode=mode_of(e.judge_mode, judge or ""),
                   preset=preset, preset_agent=preset_agent)


def prepare_run(spec: RunSpec, out: Path) -> list[EvalQuestion]:
    """The run's questions, once ``out`` is known to take the run: writable, and not a folder
    of another run (refused before the dataset's houses are built: minutes with the furniture
    of --scene.assets sh3d; ``run_eval`` checks again under the folder's lock)."""
    from efficienteqa.datasets import load_dataset
    from efficienteqa.eval.records import check_resumable
    from efficienteqa.eval.runner import manifest
    from efficienteqa.records import check_writable

    e = spec.run.eval
    check_writable(out)
    check_resumable(out, manifest(spec, 0))
    return load_dataset(e.dataset, path=e.hm_eqa_path, limit=e.limit, closed_set=e.closed_set,
                        assets=spec.run.scene.assets)


def episodes_done(out: Path, ids: Collection[str]) -> int:
    """How many of the questions ``ids`` are done in ``out`` (a line of another id is none)."""
    from efficienteqa.eval.records import read_episodes

    return len(read_episodes(out / "episodes.jsonl").done & set(ids))


def commonest_errors(out: Path, ids: Collection[str], n: int = 3) -> list[tuple[str, int]]:
    """The ``n`` commonest errors of the failed episodes among ``ids`` in ``out``."""
    from efficienteqa.eval.records import read_episodes

    asked = set(ids)
    return Counter(str(r.get("error")) for r in read_episodes(out / "episodes.jsonl").rows()
                   if r.get("status") != "done" and r["id"] in asked).most_common(n)
