"""Ground-truth semantic values, for benchmarks that isolate exploration from the model.

LSV = 1 on the prompted point closest (by path) to the question's evidence, 0 on the others.
P(worth exploring) answers the GSV question "is any direction in this view worth exploring?":
1 when the evidence is in view or a prompted direction leads at least ``gain_m`` closer to it
(by path) than the robot stands, else 0. What a perfect scorer could give SFE; never used to
answer questions.
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
                 visible: Callable[[np.ndarray], bool], gain_m: float = 1.0) -> None:
        self.distance_m, self.visible, self.gain_m = distance_m, visible, gain_m

    def score(self, obs: Observation, prompts: list[PromptPoint], question: str) -> SemanticScore:
        distances = [self.distance_m(p.xy) for p in prompts]
        best = int(np.argmin(distances))
        letters = {p.letter: float(i == best) for i, p in enumerate(prompts)}
        in_view = obs.instance is not None and self.visible(obs.instance)
        closer = distances[best] < self.distance_m((obs.pose.x, obs.pose.y)) - self.gain_m
        return SemanticScore(letters, 1.0 if in_view or closer else 0.0,
                             {"distances_m": distances})
