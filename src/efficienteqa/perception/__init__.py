"""Perception back-ends. ``semantic``: the offline default (DESIGN 5) that turns the environment's
instance buffer into short factual text for a text-only language model."""

from efficienteqa.perception.semantic import (
    FrameDescription,
    NoiseConfig,
    VisibleObject,
    describe_directions,
    describe_frame,
)

__all__ = [
    "FrameDescription",
    "NoiseConfig",
    "VisibleObject",
    "describe_directions",
    "describe_frame",
]
