"""The explorer registry: ``make_explorer(name, **config)`` builds "sfe", "frontier-only" or
"random"; ``config`` holds fields of the explorer's config dataclass (``SFEConfig`` or
``RandomConfig``).
"""

from __future__ import annotations

from collections.abc import Callable

from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.base import Explorer
from efficienteqa.explore.random_walk import RandomConfig, RandomExplorer
from efficienteqa.explore.sfe import FrontierExplorer, SFEConfig


def _sfe(**config) -> Explorer:
    return FrontierExplorer(SFEConfig(**config))


def _frontier_only(**config) -> Explorer:
    return FrontierExplorer(SFEConfig(**{**config, "use_values": False}))


def _random(**config) -> Explorer:
    return RandomExplorer(RandomConfig(**config))


EXPLORERS: dict[str, Callable[..., Explorer]] = {
    "sfe": _sfe,
    "frontier-only": _frontier_only,
    "random": _random,
}


def make_explorer(name: str, **config) -> Explorer:
    """The explorer registered as ``name``; ``config`` overrides its config fields."""
    if name not in EXPLORERS:
        raise EfficientEQAError(f"unknown explorer {name!r}", f"choose one of {sorted(EXPLORERS)}")
    return EXPLORERS[name](**config)
