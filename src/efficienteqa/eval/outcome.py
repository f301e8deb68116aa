"""What a method returns for one episode (``Outcome``), and the shape of a method: one module
below ``eval.methods`` and ``eval.agents``, which both make them."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from efficienteqa.datasets.base import EvalQuestion

if TYPE_CHECKING:
    from efficienteqa.eval.spec import RunSpec


@dataclass
class Outcome:
    """What a method returns for one episode; the runner adds identity, timing and the judge."""

    answer: str
    confidence: float
    steps: int
    budget: int | None = None
    stop_reason: str | None = None
    usage: dict[str, Any] = field(default_factory=dict)  # calls, cached_calls, tokens, latency_s
    backends: dict[str, Any] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)
    # From the ground truth after the episode (report.evidence); None where unknown.
    evidence_first_seen_step: int | None = None
    evidence_in_top_k: bool | None = None
    # a relevancy stop's tested frame: its fewest evidence pixels at 640 x 480 (report.evidence)
    evidence_stop_pixels: float | None = None
    refused_moves: int | None = None  # moves the environment refused (agent methods)


MethodFn = Callable[[EvalQuestion, "RunSpec", Path], Outcome]
