"""When an episode's evidence was in view: computed after the episode, from the ground truth.

The agent never sees any of this. A step hook (``EvidenceWatch``) notes which steps' frames show
every evidence object of a known question, by the synthetic oracle's own test
(``envs.synthetic.questions.evidence_visible``: each object covers at least the pixel threshold
the oracle step counts use); ``fields`` then gives what ``episode.json`` and the eval rows record:

- ``evidence_first_seen_step``: the first step whose frame shows the evidence (None: never);
- ``evidence_in_top_k``: whether the frames the answer was given (the retrieved top-K, or the
  best step) include such a frame;
- ``evidence_seen_steps``: every such step;
- ``evidence_stop_pixels``: where a relevancy stop ended the episode, the fewest pixels any
  evidence object covers in the frame the stop tested (the stop's own, or under look-back the
  earlier one it stopped for), in pixels of a 640 x 480 frame (``evidence_pixels``), so that
  the stop's frame is audited at the 250 px rule and at any other (DESIGN 9); None
  otherwise.

Where the scene has no ground truth (HM-EQA, a question of the user's own, an existence question
answered "no") all three are None, which is not the same as "never seen" (None, False, []).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from efficienteqa.envs.synthetic.questions import evidence_visible
from efficienteqa.explore.module import ExploreStep
from efficienteqa.observation import Observation
from efficienteqa.trace import StepRecord

FIELDS = ("evidence_first_seen_step", "evidence_in_top_k", "evidence_seen_steps",
          "evidence_stop_pixels")


def evidence_pixels(instance: np.ndarray, evidence: Sequence[int]) -> float:
    """The fewest pixels any evidence object covers in ``instance``, scaled to a 640 x 480
    frame (0 when one is out of view)."""
    counts = np.bincount(instance[instance > 0].ravel(), minlength=max(evidence) + 1)
    return float(min(counts[e] for e in evidence)) * (640 * 480) / instance.size


class EvidenceWatch:
    """A step hook: which steps' frames show every object of ``evidence`` (instance ids).
    ``evidence`` empty or None: nothing is known, and every field is None."""

    def __init__(self, evidence: Sequence[int] | None) -> None:
        self.evidence = list(evidence or [])
        self.steps: list[int] = []
        self.pixels: dict[int, float] = {}  # step -> evidence_pixels of its frame
        self.blind = False  # a frame came without an instance buffer: cannot tell

    def __call__(self, record: StepRecord, obs: Observation, out: ExploreStep | None) -> None:
        if not self.evidence:
            return
        if obs.instance is None:
            self.blind = True
        else:
            self.pixels[record.step] = evidence_pixels(obs.instance, self.evidence)
            if evidence_visible(obs.instance, self.evidence):
                self.steps.append(record.step)

    def fields(self, retrieved: Sequence[tuple[int, float]], stop_step: int | None = None
               ) -> dict[str, Any]:
        """The record's fields, given the (step, Sim) pairs of the frames the answer read and
        the frame a relevancy stop tested (None: no relevancy stop)."""
        if not self.evidence or self.blind:
            return dict.fromkeys(FIELDS)
        shown = set(self.steps)
        return {"evidence_first_seen_step": min(shown) if shown else None,
                "evidence_in_top_k": any(step in shown for step, _ in retrieved),
                "evidence_seen_steps": sorted(shown),
                "evidence_stop_pixels": (None if stop_step is None
                                         else round(self.pixels.get(stop_step, 0.0), 1))}
