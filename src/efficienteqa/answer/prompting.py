"""How the answer prompts are built: the worked example and the one-line hint for the question's
form, and the evidence as prompt text (or images to attach).

Apart from the model calls (``answer.calls``) because these are the words a model is given, not
how its reply is read; the blind answer (``answer.blind``) and the evaluation's replays
(``eval.replay``) use them as well.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

PROMPTS = "efficienteqa.answer"  # answer/prompts/*.txt

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
    # The catch-all: "" matches every question, the empty one too ("." did not, and an empty
    # question reached the assertion below).
    (r"", "What is on the shelf in the office?", ("a book; 60", "a vase; 30", "a plant; 10")),
)


# The direct answer's one-line hint per question form (first match wins; none for other forms).
# Written on training houses 0-3 from the wrong answers of the other answer prompts: a small
# model answers a "where" with a direction, counts repeated lines as one, and names the furniture
# when asked what stands on it.
_HINTS = (
    (r"^how many\b", "A number word before that object is its count (\"three chairs\" is 3, "
                     "\"a chair\" is 1); add up the entries in that place. Answer with one "
                     "number."),
    (r"^what colou?r\b", "Answer with the colour word written just before that object's name."),
    (r"^where\b", "Answer with the room the object is in: the room named after it, or else the "
                  "room the robot is in. Not a direction."),
    (r"^is there\b", "Answer yes only if an object of that kind is listed in that room; "
                     "otherwise no."),
    (r"^(is|are)\b", "Answer yes or no from the state in brackets after that object: (on) or "
                     "(open) means yes, (off) or (closed) means no."),
    (r"^what is on\b", "Find \"on the\" or \"in the\" and that furniture in what it saw, and "
                       "answer with the object written just before those words, never the "
                       "furniture itself."),
)


# The same hints for a VLM that reads the retrieved frames as images: nothing about entries,
# brackets or words written before a name, which only the text descriptions have.
_IMAGE_HINTS = (
    (r"^how many\b", "Count that object in the images, each one once: the same object may "
                     "appear in more than one image. Answer with one number."),
    (r"^what colou?r\b", "Answer with the colour of that object as the images show it."),
    (r"^where\b", "Answer with the room the object is in (such as the kitchen or a bedroom). "
                  "Not a direction."),
    (r"^is there\b", "Answer yes only if the images show an object of that kind in that room; "
                     "otherwise no."),
    (r"^(is|are)\b", "Answer yes or no from what the images show: a lamp or screen that is lit, "
                     "or a door that stands open, means yes."),
    (r"^what is on\b", "Name the object standing on that furniture in the images, never the "
                       "furniture itself."),
)


def question_hint(question: str, modality: str = "text") -> str:
    """The direct answer's hint for the form of ``question`` ("" when no form matches), written
    for the evidence's ``modality``: "text" (frame descriptions) or "image" (RGB frames)."""
    q = question.strip().lower()
    hints = _IMAGE_HINTS if modality == "image" else _HINTS
    return next((hint for pattern, hint in hints if re.search(pattern, q)), "")


def answer_example(question: str) -> str:
    """A worked example of the reply for a question of the same form as ``question``."""
    q = question.strip().lower()
    for pattern, example, lines in _EXAMPLES:
        if re.search(pattern, q):
            return f'Example, for "{example}":\n' + "\n".join(lines)
    raise AssertionError("the last pattern matches every question")


def evidence_text(evidence: Sequence[str | np.ndarray]) -> tuple[str, tuple[np.ndarray, ...]]:
    """The evidence as prompt text, and the images to attach (for VLMs)."""
    items = list(evidence)
    if items and all(isinstance(e, str) for e in items):
        return "\n".join(f"view {i + 1}: {e}" for i, e in enumerate(items)), ()
    images = tuple(e for e in items if isinstance(e, np.ndarray))
    if not images:
        return "nothing", images
    return ("the attached image" if len(images) == 1 else f"the {len(images)} attached images"), images

