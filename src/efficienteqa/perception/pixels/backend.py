"""Pixel perception (DESIGN 9, learned perception): the frame's RGB-D read by the project's
own network, then described in the same words as the semantic sensor.

It reads the observation's RGB, depth, intrinsics and pose and nothing else: no instance buffer,
no scene labels, no floor plan. The network (``perception.pixels.net``) gives classes per pixel;
``segment.read_frame`` makes instances and per-frame labels of them; the semantic describer turns
those into the view, direction and relevancy texts and the sightings, so the rest of the pipeline
is unchanged.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from efficienteqa.observation import Observation
from efficienteqa.perception.base import Modality
from efficienteqa.perception.pixels.segment import PixelClasses, read_frame
from efficienteqa.perception.semantic import SemanticPerception

if TYPE_CHECKING:
    from efficienteqa.envs.base import SceneLabels

WEIGHTS = Path(__file__).resolve().parent / "weights" / "pixels.pt"
Classifier = Callable[[np.ndarray, np.ndarray], PixelClasses]  # (rgb, depth_m) -> classes


class PixelPerception(SemanticPerception):
    """``Perception`` from pixels: the semantic describer over the instances of a classifier
    of pixels (the committed network by default, see ``load``)."""

    name = "pixels"
    modality: Modality = "text"

    def __init__(self, classify: Classifier, record: dict[str, Any] | None = None) -> None:
        super().__init__(labels=None)  # type: ignore[arg-type]  # read() is all that uses them
        self.classify = classify
        self.record = record or {}  # the weights' record (how they were made), when loaded
        self._read: tuple[Observation, Observation, SceneLabels] | None = None

    @classmethod
    def load(cls, weights: Path | None = None) -> PixelPerception:
        """The committed network (or the one at ``weights``); one-line error when missing."""
        from efficienteqa.perception.pixels.net import load_weights, predict

        net, vocabulary, meta = load_weights(weights or WEIGHTS)
        thresholds = {str(k): float(v) for k, v in meta.get("region_thresholds", {}).items()}

        def classify(rgb: np.ndarray, depth_m: np.ndarray) -> PixelClasses:
            category, colour, state, confidence = predict(net, rgb, depth_m)
            return PixelClasses(category, colour, state, vocabulary.categories,
                                vocabulary.colours, vocabulary.states,
                                confidence.astype(np.float32), thresholds)

        return cls(classify, meta)

    def read(self, obs: Observation) -> tuple[Observation, SceneLabels]:
        if self._read is None or self._read[0] is not obs:  # the network runs once per frame
            instance, labels = read_frame(self.classify(obs.rgb, obs.depth_m), obs.depth_m,
                                          obs.intrinsics, obs.cam_to_world)
            seen = Observation(rgb=obs.rgb, depth_m=obs.depth_m, cam_to_world=obs.cam_to_world,
                               intrinsics=obs.intrinsics, pose=obs.pose, instance=instance)
            self._read = (obs, seen, labels)
        return self._read[1], self._read[2]
