"""What an evaluation runs on: one question in one scene, with its reference answer.

Every dataset (the synthetic split, arbitrary synthetic seeds, HM-EQA) is read into a list of
``EvalQuestion``; the runner, the methods and the judge never look at the source format.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any


@dataclass(frozen=True)
class EvalQuestion:
    """One episode to run.

    ``id``: unique within its dataset and stable across versions of the code (the resume key).
    ``scene``: what ``scenes.open_scene`` reads ("synthetic:SEED"; HM-EQA scenes are
    "hm3d:<scene id>" and need the Habitat back-end). ``start``: canonical (x, y, yaw in
    radians), None for the scene's own start. ``choices``: the closed-set options where the
    dataset has them (HM-EQA), empty otherwise. ``accepted``: every form of the answer a grader
    must accept, where the dataset knows them (synthetic questions; graded by the ``rule``
    judge), empty otherwise. ``source``: dataset-specific fields kept for the record (e.g.
    HM-EQA's floor and Habitat start pose; a re-phrased question's ``original``).
    """

    id: str
    dataset: str
    scene: str
    question: str
    answer: str
    category: str
    alternatives: tuple[str, ...] = ()
    start: tuple[float, float, float] | None = None
    oracle_steps: int | None = None
    choices: tuple[str, ...] = ()
    accepted: tuple[str, ...] = ()
    source: dict[str, Any] = field(default_factory=dict, compare=False, hash=False)

    @property
    def original_question(self) -> str:
        """The wording the references were written for: a re-phrasing's original
        (``source["original"]["question"]``, the paraphrase split), else the question itself."""
        original = self.source.get("original")
        return str(original["question"]) if isinstance(original, dict) else self.question

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EvalQuestion:
        """The inverse of ``to_dict`` after a JSON round trip (which turns tuples into lists)."""
        data = dict(data)
        for key in ("alternatives", "choices", "accepted"):
            data[key] = tuple(data.get(key) or ())
        data["start"] = tuple(data["start"]) if data.get("start") else None
        return cls(**data)
