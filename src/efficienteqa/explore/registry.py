"""The explorer registry: ``make_explorer(name, **config)`` builds "sfe", "frontier-only" or
"random"; ``config`` holds fields of the explorer's config dataclass (``SFEConfig`` or
``RandomConfig``); ``explore.config.ExploreConfig.explorer_options`` gives those of a run.
"""

from __future__ import annotations

from typing import Any

from efficienteqa.explore.base import Explorer
from efficienteqa.explore.random_walk import RandomConfig, RandomExplorer
from efficienteqa.explore.settings import SFEConfig
from efficienteqa.explore.sfe import FrontierExplorer
from efficienteqa.registry import Registry


def _sfe(**config: Any) -> Explorer:
    return FrontierExplorer(SFEConfig(**config))


def _frontier_only(**config: Any) -> Explorer:
    return FrontierExplorer(SFEConfig(**{**config, "use_values": False}))


def _random(**config: Any) -> Explorer:
    return RandomExplorer(RandomConfig(**config))


EXPLORERS: Registry[Explorer] = Registry("explorer")
EXPLORERS.register("sfe", _sfe)
EXPLORERS.register("frontier-only", _frontier_only)
EXPLORERS.register("random", _random)


def make_explorer(name: str, **config: Any) -> Explorer:
    """The explorer registered as ``name``; ``config`` overrides its config fields."""
    return EXPLORERS.build(name, **config)
