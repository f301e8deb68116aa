"""What the models see of an observation: the perception contract.

A perception back-end turns an observation into the input of the models: a text description for
text-only language models (semantic-sensor perception, the offline default) or the RGB frame for
a vision-language model. The answerer gets ``frame(obs)``; a text relevancy scorer gets
``relevancy_text(obs)`` (an image scorer gets the RGB frame); the exploration call gets
``explore_request(obs, prompts)``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
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

    # A perception that keeps what it saw across the frames of an episode (the pixel
    # perception's room votes) has ``reset()``, which the agent calls as each episode starts.


@dataclass(frozen=True)
class Sighting:
    """An object of the question's target in a frame: its category, where it is (world x, y in
    metres: the median of its back-projected pixels), its top (z, metres above the floor), its
    pixel count, whether the frame cuts it (touches the left, right or top edge) and the room
    the frame shows it in (None when the frame does not say)."""

    category: str
    xy: tuple[float, float]
    top_m: float
    pixels: int
    cut: bool
    room: str | None
    # its world points (N, 3), where the perception keeps them (the model's boxes, for the
    # instance map)
    points: np.ndarray | None = field(default=None, repr=False, compare=False)


@dataclass(frozen=True)
class Sightings:
    """What a frame shows of the places and things a question points at, for the explorer:
    ``floor`` maps each room whose floor is in view to (N, 2) world points of that floor;
    ``things`` are the target's objects in view; ``doors`` the doors and doorways in view, each
    a ``Sighting`` of category "door" whose ``room`` is the room seen through it where the
    perception says so (a VLM's doorways), else None (the floor beyond names it). A perception
    that cannot tell by itself (images read by a VLM) gets them from the model
    (``perception.sightings.ModelSightings``); with none, the explorer steers by semantic values
    alone."""

    floor: Mapping[str, np.ndarray]
    things: tuple[Sighting, ...] = ()
    doors: tuple[Sighting, ...] = ()
