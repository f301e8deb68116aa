"""The agent's mind in the rerun viewer: one episode logged to rerun, step by step.

``RerunLog`` is a step hook (``agent.StepHook``): each call logs one step on the ``step``
timeline (rerun adds its own wall clock, ``log_time``); ``finish`` logs the outcome and closes
the recording. The recording goes to a ``.rrd`` file (open it with ``rerun FILE.rrd``), or,
with the target ``live``, to a viewer spawned on this machine. Entity paths:

- ``world`` (right-handed, z up, metres: the canonical frame): ``world/camera`` the frame's
  pose (``cam_to_world``) and pinhole (OpenCV axes: RDF), with ``world/camera/rgb`` (JPEG) and
  ``world/camera/depth`` (metres, ``meter`` 1); ``world/robot`` the robot's pose (x, y, yaw),
  its heading an arrow; ``world/trajectory`` the poses so far on the floor; from the explore
  module's steps: ``world/frontiers`` (labels: member cells), ``world/prompts`` (labels:
  letter and local value), ``world/target`` and ``world/plan`` (the path to the next pose);
- ``map``: the top-down picture (``mapping.visualize.map_image``) per explore step, and the
  final map at the last step;
- ``relevancy/sim`` (Sim per valid frame), ``relevancy/threshold`` (the threshold that acted:
  ``mu + z_applied * sigma``, the dashed line of report.html), ``relevancy/tested`` (the Sim it
  was compared with: the frame tested, the best so far under ``lookback``),
  ``relevancy/sim_abs`` (a rule with ``absolute``), ``relevancy/retrieved`` (the top-K's Sims,
  at their steps); ``zscore/z`` and ``zscore/z_applied``;
- ``episode/question``, ``episode/steps`` (one line per step), ``episode/answer`` (answer,
  confidence, stop reason, retrieved steps) and ``episode/retrieved/<rank>`` (the top-K frames
  as captured, with their ``frame_step`` and ``sim``).

rerun is imported when a log is made, never with this module: ``efficienteqa --help`` and the
agent do not load it.
"""

from __future__ import annotations

import math
import os
import shutil
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from efficienteqa.agent import AgentConfig
from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.module import ExploreStep
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping import visualize
from efficienteqa.mapping.visualize import map_image
from efficienteqa.observation import Observation
from efficienteqa.records import probe_write
from efficienteqa.stop.rules import StopCheck, rule_parts
from efficienteqa.trace import EpisodeResult, StepRecord
from efficienteqa.vc.parse import clean_answer

LIVE = "live"  # the target that spawns a viewer instead of writing a file
APP_ID = "efficienteqa"
TIMELINE = "step"
INSTALL = "pip install 'efficienteqa[rerun]'"
JPEG_QUALITY = 90
FLUSH_S = 30.0
WATCH_S = 10.0  # a call into rerun that should take a moment, given up after this (a full disk)
FLOOR_Z = 0.02  # floor marks a little above z = 0, so the floor grid does not hide them

WORLD = "world"
CAMERA = "world/camera"
RGB = "world/camera/rgb"
DEPTH = "world/camera/depth"
ROBOT = "world/robot"
TRAJECTORY = "world/trajectory"
FRONTIERS = "world/frontiers"
PROMPTS = "world/prompts"
TARGET = "world/target"
PLAN = "world/plan"
MAP = "map"
SIM = "relevancy/sim"
THRESHOLD = "relevancy/threshold"
TESTED = "relevancy/tested"
SIM_ABS = "relevancy/sim_abs"
RETRIEVED_SIM = "relevancy/retrieved"
Z = "zscore/z"
Z_APPLIED = "zscore/z_applied"
QUESTION = "episode/question"
STEPS = "episode/steps"
ANSWER = "episode/answer"
RETRIEVED = "episode/retrieved"

SIM_BLUE, THRESHOLD_RED, GREY = (0x33, 0x66, 0x99), (0xDD, 0x33, 0x33), (0x99, 0x99, 0x99)


def import_rerun() -> ModuleType:
    """The rerun SDK, or the one-line error that says how to install it."""
    try:
        import rerun
    except ImportError as error:
        missing = isinstance(error, ModuleNotFoundError) and (error.name or "rerun").startswith("rerun")
        said = "is not installed" if missing else f"does not import ({str(error).splitlines()[0]})"
        raise EfficientEQAError(f"the rerun SDK {said}", fix=INSTALL) from None
    return rerun


def viewer_executable() -> str | None:
    """The rerun viewer that the SDK installs beside this Python, or one on PATH."""
    here = Path(sys.executable).parent / "rerun"
    return str(here) if here.is_file() and os.access(here, os.X_OK) else shutil.which("rerun")


def check_target(target: str | Path, *, overwrite: bool = False) -> None:
    """Fail in one line, before any slow work, where ``target`` cannot be logged to: rerun is
    not installed, ``live`` where no viewer can start (no executable, no screen), a file that
    is not ``.rrd``, that exists (unless ``overwrite``; a folder, never) or whose folder cannot
    be written (a file is made and removed there to know)."""
    import_rerun()
    if str(target) == LIVE:
        if viewer_executable() is None:
            raise EfficientEQAError("no rerun viewer to start: the rerun executable is not "
                                    "installed here", fix=f"{INSTALL}, or write a file: "
                                    "--rerun episode.rrd")
        if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                     or os.environ.get("WAYLAND_DISPLAY")):
            raise EfficientEQAError("no rerun viewer can start here: no screen (DISPLAY and "
                                    "WAYLAND_DISPLAY are unset)",
                                    fix="write a file, --rerun episode.rrd, and open it with "
                                        "rerun episode.rrd where there is a screen")
        return
    path = Path(target)
    if path.suffix != ".rrd":
        raise EfficientEQAError(f"--rerun takes a .rrd file or {LIVE}, not {str(target)!r}",
                                fix="e.g. --rerun out/ask/episode.rrd, or --rerun live")
    if path.is_dir():
        raise EfficientEQAError(f"--rerun {path} is a folder, and a rerun recording is a file",
                                fix="choose another --rerun file")
    if (path.exists() or path.is_symlink()) and not overwrite:
        raise EfficientEQAError(f"{path} exists; a rerun recording is not written over",
                                fix="remove it, choose another --rerun file, or give --overwrite "
                                    "to replace it")
    try:
        probe_write(path.parent)
    except OSError as error:
        raise EfficientEQAError(f"cannot write the rerun recording {path}: "
                                f"{error.strerror or error}", fix="choose another --rerun file") from None


class RerunLog:
    """One episode to rerun. Call it as the agent's step hook, then ``finish(result)``;
    ``close()`` ends a recording that no result will finish (an episode that failed). ``top_k``
    lays out the viewer's retrieved frames; ``sim_abs``: the Sim that stops whatever the
    baseline (a rule with ``absolute``), drawn as its own series."""

    def __init__(self, target: str | Path, question: str, *, top_k: int = 5,
                 sim_abs: float | None = None, recording_id: str | None = None,
                 overwrite: bool = False) -> None:
        check_target(target, overwrite=overwrite)
        import rerun as rr

        self.target = target
        self.sim_abs = sim_abs
        self.rec = rr.RecordingStream(APP_ID, recording_id=recording_id)
        blueprint = _blueprint(top_k)
        if str(target) == LIVE:
            rr.spawn(executable_path=viewer_executable(), recording=self.rec,
                     default_blueprint=blueprint, hide_welcome_screen=True)
        # else: saved below, once the log's fields are set
        self.poses: list[Pose2D] = []
        self.sims: dict[int, float] = {}
        self.frames: dict[int, Any] = {}  # step -> the frame as logged (JPEG), for the top-K
        self.step = 0
        self.closed = False
        self.error: str | None = None  # why the recording is incomplete (a full disk)
        if str(target) != LIVE:
            try:
                started = _within(WATCH_S, self.rec.save, target, default_blueprint=blueprint)
            except (OSError, RuntimeError) as error:
                raise EfficientEQAError(f"cannot write the rerun recording {target}: "
                                        f"{str(error).splitlines()[0]}",
                                        fix="choose another --rerun file") from None
            if not started:  # the disk filled as it began: the episode goes on without it
                self._give_up(f"rerun's writer did not start within {WATCH_S:g} s")
                return
        self._static(question)

    @classmethod
    def of(cls, target: str | Path, question: str, config: AgentConfig, *,
           overwrite: bool = False) -> RerunLog:
        """The log of an episode run with ``config``: its K, and its ``sim_abs`` where the stop
        rule has ``absolute`` (as report.html draws it)."""
        stop = config.stop
        top_k = 1 if config.answer.answer_at == "best-step" else config.answer.top_k
        return cls(target, question, top_k=top_k,
                   sim_abs=stop.sim_abs if "absolute" in rule_parts(stop.rule) else None,
                   overwrite=overwrite)

    def _static(self, question: str) -> None:
        import rerun as rr

        log = self.rec.log
        log(WORLD, rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        log(f"{ROBOT}/heading", rr.Arrows3D(vectors=[[0.5, 0.0, 0.0]], origins=[[0.0, 0.0, FLOOR_Z]],
                                            colors=[visualize.ROBOT], radii=0.03), static=True)
        series = [(SIM, "Sim(I_t, Q)", SIM_BLUE), (THRESHOLD, "threshold that acted", THRESHOLD_RED),
                  (TESTED, "Sim of the frame tested", GREY), (SIM_ABS, "Sim that stops", THRESHOLD_RED),
                  (Z, "z of the frame tested", SIM_BLUE), (Z_APPLIED, "z that acted", THRESHOLD_RED)]
        for path, name, colour in series:
            log(path, rr.SeriesLines(names=name, colors=[colour]), static=True)
        log(RETRIEVED_SIM, rr.SeriesPoints(names="retrieved (top-K)", colors=[THRESHOLD_RED],
                                           markers="circle", marker_sizes=6.0), static=True)
        log(QUESTION, rr.TextDocument(question), static=True)

    def _give_up(self, why: str) -> None:
        """The recording cannot be written on (its writer hangs): no more calls into it. The
        stream is left as it is (closing it would wait on its writer forever)."""
        self.error = (f"the rerun recording {self.target} is incomplete: {why} (rerun's own "
                      "message says why); the episode went on without it")
        self.closed = True

    def __call__(self, record: StepRecord, obs: Observation, out: ExploreStep | None) -> None:
        if self.closed and self.error is not None:
            return  # given up: the episode goes on without it
        if self.closed:
            raise RuntimeError("this rerun log is finished: a new episode needs a new log")
        self.step = record.step
        self.rec.set_time(TIMELINE, sequence=record.step)
        self._camera(record.step, obs)
        self._robot(record)
        if record.check is not None:
            self._curve(record.check)
        if out is not None:
            self._explore(out)
        import rerun as rr

        self.rec.log(STEPS, rr.TextLog(_step_line(record), level="INFO"))

    def _camera(self, step: int, obs: Observation) -> None:
        import rerun as rr

        log = self.rec.log
        pose = np.asarray(obs.cam_to_world, dtype=float)
        h, w = obs.depth_m.shape
        log(CAMERA, rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]))
        log(CAMERA, rr.Pinhole(image_from_camera=np.asarray(obs.intrinsics, dtype=float),
                               resolution=[w, h], camera_xyz=rr.ViewCoordinates.RDF))
        frame = rr.Image(np.ascontiguousarray(obs.rgb)).compress(jpeg_quality=JPEG_QUALITY)
        self.frames[step] = frame
        log(RGB, frame)
        log(DEPTH, rr.DepthImage(np.asarray(obs.depth_m, dtype=np.float32), meter=1.0))

    def _robot(self, record: StepRecord) -> None:
        import rerun as rr

        log = self.rec.log
        x, y, yaw = record.pose
        self.poses.append(Pose2D(x, y, yaw))
        log(ROBOT, rr.Transform3D(translation=[x, y, 0.0],
                                  rotation_axis_angle=rr.RotationAxisAngle(axis=[0, 0, 1], radians=yaw)))
        strip = [[p.x, p.y, FLOOR_Z] for p in self.poses]
        log(TRAJECTORY, rr.LineStrips3D([strip], colors=[visualize.TRAJECTORY], radii=0.03))

    def _curve(self, check: StopCheck) -> None:
        import rerun as rr

        log = self.rec.log
        self.sims[check.step] = check.sim
        log(SIM, rr.Scalars(check.sim))
        tested = self.sims.get(check.tested_step or check.step)
        if check.threshold is not None and tested is not None:  # a frame that could stop
            log(THRESHOLD, rr.Scalars(check.threshold))
            log(TESTED, rr.Scalars(tested))
        if check.z is not None:
            log(Z, rr.Scalars(check.z))
        if check.z_applied is not None:
            log(Z_APPLIED, rr.Scalars(check.z_applied))
        if self.sim_abs is not None:
            log(SIM_ABS, rr.Scalars(self.sim_abs))

    def _explore(self, out: ExploreStep) -> None:
        import rerun as rr

        log = self.rec.log
        d = out.decision
        log(MAP, rr.Image(map_image(out.state, out.values, frontiers=d.frontiers,
                                    trajectory=self.poses, target_xy=d.target_xy,
                                    prompts=out.prompts)))
        if d.frontiers:
            log(FRONTIERS, rr.Points3D([[*f.xy, FLOOR_Z] for f in d.frontiers],
                                       radii=[0.05 + 0.03 * math.sqrt(f.size) for f in d.frontiers],
                                       colors=[visualize.FRONTIER], labels=[str(f.size) for f in d.frontiers],
                                       show_labels=False))
        else:
            log(FRONTIERS, rr.Clear(recursive=False))
        if out.prompts:
            log(PROMPTS, rr.Points3D(
                [[*p.xy, FLOOR_Z] for p in out.prompts], radii=0.15, colors=[visualize.PROMPT],
                labels=[p.letter + (f" {out.lsv[p.letter]:.2f}" if p.letter in out.lsv else "")
                        for p in out.prompts]))
        else:
            log(PROMPTS, rr.Clear(recursive=False))
        if d.target_xy is not None:
            log(TARGET, rr.Points3D([[*d.target_xy, FLOOR_Z]], radii=0.2, colors=[visualize.TARGET],
                                    labels=["target"]))
        else:
            log(TARGET, rr.Clear(recursive=False))
        path = np.asarray(d.path, dtype=float).reshape(-1, 2)
        if len(path) > 1:
            log(PLAN, rr.LineStrips3D([[[x, y, FLOOR_Z] for x, y in path]], colors=[visualize.FRONTIER],
                                      radii=0.02))
        else:
            log(PLAN, rr.Clear(recursive=False))

    def finish(self, result: EpisodeResult) -> None:
        """At the last step: the final map, the top-K frames and the answer; then close."""
        if self.closed and self.error is not None:
            return
        import rerun as rr

        log = self.rec.log
        last = max(result.steps, self.step)
        for step, sim in result.retrieved:  # ringed on the curve at their own steps
            self.rec.set_time(TIMELINE, sequence=step)
            log(RETRIEVED_SIM, rr.Scalars(sim))
        self.rec.set_time(TIMELINE, sequence=last)
        d = result.last_decision
        log(MAP, rr.Image(map_image(result.state, result.values,
                                    frontiers=d.frontiers if d is not None else (),
                                    trajectory=result.trajectory,
                                    target_xy=d.target_xy if d is not None else None)))
        for rank, (step, sim) in enumerate(result.retrieved, 1):
            frame = self.frames.get(step)
            if frame is not None:
                log(f"{RETRIEVED}/{rank}", frame, rr.AnyValues(frame_step=step, sim=sim))
        log(ANSWER, rr.TextDocument(answer_markdown(result), media_type=rr.MediaType.MARKDOWN))
        self.close()

    def close(self) -> None:
        """Flush and close the recording (the file is then complete); idempotent. Where its
        writer failed (a full disk: rerun's writer thread ends, and says why on stderr), the
        recording is closed as it stands and ``error`` says so: it costs the recording, not
        the episode."""
        if self.closed:
            return
        self.closed = True
        try:
            if not _within(FLUSH_S + WATCH_S, self.rec.flush, timeout_sec=FLUSH_S):
                self._give_up(f"its flush did not end within {FLUSH_S + WATCH_S:g} s")
                return
        except RuntimeError as error:  # "File-writer thread shut down prematurely"
            self._give_up(str(error).splitlines()[0] if str(error) else type(error).__name__)
        if not _within(WATCH_S, self.rec.disconnect) and self.error is None:
            self._give_up(f"it did not close within {WATCH_S:g} s")


def _within(seconds: float, call: Callable[..., object], *args: Any, **kwargs: Any) -> bool:
    """``call(*args, **kwargs)`` in a thread of its own: True when it returned within
    ``seconds`` (its exception raised here), False when it had not (it is left running). Once a
    full disk ended rerun's file writer, its flush can wait for that writer forever: in
    ``save`` as the recording begins, and in ``disconnect`` after a flush that timed out."""
    done = threading.Event()
    raised: list[BaseException] = []

    def run() -> None:
        try:
            call(*args, **kwargs)
        except BaseException as error:  # noqa: BLE001 - raised again in the caller's thread
            raised.append(error)
        finally:
            done.set()

    threading.Thread(target=run, name="rerun-call", daemon=True).start()
    if not done.wait(seconds):
        return False
    if raised:
        raise raised[0]
    return True


def answer_markdown(result: EpisodeResult) -> str:
    """The outcome as a markdown document: question, answer with its confidence, why and
    where exploration stopped, and the retrieved frames by step."""
    answer = clean_answer(result.answer) if result.answer else "(none)"
    last = result.records[-1] if result.records else None
    stop = f"{result.stop_reason} at step {result.steps} of {result.budget}"
    if (result.stop_reason == "relevancy" and last is not None and last.check is not None
            and last.check.tested_step not in (None, last.step)):
        stop += f" (the frame of step {last.check.tested_step})"
    lines = [f"**Question:** {result.question}", "",
             f"**Answer:** {answer} (confidence {result.confidence:.2f})", "",
             f"**Stop:** {stop}", "", "| rank | step | Sim |", "|---|---|---|"]
    lines += [f"| {rank} | {step} | {sim:.3f} |" for rank, (step, sim) in enumerate(result.retrieved, 1)]
    return "\n".join(lines)


def _step_line(record: StepRecord) -> str:
    """One line of what happened at a step, as the step log shows it."""
    parts = [f"step {record.step}"]
    c = record.check
    if not record.valid:
        parts.append("frame not used (too little depth)")
    elif c is None:
        parts.append("no Sim (the relevancy reply was unreadable)")
    else:
        parts.append(f"Sim {c.sim:.3f}")
        if c.z is not None:
            parts.append(f"z {c.z:+.2f}" + (f" vs {c.z_applied:g}" if c.z_applied is not None else ""))
        if c.tested_step not in (None, record.step):
            parts.append(f"(tested: step {c.tested_step})")
        if c.stop:
            parts.append("STOP")
    if record.gate is not None:
        parts.append(f"gate {'passed' if record.gate.get('ok') else 'refused'}: {record.gate.get('why', '')}")
    if record.decision:
        parts.append(f"-> {record.decision} ({record.n_frontiers} frontiers)")
    return "  ".join(parts)


def _blueprint(top_k: int) -> Any:
    """The viewer's layout: the world in 3D with the camera below it, the map, the relevancy
    and z curves and the text, and the top-K frames in a column."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(origin=WORLD, name="world"),
                rrb.Horizontal(rrb.Spatial2DView(origin=CAMERA, contents=f"{RGB}/**", name="camera"),
                               rrb.Spatial2DView(origin=CAMERA, contents=f"{DEPTH}/**", name="depth")),
                row_shares=[2, 1]),
            rrb.Vertical(
                rrb.Spatial2DView(origin=MAP, name="map"),
                rrb.TimeSeriesView(origin="relevancy", name="relevancy"),
                rrb.TimeSeriesView(origin="zscore", name="z"),
                rrb.Tabs(rrb.TextDocumentView(origin=ANSWER, name="answer"),
                         rrb.TextLogView(origin=STEPS, name="steps"),
                         rrb.TextDocumentView(origin=QUESTION, name="question")),
                row_shares=[3, 2, 1, 2]),
            rrb.Vertical(*(rrb.Spatial2DView(origin=f"{RETRIEVED}/{rank}", name=f"top {rank}")
                           for rank in range(1, max(top_k, 1) + 1))),
            column_shares=[3, 2, 1]))

