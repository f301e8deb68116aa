"""``RecordedWalk``: the ``envs.base.Recording`` over the frames of a source (MCAP or folder).

A source reads its frames in order, lazily (a walk of thousands of frames is never held in
memory): ``frames()`` starts a fresh pass. The walk gives the first frame on ``reset`` and the
next on each ``step`` (its goal is ignored: the robot went where it went); past the last frame,
``step`` gives the last frame again with ``terminated`` True.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from efficienteqa.envs.recorded.labels import RecordedLabels
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.observation import Observation


def floor_pose(cam_to_world: np.ndarray) -> Pose2D:
    """The camera's floor projection: (x, y) of its centre, the yaw of its optical axis (+z)
    projected on the floor (of its image's up direction when it looks straight down)."""
    forward = cam_to_world[:3, 2]
    if math.hypot(forward[0], forward[1]) < 1e-6:
        forward = -cam_to_world[:3, 1]
    return Pose2D(float(cam_to_world[0, 3]), float(cam_to_world[1, 3]),
                  math.atan2(float(forward[1]), float(forward[0])))


def intrinsics_matrix(fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """3x3 K in this project's convention from OpenCV's (ROS CameraInfo's): OpenCV puts the
    centre of the top-left pixel at (0, 0), ``geometry.backproject`` at (0.5, 0.5)."""
    return np.array([[fx, 0.0, cx + 0.5], [0.0, fy, cy + 0.5], [0.0, 0.0, 1.0]])


def opencv_intrinsics(k: np.ndarray) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) in OpenCV's convention of this project's 3x3 K."""
    return float(k[0, 0]), float(k[1, 1]), float(k[0, 2]) - 0.5, float(k[1, 2]) - 0.5


@dataclass(frozen=True)
class RecordedCamera(CameraSpec):
    """The recording's camera: its size and intrinsics (``k``: fx, fy, cx, cy in this
    project's convention, see ``intrinsics_matrix``). ``hfov_deg`` is the one of ``fx``;
    ``height_m`` and ``pitch_deg`` are the first frame's."""

    k: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    @classmethod
    def of(cls, width: int, height: int, intrinsics: np.ndarray,
           cam_to_world: np.ndarray) -> RecordedCamera:
        fx, fy = float(intrinsics[0, 0]), float(intrinsics[1, 1])
        forward = cam_to_world[:3, 2]
        pitch = math.degrees(math.asin(max(-1.0, min(1.0, float(forward[2])))))
        return cls(width, height, math.degrees(2 * math.atan(width / 2 / fx)),
                   float(cam_to_world[2, 3]), pitch,
                   k=(fx, fy, float(intrinsics[0, 2]), float(intrinsics[1, 2])))

    @property
    def fx(self) -> float:
        return self.k[0]

    @property
    def fy(self) -> float:
        return self.k[1]

    @property
    def intrinsics(self) -> np.ndarray:
        fx, fy, cx, cy = self.k
        return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])

    def scaled(self, width: int, height: int) -> RecordedCamera:
        sx, sy = width / self.width, height / self.height
        fx, fy, cx, cy = self.k
        return RecordedCamera(width, height, self.hfov_deg, self.height_m, self.pitch_deg,
                              k=(fx * sx, fy * sy, cx * sx, cy * sy))


class FrameSource(Protocol):
    """Where a walk's frames come from: ``length`` usable frames, read in order by each pass of
    ``frames()``; ``labels``, the simulator's labels where the recording carries them; ``note``,
    one line on what was read and what was dropped; ``layout``: "mcap" (one file), "rosbag2"
    (a bag folder) or "folder" (``poses.jsonl``)."""

    name: str
    layout: str
    camera: RecordedCamera
    length: int
    labels: RecordedLabels | None
    note: str

    def frames(self) -> Iterator[Observation]: ...

    def close(self) -> None: ...


class RecordedWalk:
    """A recorded walk as an environment (``envs.base.Recording``)."""

    recorded = True

    def __init__(self, source: FrameSource) -> None:
        self.source = source
        self.camera: CameraSpec = source.camera
        self.note = source.note
        self._frames: Iterator[Observation] | None = None
        self._obs: Observation | None = None
        self._at = -1

    @property
    def length(self) -> int:
        return self.source.length

    def scene_labels(self) -> RecordedLabels:
        """The simulator's labels the recording carries (for the semantic-sensor perception)."""
        if self.source.labels is None:
            raise EfficientEQAError(
                f"recording {self.source.name} carries no object labels (the "
                "/efficienteqa/labels topic or labels.json of a simulated walk), which "
                "semantic-sensor perception reads",
                fix="use --backends.perception pixels (the project's network over RGB-D) or "
                    "rgb (an image VLM)")
        return self.source.labels

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Observation, dict[str, Any]]:
        """The first frame; ``seed`` is accepted for the contract. A start pose cannot be
        given: the walk starts where it was recorded."""
        if (options or {}).get("start") is not None:
            raise EfficientEQAError("a recorded walk starts where it was recorded",
                                    fix="leave out --start")
        self._stop()
        self._frames = self.source.frames()
        self._obs, self._at = self._next(), 0
        return self._obs, {"frame": 0}

    def step(self, action: Pose2D) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        """The next frame, wherever ``action`` pointed; past the last, the last again with
        ``terminated`` True."""
        if self._frames is None or self._obs is None:
            raise RuntimeError("step before reset")
        info: dict[str, Any] = {"blocked": False, "short": False}
        if self._at + 1 >= self.length:
            return self._obs, 0.0, True, False, {**info, "frame": self._at}
        self._obs = self._next()
        self._at += 1
        return self._obs, 0.0, False, False, {**info, "frame": self._at}

    def observe(self) -> Observation:
        if self._obs is None:
            return self.reset()[0]
        return self._obs

    def close(self) -> None:
        self._stop()
        self.source.close()

    def _next(self) -> Observation:
        assert self._frames is not None
        try:
            return next(self._frames)
        except StopIteration:
            raise EfficientEQAError(f"recording {self.source.name} ended after {self._at + 1} "
                                    f"of its {self.length} frames while it was read",
                                    fix="check that the file was not changed since it was "
                                        "opened") from None

    def _stop(self) -> None:
        close = getattr(self._frames, "close", None)
        if close is not None:
            close()
        self._frames, self._obs, self._at = None, None, -1

    def __enter__(self) -> RecordedWalk:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
