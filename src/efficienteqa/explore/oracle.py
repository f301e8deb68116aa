"""Ground-truth semantic values, for benchmarks that isolate exploration from the model.

LSV = 1 on the prompted point closest (by path) to the question's evidence, 0 on the others;
P(worth exploring) = 1 while the evidence is in view, else 0. An upper bound on what a perfect
scorer could give SFE; never used to answer questions.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from efficienteqa.envs.base import Observation
from efficienteqa.explore.module import SemanticScore
from efficienteqa.explore.prompting import PromptPoint


class OracleScorer:
    """``distance_m(xy)`` is the path distance from a floor point to the evidence (inf when
    unreachable); ``visible(instance)`` says whether the evidence is in view in a frame."""

    def __init__(self, distance_m: Callable[[Sequence[float]], float],
                 visible: Callable[[np.ndarray], bool]) -> None:
        self.distance_m, self.visible = distance_m, visible

    def score(self, obs: Observation, prompts: list[PromptPoint], question: str) -> SemanticScore:
        distances = [self.distance_m(p.xy) for p in prompts]
        best = int(np.argmin(distances))
        letters = {p.letter: float(i == best) for i, p in enumerate(prompts)}
        in_view = obs.instance is not None and self.visible(obs.instance)
        return SemanticScore(letters, 1.0 if in_view else 0.0, {"distances_m": distances})
