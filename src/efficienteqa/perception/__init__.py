"""Perception back-ends. ``semantic``: the offline default (DESIGN 5) that turns the environment's
instance buffer into short factual text for a text-only language model."""

from efficienteqa.perception.semantic import describe_directions, describe_frame
from efficienteqa.perception.visible import FrameDescription, NoiseConfig, VisibleObject

__all__ = [
    "FrameDescription",
    "NoiseConfig",
    "VisibleObject",
    "describe_directions",
    "describe_frame",
]
