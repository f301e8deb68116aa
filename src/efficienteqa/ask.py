"""The "ask" job: one question in one scene -> answer, ``episode.json`` and ``report.html``."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from efficienteqa.agent import AgentConfig
from efficienteqa.config.run import RunConfig, SceneConfig
from efficienteqa.envs.base import is_recording, scene_labels
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS
from efficienteqa.envs.synthetic.questions import Question
from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.module import ExploreStep
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.visualize import map_image
from efficienteqa.models.base import ChatModel
from efficienteqa.models.images import encode_image
from efficienteqa.observation import Observation
from efficienteqa.records import write_json
from efficienteqa.relevancy.base import RelevancyScorer
from efficienteqa.report.episode import episode_record, failed_record
from efficienteqa.report.evidence import EvidenceWatch
from efficienteqa.report.frames import FrameCollector
from efficienteqa.report.html import write_report
from efficienteqa.report.rerun_log import RerunLog
from efficienteqa.scenes import Scene, open_scene
from efficienteqa.stack import Stack, build_agent
from efficienteqa.trace import EpisodeResult, StepHook, StepRecord


@dataclass
class AskResult:
    result: EpisodeResult
    record: dict
    episode_json: Path
    report_html: Path | None
    warnings: list[str] = field(default_factory=list)  # what failed beside the episode


def known_question(questions: list[Question], text: str) -> Question | None:
    """The scene's ground-truth question with this text (case and spacing ignored)."""
    key = " ".join(text.lower().split())
    return next((q for q in questions if " ".join(q.question.lower().split()) == key), None)


def map_url(result: EpisodeResult) -> str:
    """The final top-down map as a PNG ``data:`` URL, at full size."""
    d = result.last_decision
    rgb = map_image(result.state, result.values, frontiers=d.frontiers if d else (),
                    trajectory=result.trajectory, target_xy=d.target_xy if d else None)
    return encode_image(rgb, max_side=max(rgb.shape[:2]), fmt="png")


def ask(question: str, scene: str | Scene, out: Path, *, run: RunConfig | None = None,
        stack: Stack | None = None, config: AgentConfig | None = None,
        start: Pose2D | None = None,
        on_step: StepHook | None = None, model: ChatModel | None = None,
        relevancy: RelevancyScorer | None = None, assets: str = DEFAULT_ASSETS,
        report: bool = True, known_as: str | None = None,
        rerun: str | Path | RerunLog | None = None, record: Path | None = None,
        record_depth: str = "32FC1", record_format: str | None = None,
        replace_rerun: bool = False) -> AskResult:
    """Run one episode and write ``out/episode.json`` and (``report``) ``out/report.html``.
    ``scene``: a name such as "synthetic:3" (opened and closed here) or an opened ``Scene``
    (left open for the caller). ``run``: the whole configuration (``presets.run_config``, as
    ``efficienteqa config`` prints it): its back-ends, its agent and the scene settings a named
    scene opens with; or, without it, ``stack`` and ``config`` (defaults where left out) and
    ``assets``. ``model`` and ``relevancy`` replace the stack's back-ends (tests
    inject stubs). ``known_as``: the wording of the scene's own question that ``question``
    re-phrases (the paraphrase split), whose evidence and reference the record then carries.
    ``rerun``: also log the episode to rerun (``report.rerun_log``): a ``.rrd`` file, ``live``
    (a viewer spawned here), or a ``RerunLog`` made beforehand; finished and closed here, also
    when the episode fails (the recording then holds the steps done). An existing file is
    refused unless ``replace_rerun``.
    ``record``: write the episode's frames there as a recorded walk (``envs.recorded.write``),
    in ``record_format``: "mcap" (a file), "rosbag2" (a bag folder: metadata.yaml and the .mcap)
    or "frames" (a folder with poses.jsonl); by default mcap for a path ending in .mcap, else
    frames; depth as ``record_depth``, 32FC1 or 16UC1; with the scene's labels where it has
    them, for ``recorded:PATH`` to replay.
    A recording (``record``, ``rerun``) that cannot be written to the end (a full disk) costs
    only itself: the episode goes on, and the result's ``warnings`` say what was lost.
    Interrupted (Ctrl-C), or failed part-way, the episode's steps and model calls so far are
    written to ``out/episode.json`` (status "interrupted" or "failed") before the exception
    goes on."""
    from efficienteqa.envs.recorded.write import check_record_path

    if record is not None:
        check_record_path(record, record_depth, record_format)  # before the scene is built
    if run is not None and (stack is not None or config is not None or assets != DEFAULT_ASSETS):
        raise ValueError("give ask() the whole run (run=) or its parts (stack=, config=, "
                         "assets=), not both")
    scene_config = run.scene if run is not None else SceneConfig(assets=assets)
    stack = run.backends if run is not None else stack or Stack()
    config = run.agent if run is not None else config or AgentConfig()
    shown = (RerunLog.of(rerun, question, config, overwrite=replace_rerun)
             if rerun is not None and not isinstance(rerun, RerunLog) else rerun)
    warnings: list[str] = []
    try:
        return _ask(question, scene, out, stack, config, start, on_step, model, relevancy,
                    scene_config, report, known_as, shown, record, record_depth, record_format,
                    warnings)
    finally:
        if shown is not None:
            shown.close()  # a no-op after finish
            if shown.error is not None and shown.error not in warnings:
                warnings.append(shown.error)


def _ask(question: str, scene: str | Scene, out: Path, stack: Stack, config: AgentConfig,
         start: Pose2D | None, on_step: StepHook | None, model: ChatModel | None,
         relevancy: RelevancyScorer | None, where: SceneConfig, report: bool,
         known_as: str | None,
         shown: RerunLog | None, record: Path | None, record_depth: str,
         record_format: str | None, warnings: list[str]) -> AskResult:
    from efficienteqa.envs.recorded.write import WalkRecorder

    opened = (open_scene(scene, where.assets, env=where.env, hm3d_root=where.hm3d_root,
                         noise=where.noise) if isinstance(scene, str) else scene)
    recorder: WalkRecorder | None = None
    try:
        if start is not None and is_recording(opened.env):
            raise EfficientEQAError("a recorded walk starts where it was recorded",
                                    fix="leave out --start")
        navigable = getattr(opened.env, "is_navigable", None)  # a simulated scene's truth
        if start is not None and navigable is not None and not navigable(start.x, start.y):
            raise EfficientEQAError(f"the start ({start.x:g}, {start.y:g}) is not on the floor "
                                    f"of {opened.name}",
                                    fix="pick a point on the floor (see the house's map: "
                                        "efficienteqa scenes generate), or leave out --start")
        built = build_agent(opened.env, stack, config, opened.backend, model=model,
                            relevancy=relevancy)
        perception = built.agent.perception
        describe = (lambda obs: str(perception.frame(obs))) if perception.modality == "text" else None
        frames = FrameCollector(describe=describe)
        truth = known_question(opened.questions, known_as or question)
        # Ground truth for the record only: the hook notes frames, the agent never sees them.
        watch = EvidenceWatch(truth.evidence if truth is not None else None)

        steps: list[StepRecord] = []
        if record is not None:
            recorder = WalkRecorder(record, labels=scene_labels(opened.env),
                                    depth_encoding=record_depth, layout=record_format)

        def hook(step: StepRecord, obs: Observation, out_step: ExploreStep | None) -> None:
            if recorder is not None:
                recorder.add(obs)
            steps.append(step)
            watch(step, obs, out_step)
            if report:
                frames(step, obs, out_step)
            if shown is not None:
                shown(step, obs, out_step)
            if on_step is not None:
                on_step(step, obs, out_step)

        try:
            result = built.agent.run(opened.env, question, start=start, on_step=hook,
                                     budget=config.budget(opened.env))
        except (Exception, KeyboardInterrupt) as error:  # keep what was explored and paid for
            partial = failed_record(question, error, records=steps, config=config,
                                    backends=built.backends, scene=opened.name,
                                    exchanges=built.model.exchanges)
            write_json(out / "episode.json", partial)
            error.partial_episode = partial  # type: ignore[union-attr]  # for eval's row
            raise
        reference: dict[str, Any] | None = None
        if truth is not None:
            reference = {"id": truth.id, "answer": truth.answer,
                         "alternatives": truth.alternatives, "category": truth.category}
            if start is None:  # oracle step counts are from the scene's own start pose
                reference["oracle_steps"] = truth.oracle_steps
        last = result.records[-1] if result.records else None
        stop_step = (last.check.tested_step or last.step
                     if result.stop_reason == "relevancy" and last is not None
                     and last.check is not None else None)
        episode = episode_record(result, config=config, backends=built.backends,
                                 scene=opened.name, exchanges=built.model.exchanges,
                                 reference=reference,
                                 evidence=watch.fields(result.retrieved, stop_step))
        episode_json = write_json(out / "episode.json", episode)
        if opened.credits:  # CC-BY furniture in the frames: credit it beside them
            (out / "ATTRIBUTION.md").write_text(
                f"Furniture of {opened.name} (CC-BY 3.0):\n{opened.credits}\n", encoding="utf-8")
        if shown is not None:
            shown.finish(result)
        html = (write_report(out / "report.html", episode, map_url(result), frames.frames,
                             frames.descriptions) if report else None)
        return AskResult(result, episode, episode_json, html, warnings)
    finally:
        if recorder is not None:
            recorder.close()
            if recorder.error is not None:
                warnings.append(recorder.error)
        if isinstance(scene, str):
            opened.env.close()
