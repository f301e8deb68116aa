"""The question's words matched to what the perception names, by meaning, once per episode.

``Target.is_a`` matches the question's words to a perceived category by the words themselves
("chairs" is a "chair", "red sofa" a "sofa"); people also use other words for a category
("couch" for "sofa", "bedside table" for "nightstand", "coffee machine" for "coffee maker").
``AliasResolver`` finds those pairs once per episode and stores them in ``Target.aliases``,
which the gate, the steering, the sightings and the hints read through ``Target.is_a``:

- a word of the target one slip of the keyboard away from a word of the vocabulary (two
  neighbouring letters swapped, one dropped or doubled: ``question.slips``), where that fits one
  vocabulary word only and mending it makes the phrase a category, is that category ("tabel" a
  "table", "tv stnad" a "tv stand"): the rules hold no list of objects, the vocabulary is one;
- every other object or support word of the target that is no category of the vocabulary (after
  case and plural) is embedded with the categories (the project's MiniLM, ``relevancy.text``);
  where its words already name a category ("dining table" a "table"), only the categories
  closer to them than that one are candidates (so "dining table" is never a "chair");
- a pair at cosine ``clear`` or more is an alias;
- the ``top`` closest categories from ``unsure`` up to ``clear`` are asked of the agent's chat
  model in one yes/no call for all of them; the pairs it says "yes" to are aliases.

The vocabulary is what the perception can name: the semantic sensor's categories (the scene's
labels), the pixel network's classes (``perception.pixels``); ``stack.perception_vocabulary``
gives it. A VLM over images names no fixed list: its sightings (``perception.sightings``) are
asked in the target's own words, so they need none. Thresholds were set on a handful of
everyday synonym pairs (couch/sofa 0.86, coffee machine/coffee maker 0.88, bedside
table/nightstand 0.68, stool/chair 0.60), no held-out question.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence

import numpy as np

from efficienteqa.models.base import ChatModel, Message
from efficienteqa.question import Target, names, singular, slips
from efficienteqa.vc.prompts import load_prompt

PROMPTS = "efficienteqa.reading"  # reading/prompts/same.txt
MATCHINGS = ("words", "meaning")
CLEAR = 0.85
UNSURE = 0.5
TOP = 3
MAX_TOKENS = 48

Embed = Callable[[Sequence[str]], np.ndarray]  # texts -> (N, D) unit vectors


class AliasResolver:
    """``aliases(target, vocabulary)``: the (question's words, category) pairs that name the
    same thing; ``model`` None keeps only the clear pairs. ``problems`` collects what could not
    be read of the model's replies."""

    def __init__(self, embed: Embed, model: ChatModel | None = None, clear: float = CLEAR,
                 unsure: float = UNSURE, top: int = TOP) -> None:
        self.embed, self.model = embed, model
        self.clear, self.unsure, self.top = clear, unsure, top
        self.problems: list[str] = []

    def aliases(self, target: Target, vocabulary: Sequence[str]) -> tuple[tuple[str, str], ...]:
        categories = sorted({c.lower() for c in vocabulary})
        # a word equal to a category needs nothing; "bedside table" names a "table" by its
        # words, and may still be a "nightstand"
        words = [t for t in dict.fromkeys(target.things)
                 if not any(singular(t.lower()) == singular(c) for c in categories)]
        if not words or not categories:
            return ()
        mended = slip_aliases(words, categories)
        words = [w for w in words if w not in mended]
        if not words:
            return tuple(mended.items())
        sims = np.asarray(self.embed(words)) @ np.asarray(self.embed(categories)).T
        clear: list[tuple[str, str]] = []
        unsure: list[tuple[str, str]] = []
        for i, word in enumerate(words):
            # a category its words already name needs no alias ("wooden chair" is a "chair"),
            # and one further from them than that category is no other name for them: "dining
            # table" names a "table" (0.68), not a "chair" (0.50); "bedside table" is nearer
            # "nightstand" (0.68) than "table" (0.59)
            named = [sims[i, j] for j in range(len(categories)) if names(word, categories[j])]
            order = [j for j in np.argsort(-sims[i], kind="stable")
                     if not names(word, categories[j]) and sims[i, j] > max(named, default=-1.0)]
            sure = [(word, categories[j]) for j in order if sims[i, j] >= self.clear]
            clear += sure
            if not sure:
                unsure += [(word, categories[j]) for j in order[:self.top]
                           if sims[i, j] >= self.unsure]
        return (*mended.items(), *clear, *self._ask(unsure))

    def _ask(self, pairs: list[tuple[str, str]]) -> list[tuple[str, str]]:
        """The pairs the model says name the same kind of object: one call for all."""
        if not pairs or self.model is None:
            return []
        listed = "\n".join(f'{i + 1}. "{a}" and "{b}"' for i, (a, b) in enumerate(pairs))
        prompt = load_prompt("same", PROMPTS).format(pairs=listed)
        reply = self.model.chat([Message("user", prompt)], max_tokens=MAX_TOKENS + 6 * len(pairs),
                                temperature=0.0).text or ""
        said = {int(n): v == "yes" for n, v in
                re.findall(r"(?m)^\W*(\d+)\W+\"?.*?\b(yes|no)\b", reply.lower())}
        if len(said) < len(pairs):
            self.problems.append(f"{len(pairs) - len(said)} of {len(pairs)} pairs unanswered in "
                                 f"{reply[:60]!r}: not aliases")
        return [p for i, p in enumerate(pairs) if said.get(i + 1, False)]


def slip_aliases(words: Sequence[str], categories: Sequence[str]) -> dict[str, str]:
    """{word: category} for the words that name a category once their slips are mended: each
    token (or its singular) that is no word of the categories and is one slip
    (``question.slips``) of exactly one of them is read as that one; the mended phrase is then
    the category, or ends with it as whole words ("dining tabel" a "table"; the longest such:
    "wooden tabel lamp" a "table lamp", not a "lamp"). A longer category that merely ends with
    the phrase is a kind of it, not its name ("tabel" is no "foosball table")."""
    vocabulary = {t for c in categories for t in c.lower().split()}
    typed: dict[str, set[str]] = {}
    for token in vocabulary:
        for slip in slips(token):
            typed.setdefault(slip, set()).add(token)

    def mend(token: str) -> str:
        if token in vocabulary or singular(token) in vocabulary:
            return token
        fits = typed.get(token) or typed.get(singular(token)) or set()
        return next(iter(fits)) if len(fits) == 1 else token

    out: dict[str, str] = {}
    for word in words:
        tokens = word.lower().split()
        fixed = " ".join(map(mend, tokens))
        if fixed != " ".join(tokens):
            phrase = singular(fixed)
            named = [c for c in categories if phrase == singular(c.lower())
                     or phrase.endswith(" " + singular(c.lower()))]
            if named:
                out[word] = max(named, key=len)
    return out
