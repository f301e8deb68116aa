"""Perception back-ends. ``semantic``: the offline default (SPEC 5) that turns the environment's
instance buffer into short factual text for a text-only language model."""

from efficienteqa.perception.semantic import (
    FrameDescription,
    NoiseConfig,
    ObjectLabel,
    SceneLabels,
    VisibleObject,
    describe_directions,
    describe_frame,
    house_labels,
)

__all__ = [
    "FrameDescription",
    "NoiseConfig",
    "ObjectLabel",
    "SceneLabels",
    "VisibleObject",
    "describe_directions",
    "describe_frame",
    "house_labels",
]
