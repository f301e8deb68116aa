"""Back-ends are chosen by name one way everywhere: one registry per kind, built lazily."""

from __future__ import annotations

import sys

import pytest

from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.registry import EXPLORERS
from efficienteqa.models.backends import CHAT_BACKENDS
from efficienteqa.registry import Registry
from efficienteqa.relevancy.base import SCORERS
from efficienteqa.stack import GROUPINGS, PERCEPTIONS


def test_an_unknown_name_is_one_error_listing_the_known_ones():
    for registry, kind in ((EXPLORERS, "explorer"), (SCORERS, "relevancy scorer"),
                           (PERCEPTIONS, "perception"), (GROUPINGS, "grouping"),
                           (CHAT_BACKENDS, "chat back-end")):
        with pytest.raises(EfficientEQAError) as info:
            registry.build("no-such-thing")
        message = str(info.value)
        assert f"unknown {kind} 'no-such-thing'" in message
        assert all(name in message for name in registry.names())


def test_a_string_factory_is_imported_only_when_built_and_defaults_can_be_overridden():
    registry: Registry[object] = Registry("thing")
    registry.register("frac", "fractions:Fraction", numerator=3)
    sys.modules.pop("fractions", None)
    assert "fractions" not in sys.modules
    assert registry.build("frac") == 3
    assert "fractions" in sys.modules
    assert registry.build("frac", numerator=1, denominator=2) == 0.5


def test_a_name_registers_once():
    registry: Registry[object] = Registry("thing")
    registry.register("a", dict)
    with pytest.raises(ValueError, match="registered twice"):
        registry.register("a", list)
