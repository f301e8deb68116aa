"""Run a method over a dataset: sequentially, or on Ray workers, resumably.

An episode is the unit of work and of failure. ``run_episode`` runs one and returns its line
for ``episodes.jsonl`` — the method's answer, steps and usage, the ``rule`` judge's grade where
the question lists its accepted answers (synthetic datasets), the ``choice`` grade of a
closed-set question (right when the chosen letter is the reference's), the LLM-Match judgement
where a judge model is given, the wall time — or, when anything goes wrong, a ``failed`` line with the
one-line error. Only the driver
appends lines (``records``); a re-run in the same folder skips the episodes already done and
retries the failed ones.

Ray (DESIGN 6): one task per episode, at most ``workers`` at a time, each task one CPU; a task
whose worker process dies is retried by Ray. Workers share the machine's model server (the
driver starts it first) and its response cache.
"""

from __future__ import annotations

import functools
import json
import logging
import os
import platform
import sys
import time
import traceback
from collections.abc import Callable, Collection, Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.agents import agent_identity
from efficienteqa.eval.methods import METHODS, RunSpec, effective_config, resolve, usage_of
from efficienteqa.eval.records import (
    EPISODES_FILE,
    RUN_FORMAT,
    append_episode,
    open_run,
    run_lock,
)
from efficienteqa.records import code_version, plain

Progress = Callable[[dict[str, Any]], None]
log = logging.getLogger(__name__)
# Environment variables whose names say they hold a secret (matched case-insensitively).
SECRET_MARKS = ("KEY", "TOKEN", "SECRET", "PASSWORD", "PASSWD", "CREDENTIAL")
# Ray binds its servers (GCS, raylet, every worker) to all interfaces unless its node's IP is the
# loopback one, which it takes only with its "clusters" off: this variable, read when ray is
# imported (ray._private.ray_constants; Ray's default on macOS and Windows). A local run needs
# no other machine to reach it; a cluster is opened on purpose (--eval.address, docs/SCALING.md).
# Set before the first import only: a process that imported Ray already keeps Ray's default.
RAY_LOOPBACK = ("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")


def episode_folder(out: Path, episode_id: str) -> Path:
    return out / "episodes" / episode_id.replace("/", "__")


@functools.cache
def build_judge(spec: str, mode: str) -> Any:
    """One judge per (spec, mode) and process: workers grade many episodes."""
    from efficienteqa.eval.judge import LLMMatchJudge
    from efficienteqa.models.backends import build_chat_model
    from efficienteqa.stack import parse_vlm

    return LLMMatchJudge(build_chat_model(parse_vlm(spec, images=False, flag="--judge")),
                         mode=mode)


def _rule(q: EvalQuestion, answer: str) -> dict[str, Any] | None:
    """The rule judge's grade, for questions that carry their accepted answers."""
    from efficienteqa.eval.synthetic_judge import RULE_CATEGORIES, rule_judgement

    if not q.accepted or q.category not in RULE_CATEGORIES:
        return None
    # A re-phrased question is graded as its original (its yes/no frame first); the words of
    # both wordings are the question's own, not answers ("the bookshelf next to the sofa").
    wording = q.question if q.original_question == q.question else f"{q.original_question} {q.question}"
    return rule_judgement(wording, q.category, q.accepted, answer).to_dict()


def _choice(q: EvalQuestion, extra: dict[str, Any]) -> dict[str, Any] | None:
    """Exact-letter grading of a closed-set question: the method's chosen letter
    (``extra["letter"]``) against the reference letter (``source["letter"]``)."""
    if not q.choices:
        return None
    letter, reference = extra.get("letter"), q.source.get("letter")
    correct = isinstance(letter, str) and letter.strip().upper() == str(reference).upper()
    return {"correct": correct, "value": 100.0 if correct else 0.0, "letter": letter,
            "reference_letter": reference}


def _judge(spec: RunSpec, q: EvalQuestion, answer: str) -> dict[str, Any] | None:
    """LLM-Match's judgement, where there is a judge and a reference answer to grade against
    (a question of your own may have none: it is run, not graded)."""
    if spec.judge is None or not q.answer.strip():
        return None
    judge = build_judge(spec.judge, spec.judge_mode)
    return judge.judge(q.question, q.answer, answer, extra=q.alternatives).to_dict()


def rejudge(out: Path, judge_spec: str, mode: str,
            on_episode: Progress | None = None) -> tuple[int, float]:
    """Grade every finished episode of the run in ``out`` again with another judge (or mode):
    each regraded row is appended as it is graded (a later line replaces the earlier one, so an
    interrupted regrade loses nothing), the file is compacted to one line per episode at the
    end, and ``run.json`` names the new judge. Returns the episodes graded and the run's
    LLM-Match as the report computes it (a failed episode scores 0)."""
    from efficienteqa.eval.records import RUN_FILE, compact_episodes, read_run
    from efficienteqa.eval.summary import summarise
    from efficienteqa.records import write_json

    manifest, episodes = read_run(out)
    judge = build_judge(judge_spec, mode)
    rows, graded = [], 0
    for row in episodes.rows():
        if row.get("status") == "done":
            verdict = judge.judge(row["question"], row["reference"], row.get("answer"),
                                  extra=row.get("alternatives") or ())
            row = {**row, "judge": verdict.to_dict()}
            append_episode(out / EPISODES_FILE, plain(row))
            graded += 1
            if on_episode is not None:
                on_episode(row)
        rows.append(row)
    compact_episodes(out / EPISODES_FILE)
    manifest = {**manifest, "judge": judge_spec, "judge_mode": mode}
    write_json(out / RUN_FILE, manifest)
    return graded, summarise(manifest, rows).llm_match


def run_episode(spec: RunSpec, q: EvalQuestion, out: Path) -> dict[str, Any]:
    """One episode, never raising: its ``episodes.jsonl`` line."""
    t0 = time.perf_counter()
    row = _identity(spec, q)
    row["worker"] = f"{platform.node()}:{os.getpid()}"
    try:
        outcome = resolve(spec.method)(q, spec, episode_folder(out, q.id))
        row.update(status="done", answer=outcome.answer, confidence=outcome.confidence,
                   steps=outcome.steps, budget=outcome.budget, stop_reason=outcome.stop_reason,
                   usage=outcome.usage, backends=outcome.backends, extra=outcome.extra,
                   evidence_first_seen_step=outcome.evidence_first_seen_step,
                   evidence_in_top_k=outcome.evidence_in_top_k,
                   evidence_stop_pixels=outcome.evidence_stop_pixels,
                   refused_moves=outcome.refused_moves)
        row["rule"] = _rule(q, outcome.answer)
        row["choice"] = _choice(q, outcome.extra)
        row["judge"] = _judge(spec, q, outcome.answer)
    except Exception as exc:  # noqa: BLE001 - one episode's failure must not end the run
        row.update(_failure(exc), traceback=traceback.format_exc(limit=6)[-2000:])
        partial = getattr(exc, "partial_episode", None)  # an agent episode that failed part-way
        if isinstance(partial, dict):  # its calls were paid for: count them
            row.update(steps=partial["steps"], usage=usage_of(partial["model"]["exchanges"]))
    row["wall_s"] = round(time.perf_counter() - t0, 3)
    row["finished"] = time.time()
    return plain(row)


def _identity(spec: RunSpec, q: EvalQuestion) -> dict[str, Any]:
    """What every line says of its episode, whatever happened to it."""
    return {"id": q.id, "dataset": q.dataset, "method": spec.method, "scene": q.scene,
            "question": q.question, "reference": q.answer, "alternatives": list(q.alternatives),
            "accepted": list(q.accepted), "category": q.category, "oracle_steps": q.oracle_steps}


def _failure(exc: BaseException) -> dict[str, Any]:
    message = str(exc).splitlines()[0] if str(exc) else ""
    return {"status": "failed", "error": f"{type(exc).__name__}: {message}".rstrip(": ")}


@dataclass
class RunResult:
    out: Path
    ran: int
    skipped: int
    failed: int
    wall_s: float

    @property
    def episodes_per_hour(self) -> float:
        return 3600.0 * self.ran / self.wall_s if self.wall_s > 0 else 0.0


def machine() -> dict[str, Any]:
    """Where a run ran: the platform, Python and the CPUs (``run.json``'s ``machine``)."""
    return {"platform": platform.platform(), "python": platform.python_version(),
            "cpus": os.cpu_count()}


def scene_seeds(scenes: Sequence[str]) -> dict[str, Any]:
    """The scenes of a run's questions, and for synthetic houses their seeds (``run.json``)."""
    names = sorted(set(scenes))
    seeds = sorted({int(s.partition(":")[2]) for s in names
                    if s.startswith("synthetic:") and s.partition(":")[2].isdigit()})
    return {"scenes": names, **({"seeds": seeds} if seeds else {})}


def manifest(spec: RunSpec, n_questions: int, scenes: Sequence[str] = (),
             ids: Sequence[str] | None = None) -> dict[str, Any]:
    """``run.json``: ``config`` holds the options as given (part of the run's identity);
    ``method_config``, what the method's episodes ran with (``methods.effective_config``);
    ``preset`` and ``preset_config``, the named configuration the options started from and
    what it alone set (a table's label, ``run_labels.label``); ``question_ids``, the episode ids
    of the questions (``ids``), so that a report counts no line of another question; ``run``,
    the whole configuration tree the run was made from (format 5), which ``--config run.json``
    reads back; ``agent``, a user's method's name, module and source digest (``eval.agents``)."""
    effective = effective_config(spec.method, spec.config)
    return plain({"format": RUN_FORMAT, "method": spec.method, "dataset": spec.dataset,
                  "closed_set": spec.closed_set, "config": asdict(spec.config),
                  "method_config": asdict(effective) if effective is not None else None,
                  "stack": asdict(spec.stack),
                  "preset": spec.preset, "preset_config": asdict(spec.preset_config),
                  "judge": spec.judge, "judge_mode": spec.judge_mode, "assets": spec.assets,
                  "env": spec.env, "hm3d_root": spec.hm3d_root, "noise": spec.noise,
                  "questions": n_questions,
                  **({"question_ids": list(ids)} if ids is not None else {}),
                  **scene_seeds(scenes),
                  "run": json.loads(json.dumps(asdict(spec.run), default=str)),
                  **({"agent": agent_identity(spec.method)} if spec.method not in METHODS else {}),
                  "code_version": code_version(), "created": time.time(), "machine": machine()})


def _prepare(spec: RunSpec, todo: Sequence[EvalQuestion]) -> None:
    """Fail before the first episode on what would fail them all: an unknown method, scenes no
    back-end here can open, a model server that cannot start. The server started here is the
    one every worker then uses."""
    from efficienteqa.eval.methods import run_agent_method

    if resolve(spec.method) is run_agent_method:
        kinds = {q.scene.partition(":")[0] for q in todo}
        if "hm3d" in kinds:
            if spec.env != "habitat" or spec.hm3d_root is None:
                raise EfficientEQAError(
                    f"method {spec.method!r} explores the HM3D scenes of {spec.dataset} in Habitat-Sim",
                    fix="add --scene.env habitat --scene.hm3d-root FOLDER (docs/habitat.md), or "
                        "run --eval.method blind, or use --eval.dataset synthetic")
            from efficienteqa.envs.habitat.env import import_habitat_sim
            from efficienteqa.envs.habitat.scenes import check_root

            import_habitat_sim()
            check_root(spec.hm3d_root)
        unknown = sorted(kinds - {"synthetic", "hm3d", "recorded"})
        if unknown:
            raise EfficientEQAError(f"no environment back-end opens {', '.join(unknown)} scenes",
                                    fix="use --eval.dataset synthetic or hm-eqa")
        from efficienteqa.envs.recorded import parse_spec

        for scene in sorted({q.scene for q in todo if q.scene.startswith("recorded:")}):
            path = parse_spec(scene.partition(":")[2])[0]
            if not path.exists():
                raise EfficientEQAError(f"recording {path} of {spec.dataset} does not exist",
                                        fix="give recordings' paths relative to the questions "
                                            "file, or absolute")
    from efficienteqa.eval.methods import method_config
    from efficienteqa.models.backends import build_chat_model
    from efficienteqa.stack import parse_vlm
    from efficienteqa.vc.logprobs import require_logprobs

    # The servers: started (local) or probed (openai:) once here, not per episode.
    model = build_chat_model(parse_vlm(spec.stack.vlm, images=spec.stack.perception == "rgb",
                                       cache=spec.stack.cache, **spec.stack.server_options()))
    if spec.judge is not None and spec.judge != spec.stack.vlm:
        build_chat_model(parse_vlm(spec.judge, images=False, cache=spec.stack.cache,
                                   flag="--eval.judge"))
    if resolve(spec.method) is run_agent_method:
        config = method_config(spec.method, spec.config)
        if config.answer.confidence == "token" or config.answer.answer == "direct":
            require_logprobs(model)  # white-box ExploreEQA: refused once, not per episode


def run_eval(spec: RunSpec, questions: Sequence[EvalQuestion], out: Path, *, workers: int = 1,
             address: str | None = None, on_episode: Progress | None = None,
             prepare: bool = True) -> RunResult:
    """Run ``spec`` on every question not yet done in ``out``. ``workers`` 1 and no
    ``address``: in this process; otherwise on Ray (``address`` None starts a local Ray)."""
    if len({q.id for q in questions}) != len(questions):
        raise EfficientEQAError("the dataset has repeated episode ids", fix="fix the dataset")
    with run_lock(out):
        earlier = open_run(out, manifest(spec, len(questions), [q.scene for q in questions],
                                         [q.id for q in questions]))
        todo = [q for q in questions if q.id not in earlier.done]
        if prepare and todo:
            _prepare(spec, todo)
        t0 = time.perf_counter()
        failed = 0
        lines = (_sequential(spec, todo, out) if workers <= 1 and address is None
                 else _on_ray(spec, todo, out, workers, address))
        for row in lines:
            append_episode(out / EPISODES_FILE, row)
            failed += row["status"] != "done"
            if on_episode is not None:
                on_episode(row)
    return RunResult(out, len(todo), len(questions) - len(todo), failed, time.perf_counter() - t0)


def _sequential(spec: RunSpec, todo: Sequence[EvalQuestion], out: Path) -> Iterator[dict[str, Any]]:
    for q in todo:
        yield run_episode(spec, q, out)


def _on_ray(spec: RunSpec, todo: Sequence[EvalQuestion], out: Path, workers: int,
            address: str | None) -> Iterator[dict[str, Any]]:
    if address is None and "ray" not in sys.modules:
        os.environ.setdefault(*RAY_LOOPBACK)
    try:
        import ray
    except ImportError:
        raise EfficientEQAError("Ray is not installed",
                                fix="pip install 'efficienteqa[ray]', or run with --workers 1") from None
    started = not ray.is_initialized()
    if started:
        if address is not None:
            note = _cluster_key_note(spec, address)
            if note:
                log.warning(note)
        ray.init(address=address, **ray_init_options(workers, address, _key_names(spec)))
    try:
        task = ray.remote(num_cpus=1, max_retries=3)(run_episode)
        pending: dict[Any, EvalQuestion] = {}
        queue = list(todo)
        while queue or pending:
            while queue and len(pending) < workers:
                q = queue.pop(0)
                pending[task.remote(spec, q, out)] = q
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                q = pending.pop(ref)
                try:
                    yield ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - the worker died past its retries
                    yield plain({**_identity(spec, q), **_failure(exc), "finished": time.time()})
    finally:
        if started:
            ray.shutdown()


def is_secret_name(name: str) -> bool:
    """Whether an environment variable's name says it holds a secret (an API key, a token)."""
    return any(mark in name.upper() for mark in SECRET_MARKS)


def ray_init_options(workers: int, address: str | None,
                     keys: Collection[str] = ()) -> dict[str, Any]:
    """``ray.init``'s options for a Ray this runner starts or joins.

    Workers must import the same code and use the same caches as this process, so its
    ``PYTHONPATH``, ``EFFICIENTEQA_*`` and ``XDG_CACHE_HOME`` go in ``runtime_env``. No secret
    does: Ray writes the runtime_env in plain text to its session logs (world-readable), so any
    variable whose name looks secret is left out, and so are ``keys``, the variables the run's
    models read their keys from (``--backends.api-key-env``, named as the user likes, e.g.
    EFFICIENTEQA_AUTH). A local Ray's workers inherit this process's environment, keys
    included; a cluster's nodes must have them set by their user."""
    env = {k: v for k, v in os.environ.items()  # never a secret: Ray logs them all
           if (k.startswith("EFFICIENTEQA_") or k == "XDG_CACHE_HOME") and not is_secret_name(k)
           and k not in keys}
    env["PYTHONPATH"] = os.pathsep.join(p for p in [os.getcwd(), *sys.path] if p)
    options: dict[str, Any] = {"runtime_env": {"env_vars": env}, "log_to_driver": False,
                               "configure_logging": False}
    if address is None:
        options.update(num_cpus=workers, include_dashboard=False)
    return options


def _key_names(spec: RunSpec) -> set[str]:
    """The environment variables the run's models (its VLM and its judge) read their keys from."""
    from efficienteqa.stack import parse_vlm

    names = set()
    for vlm, options in ((spec.stack.vlm, spec.stack.server_options()), (spec.judge, {})):
        if vlm is None:
            continue
        try:
            backend = parse_vlm(vlm, images=False, **options)
        except EfficientEQAError:
            continue  # not a model spec (e.g. "rule"); a bad one fails in the episode
        if backend.key_env is not None:
            names.add(backend.key_env)
    return names


def _cluster_key_note(spec: RunSpec, address: str) -> str | None:
    """One line for a run on a Ray at ``address`` whose models read an API key: the key is not
    sent to the workers, they read it from their own node's environment."""
    names = _key_names(spec)
    if not names:
        return None
    return (f"Ray at {address}: {', '.join(sorted(names))} is not sent to the workers; "
            "set it in the environment of every node")
