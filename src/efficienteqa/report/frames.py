"""Keeps small JPEGs of every frame during an episode, for the report (the agent keeps none)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from efficienteqa.explore.module import ExploreStep
from efficienteqa.models.images import encode_image
from efficienteqa.models.recording import image_digest
from efficienteqa.observation import Observation
from efficienteqa.perception.image import draw_prompts
from efficienteqa.trace import StepRecord

THUMB_WIDTH_PX = 320
SENT_WIDTH_PX = 160  # the images of a model call, shown beside it


@dataclass(frozen=True)
class SentImage:
    """A frame as a model may have been sent it: ``step``, whether the lettered circles were
    drawn on it (``marked``) and a small JPEG ``data:`` URL."""

    step: int
    marked: bool
    url: str

    @property
    def label(self) -> str:
        return f"step {self.step}, " + ("with the lettered circles" if self.marked else "as captured")


class StepFrames(dict[int, str]):
    """step -> the frame as captured (a JPEG ``data:`` URL): what relevancy scored and what the
    answer model was sent. ``marked``: step -> the frame with its lettered prompts drawn, for
    the steps that had prompts; ``sent``: ``models.recording.image_digest`` of either version
    -> a ``SentImage``, so the report can show each model call's images by the references the
    recording keeps."""

    def __init__(self) -> None:
        super().__init__()
        self.marked: dict[int, str] = {}
        self.sent: dict[str, SentImage] = {}


class FrameCollector:
    """A step hook: per step the frame as captured and, where the step had lettered prompts,
    the frame with them drawn (as a VLM's exploration call sees it), as JPEG ``data:`` URLs
    ``width_px`` wide (``frames``, a ``StepFrames``), and the frame's description when
    perception is text."""

    def __init__(self, width_px: int = THUMB_WIDTH_PX,
                 describe: Callable[[Observation], str] | None = None,
                 sent_width_px: int = SENT_WIDTH_PX) -> None:
        self.width_px, self.sent_width_px = width_px, sent_width_px
        self.describe = describe
        self.frames = StepFrames()
        self.descriptions: dict[int, str] = {}

    def __call__(self, record: StepRecord, obs: Observation, out: ExploreStep | None) -> None:
        step = record.step
        self.frames[step] = self._keep(step, obs.rgb, marked=False)
        if out is not None and out.prompts:
            self.frames.marked[step] = self._keep(step, draw_prompts(obs.rgb, out.prompts),
                                                  marked=True)
        if self.describe is not None and record.valid:
            self.descriptions[step] = self.describe(obs)

    def _keep(self, step: int, rgb: np.ndarray, marked: bool) -> str:
        self.frames.sent[image_digest(rgb)] = SentImage(
            step, marked, encode_image(rgb, max_side=self.sent_width_px, fmt="jpeg"))
        return encode_image(rgb, max_side=self.width_px, fmt="jpeg")
