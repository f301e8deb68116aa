"""The direction experiment's scorers (DESIGN 8): what ``direction-logit``
(``efficienteqa.explore.text_scorers.LogitDirections``) was chosen against on recorded frames
(``experiments/direction_bench.py``): random, the nearest point, keyword overlap, MiniLM
similarity between the question and each direction, and the black-box and white-box
elicitations of a text model (``ELICITATIONS``). Each is a ``DirectionTextScorer``;
``DirectionScorer`` turns one into the explore module's scorer (``explore_bench`` steering).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from efficienteqa.explore.text_scorers import (
    DirectionFrame,
    DirectionTextScorer,
    Scores,
    direction_parts,
    softmax,
    uniform,
)
from efficienteqa.explore.vlm_scorer import (
    PROMPTS,
    directions_text,
    explore_scores,
    explore_token_scores,
)
from efficienteqa.models.base import ChatModel, Message
from efficienteqa.relevancy.text import MiniLMScorer, content_words
from efficienteqa.vc.logprobs import (
    TOP_LOGPROBS,
    letter_probs_from_logprobs,
    letter_read,
    require_logprobs,
    yes_prob_from_logprobs,
    yes_prob_or_none,
)
from efficienteqa.vc.parse import DEFAULT_LETTERS, M
from efficienteqa.vc.prompts import load_prompt
from efficienteqa.vc.yes_no import DEFAULT_P_YES


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


# Black-box elicitations of a text model over the direction texts (DESIGN 8), each a
# ``DirectionTextScorer`` (explore/text_scorers.py): per-letter confidences from a frame's
# question, view and direction texts. ``DirectionScorer`` makes any of them a SemanticScorer.


class VCDirections:
    """The current exploration call (``explore_scores``, verbalized confidence) as a direction
    scorer: the reference the new elicitations must beat."""

    name = "vc"

    def __init__(self, model: ChatModel, m: int = M) -> None:
        self.model, self.m = model, m

    def letter_scores(self, frame: DirectionFrame) -> Scores:
        s = explore_scores(self.model, frame.question, frame.view, dict(frame.directions), m=self.m)
        return s.letters, {"problems": s.info.get("problems", []), "raw": s.info.get("raw")}


class TokenDirections:
    """The white-box reading (``explore_token_scores``): P(letter) from token probabilities."""

    name = "token"

    def __init__(self, model: ChatModel) -> None:
        self.model = model

    def letter_scores(self, frame: DirectionFrame) -> Scores:
        s = explore_token_scores(self.model, frame.question, frame.view, dict(frame.directions))
        return s.letters, {"problems": s.info.get("problems", []), "raw": s.info.get("raw")}


def relabelled(directions: Mapping[str, str], shift: int) -> dict[str, str]:
    """The directions in an order turned by ``shift`` and lettered afresh A, B, C...: new letter
    -> original letter. Shift 0 is the identity."""
    original = list(directions)
    turned = original[shift % len(original):] + original[:shift % len(original)]
    return {DEFAULT_LETTERS[i]: x for i, x in enumerate(turned)}


def choice_prompt(question: str, view: str, directions: Mapping[str, str]) -> str:
    return load_prompt("explore_choice", PROMPTS).format(
        question=question, view=view or "nothing visible",
        directions=directions_text(list(directions), directions))


class DebiasedDirections:
    """Order-debiased single choice: the directions are shown in every cyclic order, lettered
    afresh each time (so neither a position nor a letter is favoured), P(letter) is read from
    the first reply token's probabilities, mapped back and averaged. One one-token call per
    order (``len(letters)`` calls)."""

    name = "debiased"

    def __init__(self, model: ChatModel) -> None:
        require_logprobs(model)
        self.model = model

    def letter_scores(self, frame: DirectionFrame) -> Scores:
        letters = frame.letters
        total = dict.fromkeys(letters, 0.0)
        problems: list[str] = []
        for shift in range(len(letters)):
            names = relabelled(frame.directions, shift)
            shown = {new: frame.directions[old] for new, old in names.items()}
            resp = self.model.chat([Message("user", choice_prompt(frame.question, frame.view,
                                                                  shown))],
                                   max_tokens=1, temperature=0.0, logprobs=TOP_LOGPROBS)
            if not resp.logprobs:
                problems.append(f"order {shift}: no logprobs, counted uniform")
            elif not letter_read(resp.logprobs, list(names)):
                problems.append(f"order {shift}: no letter among the top logprobs, counted uniform")
            probs = letter_probs_from_logprobs(resp.logprobs, list(names))
            for new, old in names.items():
                total[old] += probs[new] / len(letters)
        return total, {"problems": problems}


class SampledDirections:
    """Sampled single choices counted as confidence: ``n`` replies at ``temperature`` (seeds
    0..n-1, the cyclic orders of the directions in equal blocks, lettered afresh), the share of replies naming
    each direction; a reply naming none counts for nothing (all unreadable: uniform)."""

    name = "sampled"

    def __init__(self, model: ChatModel, n: int = 6, temperature: float = 1.0) -> None:
        self.model, self.n, self.temperature = model, n, temperature

    def letter_scores(self, frame: DirectionFrame) -> Scores:
        letters = frame.letters
        votes = dict.fromkeys(letters, 0.0)
        for k in range(self.n):  # orders in blocks: repeats of a prompt reuse its evaluation
            names = relabelled(frame.directions, k * len(letters) // self.n)
            shown = {new: frame.directions[old] for new, old in names.items()}
            resp = self.model.chat([Message("user", choice_prompt(frame.question, frame.view,
                                                                  shown))],
                                   max_tokens=2, temperature=self.temperature, seed=k)
            picked = first_letter(resp.text or "", list(names))
            if picked is not None:
                votes[names[picked]] += 1.0
        if not any(votes.values()):
            return {x: 1.0 / len(letters) for x in letters}, {
                "problems": ["no reply named a direction: uniform"]}
        return {x: v / sum(votes.values()) for x, v in votes.items()}, {"problems": []}


def first_letter(reply: str, letters: Sequence[str]) -> str | None:
    """The first of ``letters`` that a reply names as a word ("B", "B.", "(C)"), or None."""
    for word in reply.replace("(", " ").replace(")", " ").split():
        key = word.strip(".:;,!?*\"'").upper()
        if key in letters:
            return key
    return None


def direction_prompt(question: str, view: str, direction: str) -> str:
    return load_prompt("explore_direction", PROMPTS).format(
        question=question, view=view or "nothing visible", direction=direction or "no description")


class YesNoDirections:
    """One question per direction: "does this direction lead towards the answer?", read as
    P(yes) over {yes, no} from the first reply token's probabilities (``DEFAULT_P_YES`` when
    neither is among them, with a recorded problem). One one-token call per direction."""

    name = "yes-no"

    def __init__(self, model: ChatModel) -> None:
        require_logprobs(model)
        self.model = model

    def letter_scores(self, frame: DirectionFrame) -> Scores:
        scores, problems = {}, []
        for x, text in frame.directions.items():
            resp = self.model.chat([Message("user", direction_prompt(frame.question, frame.view,
                                                                     text))],
                                   max_tokens=1, temperature=0.0, logprobs=TOP_LOGPROBS)
            if yes_prob_or_none(resp.logprobs) is None:
                problems.append(f"{x}: no yes/no among the reply's tokens: P(yes) = {DEFAULT_P_YES}")
            scores[x] = yes_prob_from_logprobs(resp.logprobs)
        return scores, {"problems": problems}


ELICITATIONS: dict[str, Callable[[ChatModel], DirectionTextScorer]] = {
    "vc": VCDirections, "token": TokenDirections, "debiased": DebiasedDirections,
    "sampled": SampledDirections, "yes-no": YesNoDirections,
}
