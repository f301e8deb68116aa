"""Choosing a back-end by name, one way everywhere.

Each kind of back-end (explorer, relevancy scorer, perception, answer grouping, chat back-end)
keeps one ``Registry``: names mapped to factories, built lazily. A factory is a callable or a
``"module:attribute.path"`` string imported only when that name is built, so heavy optional
dependencies (torch, transformers) load only for the back-ends that need them. An unknown name is
one clear error listing the known ones.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any, Generic, TypeVar

from efficienteqa.errors import EfficientEQAError

T = TypeVar("T")


class Registry(Generic[T]):
    """Named factories of one kind of back-end. ``kind`` names it in errors ("explorer")."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._factories: dict[str, tuple[Callable[..., T] | str, dict[str, Any]]] = {}

    def register(self, name: str, factory: Callable[..., T] | str, **defaults: Any) -> None:
        """``defaults`` are keyword arguments every build of ``name`` gets (callers may override)."""
        if name in self._factories:
            raise ValueError(f"{self.kind} {name!r} is registered twice")
        self._factories[name] = (factory, defaults)

    def names(self) -> tuple[str, ...]:
        return tuple(self._factories)

    def __contains__(self, name: object) -> bool:
        return name in self._factories

    def check(self, name: str) -> None:
        """Fail with one line, before anything slow, when ``name`` is not registered."""
        if name not in self._factories:
            raise EfficientEQAError(f"unknown {self.kind} {name!r}",
                                    fix=f"use one of {', '.join(self._factories)}")

    def build(self, name: str, **kwargs: Any) -> T:
        self.check(name)
        factory, defaults = self._factories[name]
        if isinstance(factory, str):
            module, _, path = factory.partition(":")
            target: Any = importlib.import_module(module)
            for attr in path.split("."):
                target = getattr(target, attr)
            factory = target
        assert callable(factory)
        return factory(**{**defaults, **kwargs})
