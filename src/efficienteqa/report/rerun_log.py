"""The agent's mind in the rerun viewer: one episode logged to rerun, step by step.

``RerunLog`` is a step hook (``agent.StepHook``): each call logs one step on the ``step``
timeline (rerun adds its own wall clock, ``log_time``); ``finish`` logs the outcome and closes
the recording. The recording goes to a ``.rrd`` file (open it with ``rerun FILE.rrd``), or,
with the target ``live``, to a viewer spawned on this machine (``rerun_target`` checks it
first). The entity paths and the viewer's layout are ``rerun_layout``'s; the text of the
answer and of each step is ``rerun_text``'s.

rerun is imported when a log is made, never with this module: ``efficienteqa --help`` and the
agent do not load it.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.agent import AgentConfig
from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.module import ExploreStep
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping import visualize
from efficienteqa.mapping.visualize import map_image
from efficienteqa.observation import Observation
from efficienteqa.report.rerun_layout import (
    ANSWER,
    CAMERA,
    DEPTH,
    FRONTIERS,
    GREY,
    MAP,
    PLAN,
    PROMPTS,
    QUESTION,
    RETRIEVED,
    RETRIEVED_SIM,
    RGB,
    ROBOT,
    SIM,
    SIM_ABS,
    SIM_BLUE,
    STEPS,
    TARGET,
    TESTED,
    THRESHOLD,
    THRESHOLD_RED,
    TRAJECTORY,
    WORLD,
    Z_APPLIED,
    Z,
    blueprint,
)
from efficienteqa.report.rerun_target import LIVE, check_target, viewer_executable
from efficienteqa.report.rerun_text import answer_markdown, step_line
from efficienteqa.stop.rules import StopCheck, rule_parts
from efficienteqa.trace import EpisodeResult, StepRecord

APP_ID = "efficienteqa"
TIMELINE = "step"
JPEG_QUALITY = 90
FLUSH_S = 30.0
WATCH_S = 10.0  # a call into rerun that should take a moment, given up after this (a full disk)
FLOOR_Z = 0.02  # floor marks a little above z = 0, so the floor grid does not hide them


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
        layout = blueprint(top_k)
        if str(target) == LIVE:
            rr.spawn(executable_path=viewer_executable(), recording=self.rec,
                     default_blueprint=layout, hide_welcome_screen=True)
        # else: saved below, once the log's fields are set
        self.poses: list[Pose2D] = []
        self.sims: dict[int, float] = {}
        self.frames: dict[int, Any] = {}  # step -> the frame as logged (JPEG), for the top-K
        self.step = 0
        self.closed = False
        self.error: str | None = None  # why the recording is incomplete (a full disk)
        if str(target) != LIVE:
            try:
                started = _within(WATCH_S, self.rec.save, target, default_blueprint=layout)
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

        self.rec.log(STEPS, rr.TextLog(step_line(record), level="INFO"))

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

