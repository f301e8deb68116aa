"""What the models see of an observation: the perception contract.

A perception back-end turns an observation into the input of the models: a text description for
text-only language models (semantic-sensor perception, the offline default) or the RGB frame for
a vision-language model. The answerer gets ``frame(obs)``; a text relevancy scorer gets
``relevancy_text(obs)`` (an image scorer gets the RGB frame); the exploration call gets
``explore_request(obs, prompts)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np

if TYPE_CHECKING:
    from efficienteqa.observation import Observation, PromptPoint

Modality = Literal["image", "text"]


@dataclass(frozen=True)
class ExploreRequest:
    """The inputs of one exploration VC call: ``view`` (scene text, or "" with images),
    ``directions`` (letter -> description for text models, letters for VLMs) and ``images``."""

    view: str
    directions: Mapping[str, str] | Sequence[str]
    images: tuple[np.ndarray, ...] = ()


class Perception(Protocol):
    name: str  # recorded with every result, e.g. "semantic-sensor" or "rgb"
    modality: Modality

    def frame(self, obs: Observation) -> str | np.ndarray: ...

    def relevancy_text(self, obs: Observation) -> str:
        """What a text relevancy scorer compares with the question: one line per thing in view."""
        ...

    def explore_request(self, obs: Observation, prompts: Sequence[PromptPoint]) -> ExploreRequest: ...
