"""The question's target of one episode: read (``reading``), then matched to what the
perception names (``matching``); both are ``AgentConfig`` options.

``reading``: "rules" (``question.parse_question``, no call), "model" (``reader.ModelReader``:
one call, each field checked, the rules' field where it fails), "rules+rooms" (the rules'
target with the model's likely rooms only, one call where the question names no room).
``matching``: "words" (the question's words name a category by themselves) or "meaning"
(``aliases.AliasResolver`` over the perception's vocabulary). With an ``adjacency``
(``TargetConfig.near_rooms``), a named room's usual neighbours (``adjacency.RoomAdjacency``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from efficienteqa.question import Target, parse_question
from efficienteqa.reading.adjacency import RoomAdjacency
from efficienteqa.reading.aliases import MATCHINGS, AliasResolver
from efficienteqa.reading.reader import READINGS, ModelReader


class TargetReading:
    def __init__(self, reading: str = "rules", matching: str = "words",
                 reader: ModelReader | None = None, resolver: AliasResolver | None = None,
                 vocabulary: Sequence[str] = (), adjacency: RoomAdjacency | None = None
                 ) -> None:
        if reading not in READINGS:
            raise ValueError(f"reading must be one of {READINGS}, not {reading!r}")
        if matching not in MATCHINGS:
            raise ValueError(f"matching must be one of {MATCHINGS}, not {matching!r}")
        if reading != "rules" and reader is None:
            raise ValueError(f"the {reading!r} reading needs a model reader")
        if matching == "meaning" and resolver is None:
            raise ValueError("matching by meaning needs an alias resolver")
        self.reading, self.matching = reading, matching
        self.reader, self.resolver, self.vocabulary = reader, resolver, tuple(vocabulary)
        self.adjacency = adjacency

    @property
    def problems(self) -> list[str]:
        return [*(self.reader.problems if self.reader else []),
                *(self.resolver.problems if self.resolver else []),
                *(self.adjacency.problems if self.adjacency else [])]

    def target(self, question: str) -> Target:
        target = parse_question(question)
        if self.reader is not None and self.reading == "model":
            target = self.reader.read(question)
        elif self.reader is not None and self.reading == "rules+rooms" and not target.rooms:
            # the likely rooms act only where the question names none: no call otherwise
            target = replace(target, likely_rooms=self.reader.read(question).likely_rooms)
        if self.resolver is not None and self.matching == "meaning":
            target = replace(target, aliases=self.resolver.aliases(target, self.vocabulary))
        if self.adjacency is not None and target.room is not None:
            target = replace(target, near_rooms=self.adjacency.near(target.room))
        return target
