"""Keeps a small JPEG of every frame during an episode, for the report (the agent keeps none)."""

from __future__ import annotations

from collections.abc import Callable

from efficienteqa.agent import StepRecord
from efficienteqa.explore.module import ExploreStep
from efficienteqa.models.client import encode_image
from efficienteqa.observation import Observation
from efficienteqa.perception.image import draw_prompts

THUMB_WIDTH_PX = 320


class FrameCollector:
    """A step hook: per step the frame (with its lettered prompts drawn, as a VLM would see it)
    as a JPEG ``data:`` URL ``width_px`` wide, and the frame's description when perception is
    text."""

    def __init__(self, width_px: int = THUMB_WIDTH_PX,
                 describe: Callable[[Observation], str] | None = None) -> None:
        self.width_px = width_px
        self.describe = describe
        self.frames: dict[int, str] = {}
        self.descriptions: dict[int, str] = {}

    def __call__(self, record: StepRecord, obs: Observation, out: ExploreStep | None) -> None:
        rgb = draw_prompts(obs.rgb, out.prompts) if out is not None and out.prompts else obs.rgb
        self.frames[record.step] = encode_image(rgb, max_side=self.width_px, fmt="jpeg")
        if self.describe is not None and record.valid:
            self.descriptions[record.step] = self.describe(obs)
