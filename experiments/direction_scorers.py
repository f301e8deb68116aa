"""The direction experiment's baseline scorers (DESIGN 8): what ``direction-logit``
(``efficienteqa.explore.text_scorers.LogitDirections``) was chosen against on recorded frames
(``experiments/direction_bench.py``): random, the nearest point, keyword overlap, and MiniLM
similarity between the question and each direction. Each is a ``DirectionTextScorer``;
``DirectionScorer`` turns one into the explore module's scorer (``explore_bench`` steering).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from efficienteqa.explore.text_scorers import (
    DirectionFrame,
    Scores,
    direction_parts,
    softmax,
    uniform,
)
from efficienteqa.relevancy.text import MiniLMScorer, content_words


class RandomDirections:
    """Uniformly random confidences from a seeded generator: the chance reference."""

    name = "random"

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)

    def letter_scores(self, frame: DirectionFrame) -> Scores:
        return {x: float(self.rng.random()) for x in frame.letters}, {}


class NearestDirections:
    """No semantics: the nearer a point, the higher its confidence (exp(-range / ``scale_m``))."""

    name = "nearest"

    def __init__(self, scale_m: float = 1.0) -> None:
        self.scale_m = scale_m

    def letter_scores(self, frame: DirectionFrame) -> Scores:
        return nearness(frame, self.scale_m), {}


def nearness(frame: DirectionFrame, scale_m: float = 1.0) -> dict[str, float]:
    """exp(-range / scale_m) normalised over the letters: a prior for the nearest point."""
    return softmax({x: -float(frame.ranges_m.get(x, 0.0)) for x in frame.letters}, scale_m)


class KeywordDirections:
    """The share of the question's content words found in each direction's text (uniform when
    none is found anywhere)."""

    name = "keyword"

    def letter_scores(self, frame: DirectionFrame) -> Scores:
        wanted = content_words(frame.question)
        hits = {x: len(wanted & content_words(t)) / max(len(wanted), 1)
                for x, t in frame.directions.items()}
        if not any(hits.values()):
            return uniform(frame.letters), {}
        return hits, {}


class EmbeddingDirections:
    """MiniLM cosine between the question and each direction's text: the whole text, or with
    ``parts`` its best phrase (a direction that shows the asked-about room or object among
    much else). Confidences are a softmax at ``temperature``; ``near_weight`` > 0 multiplies in
    the nearness prior (``nearness`` to that power)."""

    def __init__(self, embedder: MiniLMScorer, parts: bool = False, temperature: float = 0.05,
                 near_weight: float = 0.0, name: str = "minilm") -> None:
        self.embedder, self.parts, self.temperature = embedder, parts, temperature
        self.near_weight, self.name = near_weight, name

    @classmethod
    def from_package(cls, **kwargs: Any) -> EmbeddingDirections:
        return cls(MiniLMScorer.from_package(num_threads=1), **kwargs)

    def cosines(self, frame: DirectionFrame) -> dict[str, float]:
        texts = {x: (direction_parts(t) if self.parts else [t]) for x, t in frame.directions.items()}
        flat = [p for ps in texts.values() for p in ps]
        vectors = self.embedder.embed([frame.question, *flat])
        sims = vectors[1:] @ vectors[0]
        out, at = {}, 0
        for x, ps in texts.items():
            out[x] = float(sims[at:at + len(ps)].max())
            at += len(ps)
        return out

    def letter_scores(self, frame: DirectionFrame) -> Scores:
        if not frame.question.strip() or not any(t.strip() for t in frame.directions.values()):
            return uniform(frame.letters), {"problems": ["no question or no direction text: uniform"]}
        scores = softmax(self.cosines(frame), self.temperature)
        if self.near_weight:
            near = nearness(frame)
            scores = {x: v * near[x] ** self.near_weight for x, v in scores.items()}
        return scores, {}
