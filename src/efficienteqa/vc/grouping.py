"""Semantic grouping E(.) of free-form answers and the class confidences C_k."""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from efficienteqa.models.base import ChatModel, Message
from efficienteqa.vc.parse import AnswerClass, Candidate
from efficienteqa.vc.prompts import load_prompt

# ---------------------------------------------------------------------------- VC pipeline

def normalise(candidates: Sequence[Candidate]) -> list[Candidate]:
    """``c_i' = c_i / sum c`` (non-finite or negative count as 0; all zero -> uniform)."""
    conf = [c.confidence if math.isfinite(c.confidence) and c.confidence > 0 else 0.0
            for c in candidates]
    total = sum(conf)
    if total <= 0:
        return [Candidate(c.text, 1.0 / len(candidates)) for c in candidates]
    return [Candidate(c.text, x / total) for c, x in zip(candidates, conf)]


class Grouper(Protocol):
    """The semantic grouping E(.): a class label per answer, labels numbered by first appearance,
    plus the repairs made on the way."""

    def partition(self, question: str, texts: Sequence[str]) -> tuple[list[int], list[str]]: ...


def _tokens(text: str) -> list[str]:
    return re.findall(r"[a-z]+|[0-9]+(?:\.[0-9]+)?", text.casefold())


_ARTICLES = {"a", "an", "the"}
_FILLER = {"there", "are", "is", "it", "its", "i", "see", "about", "around", "approximately",
           "roughly", "maybe", "probably", "likely", "total", "in", "of"}
_NUMBER_WORDS = {w: i for i, w in enumerate((
    "zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten", "eleven",
    "twelve", "thirteen", "fourteen", "fifteen", "sixteen", "seventeen", "eighteen", "nineteen",
    "twenty"))} | {"none": 0}
_YES = {"yes", "yeah", "yep", "correct", "true"}
_NO = {"no", "nope", "false", "incorrect"}
# The veto lists: answers naming different members of one of these sets never merge.
_COLOURS = {"red", "orange", "yellow", "green", "blue", "purple", "pink", "brown", "black", "white",
            "grey", "gray", "beige", "silver", "gold"}
_ROOMS = {"kitchen", "bedroom", "bathroom", "living", "dining", "hallway", "hall", "corridor",
          "office", "study", "garage", "laundry", "closet", "basement", "attic", "balcony"}
_SYNONYMS = {"gray": "grey", "hall": "hallway", "corridor": "hallway"}


def _singular(w: str) -> str:
    if len(w) > 4 and w.endswith("ies"):
        return w[:-3] + "y"
    if len(w) > 4 and w.endswith(("ches", "shes", "xes", "sses")):
        return w[:-2]
    if len(w) > 3 and w.endswith("s") and not w.endswith(("ss", "us", "is")):
        return w[:-1]
    return w


@dataclass(frozen=True)
class _Facts:
    key: str
    numbers: frozenset[float]
    polarity: str | None
    colours: frozenset[str]
    rooms: frozenset[str]


def _facts(text: str) -> _Facts:
    toks = _tokens(text)
    numbers: set[float] = set()
    content: list[str] = []
    for i, t in enumerate(toks):
        if t[0].isdigit():
            numbers.add(float(t))
        elif t in _NUMBER_WORDS and (t != "one" or i == 0):  # "the red one" is not a count
            numbers.add(float(_NUMBER_WORDS[t]))
        elif t not in _ARTICLES and t not in _FILLER:
            content.append(_singular(t))
    polarity = "yes" if toks and toks[0] in _YES else "no" if toks and toks[0] in _NO else None
    if polarity:
        key = polarity
    elif len(numbers) == 1 and len(content) <= 2:
        key = f"#{next(iter(numbers)):g}"
    else:
        key = " ".join(content) or " ".join(text.casefold().split())
    words = {_SYNONYMS.get(t, t) for t in toks}
    return _Facts(key, frozenset(numbers), polarity, frozenset(words & _COLOURS - {"gray"}),
                  frozenset(words & _ROOMS - {"hall", "corridor"}))


def contradictory(a: str, b: str) -> bool:
    """The veto: different numbers, yes vs no, different colour words, different room words."""
    fa, fb = _facts(a), _facts(b)
    return any(x and y and x != y for x, y in ((fa.numbers, fb.numbers), (fa.polarity, fb.polarity),
                                               (fa.colours, fb.colours), (fa.rooms, fb.rooms)))


class _Classes:
    """Union of answers into classes; a merge is refused if any two members contradict."""

    def __init__(self, texts: Sequence[str]) -> None:
        self.texts = list(texts)
        self.label = list(range(len(texts)))

    def members(self, k: int) -> list[int]:
        return [i for i, lab in enumerate(self.label) if lab == k]

    def merge(self, i: int, j: int) -> bool:
        a, b = self.label[i], self.label[j]
        if a == b:
            return True
        if any(contradictory(self.texts[x], self.texts[y]) for x in self.members(a) for y in self.members(b)):
            return False
        lo, hi = min(a, b), max(a, b)
        self.label = [lo if lab == hi else lab for lab in self.label]
        return True

    def labels(self) -> list[int]:
        order: dict[int, int] = {}
        return [order.setdefault(lab, len(order)) for lab in self.label]


class ExactGrouper:
    """For letters: equal after case folding and whitespace/punctuation trimming."""

    def partition(self, question: str, texts: Sequence[str]) -> tuple[list[int], list[str]]:
        order: dict[str, int] = {}
        return [order.setdefault(" ".join(t.casefold().split()).strip(" .!?,;:'\""), len(order))
                for t in texts], []


class RuleGrouper:
    """Cheap rules: case, articles, plurals; one number with at most two other words ("4",
    "four", "4 chairs"); yes/no by the first word ("yes, it is on"). Vetoed pairs stay apart."""

    def partition(self, question: str, texts: Sequence[str]) -> tuple[list[int], list[str]]:
        classes = _Classes(texts)
        keys = [_facts(t).key for t in texts]
        for j in range(len(texts)):
            for i in range(j):
                if keys[i] == keys[j]:
                    classes.merge(i, j)
        return classes.labels(), []


class LLMGrouper:
    """Rules first; the remaining classes are compared pairwise. With an ``embedder``
    (``embed(texts) -> (n, d) array``) only pairs of cosine >= ``threshold`` are proposed; each
    proposal is confirmed by the model with ``group.txt`` (one yes/no per pair: the easiest
    output for a 1.5B model to get right, and M = 3 leaves at most three pairs). Vetoed pairs
    never reach the model."""

    def __init__(self, model: ChatModel, embedder: Callable[[list[str]], np.ndarray] | None = None,
                 threshold: float = 0.8, max_pairs: int = 6) -> None:
        self.model, self.embedder = model, embedder
        self.threshold, self.max_pairs = threshold, max_pairs
        self.rules = RuleGrouper()
        self._answers: dict[tuple[str, ...], bool] = {}

    def partition(self, question: str, texts: Sequence[str]) -> tuple[list[int], list[str]]:
        labels, problems = self.rules.partition(question, texts)
        classes = _Classes(texts)
        for j, lab in enumerate(labels):
            classes.merge(labels.index(lab), j)
        reps = [labels.index(k) for k in range(max(labels, default=-1) + 1)]
        sims = self._similarity([texts[r] for r in reps], problems)
        asked = 0
        for b in range(len(reps)):
            for a in range(b):
                i, j = reps[a], reps[b]
                if contradictory(texts[i], texts[j]) or (sims is not None and sims[a, b] < self.threshold):
                    continue
                if asked >= self.max_pairs:
                    problems.append("grouping: pair budget spent")
                    return classes.labels(), problems
                asked += 1
                if self._same(question, texts[i], texts[j], problems):
                    classes.merge(i, j)
        return classes.labels(), problems

    def _similarity(self, texts: list[str], problems: list[str]) -> np.ndarray | None:
        if self.embedder is None or len(texts) < 2:
            return None
        emb = np.asarray(self.embedder(texts), dtype=float)
        if emb.ndim != 2 or len(emb) != len(texts) or not np.isfinite(emb).all():
            problems.append("grouping: unusable embeddings, asking about every pair")
            return None
        unit = emb / np.maximum(np.linalg.norm(emb, axis=1, keepdims=True), 1e-12)
        return unit @ unit.T

    def _same(self, question: str, a: str, b: str, problems: list[str]) -> bool:
        key = (question, *sorted((a, b)))
        if key not in self._answers:
            prompt = load_prompt("group").format(question=question, first=a, second=b)
            reply = self.model.chat([Message("user", prompt)], max_tokens=4, temperature=0.0).text or ""
            words = re.findall(r"[a-z]+", reply.lower())
            verdict = next((w for w in words if w in ("yes", "same", "no", "different")), None)
            if verdict is None:
                problems.append(f"grouping: unreadable reply {reply[:20]!r}, kept apart")
            self._answers[key] = verdict in ("yes", "same")
        return self._answers[key]


def group_answers(question: str, candidates: Sequence[Candidate], grouper: Grouper,
                  problems: list[str] | None = None) -> list[AnswerClass]:
    """Normalise, apply E(.) and sum ``C_k = sum c_i'`` per class (classes by first appearance;
    a class is named by its most confident member)."""
    norm = normalise(candidates)
    if not norm:
        return []
    labels, found = grouper.partition(question, [c.text for c in norm])
    if problems is not None:
        problems.extend(found)
    classes: list[AnswerClass] = []
    for k in range(max(labels) + 1):
        members = [c for c, lab in zip(norm, labels) if lab == k]
        if members:
            best = max(members, key=lambda c: c.confidence)  # first on ties
            classes.append(AnswerClass(best.text, members, sum(c.confidence for c in members)))
    return classes


def argmax(classes: Sequence[AnswerClass]) -> tuple[str, float]:
    """``(R*, C*)``; ties go to the first class; no classes -> ``("", 0.0)``."""
    best = None
    for c in classes:
        if best is None or c.confidence > best.confidence:
            best = c
    return (best.text, best.confidence) if best else ("", 0.0)


