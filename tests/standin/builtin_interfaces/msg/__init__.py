"""``builtin_interfaces/msg``: ``Time`` and ``Duration`` (sec, nanosec)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Time:
    sec: int = 0
    nanosec: int = 0


@dataclass
class Duration:
    sec: int = 0
    nanosec: int = 0
