"""Keeps a small JPEG of every frame during an episode, for the report (the agent keeps none)."""

from __future__ import annotations

import io
from collections.abc import Callable

import numpy as np
from PIL import Image

from efficienteqa.agent import StepRecord
from efficienteqa.envs.base import Observation
from efficienteqa.explore.module import ExploreStep
from efficienteqa.explore.prompting import draw_prompts

THUMB_WIDTH_PX = 320


def jpeg(rgb: np.ndarray, width_px: int | None = None, quality: int = 80) -> bytes:
    image = Image.fromarray(np.ascontiguousarray(rgb, dtype=np.uint8))
    if width_px is not None and image.width > width_px:
        image = image.resize((width_px, round(image.height * width_px / image.width)),
                             Image.Resampling.BILINEAR)
    buf = io.BytesIO()
    image.save(buf, format="JPEG", quality=quality)
    return buf.getvalue()


class FrameCollector:
    """A step hook: per step the frame (with its lettered prompts drawn, as a VLM would see it)
    as a JPEG ``width_px`` wide, and the frame's description when perception is text."""

    def __init__(self, width_px: int = THUMB_WIDTH_PX,
                 describe: Callable[[Observation], str] | None = None) -> None:
        self.width_px = width_px
        self.describe = describe
        self.frames: dict[int, bytes] = {}
        self.descriptions: dict[int, str] = {}

    def __call__(self, record: StepRecord, obs: Observation, out: ExploreStep | None) -> None:
        rgb = draw_prompts(obs.rgb, out.prompts) if out is not None and out.prompts else obs.rgb
        self.frames[record.step] = jpeg(rgb, self.width_px)
        if self.describe is not None and record.valid:
            self.descriptions[record.step] = self.describe(obs)
