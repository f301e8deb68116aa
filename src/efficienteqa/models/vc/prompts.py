"""Prompt templates: package text files under ``models/prompts``."""

from __future__ import annotations

import functools
import re
from importlib import resources


@functools.cache
def load_prompt(name: str) -> str:
    """The prompt template ``prompts/<name>.txt`` (package data)."""
    return (resources.files("efficienteqa.models") / "prompts" / f"{name}.txt").read_text("utf-8")


# One worked example per question form, in the reply format: small models copy the kind of
# answer in the example (a place for "where", a number for "how many") more than they follow
# an instruction. The examples are about objects no synthetic question asks about.
_EXAMPLES = (
    (r"^how many\b", "How many cups are on the table?", ("2; 60", "3; 30", "1; 10")),
    (r"^what colou?r\b", "What colour is the rug in the hallway?", ("red; 60", "brown; 30",
                                                                      "beige; 10")),
    (r"^where\b", "Where is the kettle?", ("in the kitchen; 70", "in the dining room; 20",
                                           "in the hallway; 10")),
    (r"^(is|are|was|were|does|do|did|can|could|has|have)\b", "Is the window in the kitchen open?",
     ("yes; 70", "no; 30")),
    (r".", "What is on the shelf in the office?", ("a book; 60", "a vase; 30", "a plant; 10")),
)


def answer_example(question: str) -> str:
    """A worked example of the reply for a question of the same form as ``question``."""
    q = question.strip().lower()
    for pattern, example, lines in _EXAMPLES:
        if re.search(pattern, q):
            return f'Example, for "{example}":\n' + "\n".join(lines)
    raise AssertionError("the last pattern matches every question")
