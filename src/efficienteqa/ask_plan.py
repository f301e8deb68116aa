"""What an ask is, decided before anything slow, and the ask run in its folder.

``efficienteqa ask`` calls ``plan_ask`` (as ``eval`` calls ``eval.plan.plan_run``) and then
``run_ask``; so can a library caller, with the same refusals in the same words: a method other
than efficienteqa, bad back-ends, a --record-format without --record, an unknown --episode, a
start pose on a recorded walk, no question, a rerun target that cannot be written, a folder
holding another question's episode. Each is one line, before the scene opens.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from efficienteqa.config.run import RunConfig
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D

if TYPE_CHECKING:
    from efficienteqa.ask import AskResult
    from efficienteqa.envs.habitat.scenes import HabitatStart
    from efficienteqa.scenes import Scene
    from efficienteqa.trace import StepHook

ASK_OUT = Path("out/ask")  # ask's folder without --out: a scratch folder each ask replaces
EPISODE_FILE = "episode.json"


@dataclass(frozen=True)
class AskPlan:
    """One ask, checked: the question and scene (an --episode's own where one was named), the
    folder and what may be replaced there, and the recordings asked for."""

    run: RunConfig
    question: str
    scene: str
    out: Path
    overwrite: bool  # the folder's episode of another question may be replaced
    replace_rerun: bool  # an existing rerun file may be replaced
    start: Pose2D | None = None
    habitat_start: HabitatStart | None = None
    reference: str | None = None  # an --episode's reference answer
    known_as: str | None = None  # the wording of the dataset's own question it re-phrases
    rerun: str | None = None
    record: Path | None = None
    record_format: str | None = None


def check_backends(run: RunConfig) -> None:
    """Bad back-ends fail before anything slow: unknown furniture, an unknown back-end name, a
    VLM spec that cannot be read, a local model that is not in the registry."""
    from efficienteqa.envs.synthetic.house import check_assets
    from efficienteqa.stack import check_stack, parse_vlm

    stack = run.backends
    check_assets(run.scene.assets)  # before a house is built
    check_stack(stack)
    backend = parse_vlm(stack.vlm, images=stack.perception == "rgb",
                        temperature=stack.temperature, **stack.server_options())
    if backend.kind == "local":  # a misspelt local model: now, not once the scene is open
        from efficienteqa.models.local.weights import registry_entry

        registry_entry(backend.model)


def parse_start(text: str | None) -> Pose2D | None:
    """A start pose given as X,Y,YAW_DEG (metres and degrees)."""
    if text is None:
        return None
    fix = "give it as X,Y,YAW_DEG in metres and degrees, e.g. 2.5,3,90"
    try:
        x, y, yaw_deg = (float(v) for v in text.split(","))
    except ValueError:
        raise EfficientEQAError(f"cannot read the start pose {text!r}", fix=fix) from None
    if not all(math.isfinite(v) for v in (x, y, yaw_deg)):
        raise EfficientEQAError(f"the start pose {text!r} is not finite", fix=fix)
    return Pose2D(x, y, math.radians(yaw_deg))


def _same_question(a: str, b: str) -> bool:
    return " ".join(a.lower().split()) == " ".join(b.lower().split())


def check_ask_folder(out: Path, question: str, overwrite: bool) -> None:
    """Before any work: ``out`` can take this ask's episode. Its episode.json and report.html
    must be files to write, and an episode of another question there is not replaced unless
    ``overwrite`` (two asks into one --out left only the second, without a word). The same
    question asked again replaces its own episode: that is running it again."""
    import json

    for name in (EPISODE_FILE, "report.html"):
        if (out / name).is_dir():
            raise EfficientEQAError(f"{out / name} is a folder",
                                    fix="remove it, or use another --out folder")
    path = out / EPISODE_FILE
    if overwrite or not path.exists():
        return
    try:
        earlier = json.loads(path.read_text()).get("question")
    except (OSError, ValueError, AttributeError):  # unreadable: whose it is is not known
        earlier = None
    if isinstance(earlier, str) and _same_question(earlier, question):
        return
    asked = (f": {earlier[:60]!r}" + ("..." if len(earlier) > 60 else "")
             if isinstance(earlier, str) else "")
    raise EfficientEQAError(f"{out} holds the episode of another question{asked}",
                            fix="use another --out folder, or --overwrite to replace it")


def plan_ask(run: RunConfig, question: str | None, scene: str = "synthetic:0", *,
             episode: str | None = None, start: str | Pose2D | None = None,
             out: Path | None = None, overwrite: bool = False, rerun: str | None = None,
             record: Path | None = None, record_format: str | None = None) -> AskPlan:
    """The ``AskPlan`` of one ask, after every check that needs no scene. ``episode``: a
    question ID (or row N) of ``run.eval.dataset``, asked in its scene from its start pose.
    ``out`` left out is ``ASK_OUT``, a scratch folder each ask replaces; ``overwrite`` replaces
    another question's episode in ``out`` and an existing ``rerun`` file."""
    from efficienteqa.envs.habitat.scenes import HabitatStart
    from efficienteqa.records import check_writable

    replace_rerun = overwrite  # given: the scratch folder's own replacing is not a rerun file's
    if out is None:  # the scratch folder: each ask without --out replaces its episode
        out, overwrite = ASK_OUT, True
    if run.eval.method != "efficienteqa":
        raise EfficientEQAError(f"ask runs efficienteqa; method {run.eval.method!r} is for eval",
                                fix="use efficienteqa eval --eval.method with this configuration")
    check_backends(run)
    start_pose = parse_start(start) if isinstance(start, str) else start
    habitat_start, reference, known_as = None, None, None
    check_writable(out)  # before the episode, not after it
    if record is not None:
        from efficienteqa.envs.recorded.write import check_record_path

        check_record_path(record, layout=record_format)
    elif record_format is not None:
        raise EfficientEQAError("--record-format says how --record writes, and there is no "
                                "--record", fix="add --record PATH, or leave out --record-format")
    if episode is not None:
        from efficienteqa.datasets import find_question, load_dataset

        q = find_question(load_dataset(run.eval.dataset, path=run.eval.hm_eqa_path,
                                       assets=run.scene.assets), episode)
        question, scene, reference, known_as = q.question, q.scene, q.answer, q.original_question
        habitat_start = HabitatStart.from_source(q.source)
        start_pose = start_pose or (Pose2D(*q.start) if q.start is not None else None)
    if start_pose is not None and scene.startswith("recorded:"):
        raise EfficientEQAError("a recorded walk starts where it was recorded",
                                fix="leave out --start")
    if not question or not question.strip():  # "   " too: before the scene opens, not after
        raise EfficientEQAError("no question", fix='give one, e.g. efficienteqa ask "What colour is '
                                'the sofa?", or --episode ID with --eval.dataset')
    if rerun is not None:  # rerun missing, no viewer, an unwritable file: before the scene opens
        from efficienteqa.report.rerun_target import check_target

        check_target(rerun, overwrite=replace_rerun)
    return AskPlan(run, question, scene, out, overwrite, replace_rerun, start_pose,
                   habitat_start, reference, known_as, rerun, record, record_format)


@contextmanager
def _no_progress(_: Scene, __: int | None) -> Iterator[StepHook | None]:
    yield None


def run_ask(plan: AskPlan, *, opening: Callable[[str], AbstractContextManager[object]] = nullcontext,
            progress: Callable[[Scene, int | None], AbstractContextManager[StepHook | None]]
            = _no_progress
            ) -> AskResult:
    """The planned ask, under its folder's lock (a second ask into the folder fails at once,
    not after exploring): open the scene (within ``opening(scene)``, e.g. a spinner), explore
    (each step to the hook ``progress(opened, budget)`` yields: the scene and its step
    budget, e.g. a progress bar), answer, write, close the scene."""
    from efficienteqa.ask import ask
    from efficienteqa.records import run_lock
    from efficienteqa.scenes import open_scene

    s = plan.run.scene
    with run_lock(plan.out):
        check_ask_folder(plan.out, plan.question, plan.overwrite)
        with opening(plan.scene):
            opened = open_scene(plan.scene, s.assets, env=s.env, hm3d_root=s.hm3d_root,
                                noise=s.noise, start=plan.habitat_start)
        try:
            with progress(opened, plan.run.agent.budget(opened.env)) as on_step:
                return ask(plan.question, opened, plan.out, run=plan.run, start=plan.start,
                           on_step=on_step, known_as=plan.known_as, rerun=plan.rerun,
                           record=plan.record, record_format=plan.record_format,
                           replace_rerun=plan.replace_rerun)
        finally:
            opened.env.close()
