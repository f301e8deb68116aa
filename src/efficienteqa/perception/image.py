"""Pixels for a vision-language model: the RGB frame, and the frame with lettered circles."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from efficienteqa.explore.prompting import draw_prompts
from efficienteqa.perception.base import ExploreRequest, Modality

if TYPE_CHECKING:
    from efficienteqa.envs.base import Observation
    from efficienteqa.explore.prompting import PromptPoint


class ImagePerception:
    """The paper's setting: the VLM reads the frames themselves. The exploration call gets the
    frame with the candidate points drawn as lettered circles (SPEC 3.3); the VLM answers the
    "worth exploring" part from the same image."""

    name = "rgb"
    modality: Modality = "image"

    def frame(self, obs: Observation) -> np.ndarray:
        return obs.rgb

    def relevancy_text(self, obs: Observation) -> str:
        raise ValueError("RGB perception gives no text: use an image relevancy scorer")

    def explore_request(self, obs: Observation, prompts: Sequence[PromptPoint]) -> ExploreRequest:
        return ExploreRequest("", [p.letter for p in prompts], (draw_prompts(obs.rgb, prompts),))
