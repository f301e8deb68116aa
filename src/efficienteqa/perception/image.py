"""Pixels for a vision-language model: the RGB frame, and the frame with lettered circles."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from efficienteqa.perception.base import ExploreRequest, Modality

CIRCLE_RADIUS_PX = 18
CIRCLE_FILL = (220, 220, 220)  # light grey

if TYPE_CHECKING:
    from efficienteqa.observation import Observation, PromptPoint


class ImagePerception:
    """The paper's setting: the VLM reads the frames themselves. The exploration call gets the
    frame with the candidate points drawn as lettered circles (DESIGN 3.3), kept apart in pixels;
    "worth exploring" is asked in a call of its own on the unmarked frame
    (``explore/vlm_scorer.py``)."""

    name = "rgb"
    modality: Modality = "image"

    def reset(self) -> None:
        """A new episode: nothing is kept between frames, so nothing to do."""

    def frame(self, obs: Observation) -> np.ndarray:
        return obs.rgb

    def relevancy_text(self, obs: Observation) -> str:
        raise ValueError("RGB perception gives no text: use an image relevancy scorer")

    def explore_request(self, obs: Observation, prompts: Sequence[PromptPoint]) -> ExploreRequest:
        return ExploreRequest("", [p.letter for p in prompts], (draw_prompts(obs.rgb, prompts),))


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    try:
        return ImageFont.load_default(size=size)  # Pillow >= 10.1
    except TypeError:
        return ImageFont.load_default()


def draw_prompts(rgb: np.ndarray, points: Sequence[PromptPoint],
                 radius_px: int = CIRCLE_RADIUS_PX) -> np.ndarray:
    """A copy of ``rgb`` (H, W, 3) uint8 with each point as a light grey disk, black outline and
    its letter centred in black."""
    image = Image.fromarray(np.ascontiguousarray(rgb, dtype=np.uint8))
    draw = ImageDraw.Draw(image)
    font = _font(int(radius_px * 1.3))
    for p in points:
        cu, cv = p.pixel[0] - 0.5, p.pixel[1] - 0.5  # Pillow puts pixel centres on integers
        draw.ellipse((cu - radius_px, cv - radius_px, cu + radius_px, cv + radius_px),
                     fill=CIRCLE_FILL, outline=(0, 0, 0), width=2)
        x0, y0, x1, y1 = draw.textbbox((0, 0), p.letter, font=font)
        draw.text((cu - (x0 + x1) / 2, cv - (y0 + y1) / 2), p.letter, fill=(0, 0, 0), font=font)
    return np.asarray(image).copy()
