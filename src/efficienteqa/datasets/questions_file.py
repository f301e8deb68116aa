"""Your own questions: a JSON Lines file, one question a line, for ``eval`` and ``ask --episode``.

::

    {"question": "What colour is the sofa?", "answer": "blue", "scene": "recorded:walk.mcap"}
    {"question": "Is the stove on?", "scene": "recorded:walk.mcap", "id": "stove"}

``question`` and ``scene`` are needed (any scene ``ask --scene`` takes: a recorded walk, a
synthetic house); ``answer`` (the reference, graded by the judge; without it the episode is run
and not graded), ``alternatives`` (other right answers), ``id`` (default: the file's name and
the row, "questions/000") and ``category`` (default "open") are optional. A recording's path is
read relative to the questions file's folder unless it is absolute.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.errors import EfficientEQAError

FIX = ('one JSON object a line: {"question": "...", "scene": "recorded:walk.mcap", '
       '"answer": "..."} (answer optional)')


def is_questions_file(name: str) -> bool:
    return name.strip().lower().endswith(".jsonl")


def _scene(scene: str, folder: Path) -> str:
    """A recording's path relative to the questions file's folder (kept relative when the
    file's own path was)."""
    kind, _, rest = scene.partition(":")
    if kind != "recorded" or not rest or os.path.isabs(rest):
        return scene
    return f"recorded:{os.path.normpath(folder / rest)}"


def load_questions_file(path: Path) -> list[EvalQuestion]:
    if not path.is_file():
        raise EfficientEQAError(f"questions file {path} does not exist",
                                fix="give a .jsonl file of questions, " + FIX)
    questions: list[EvalQuestion] = []
    ids: set[str] = set()
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        where = f"{path} line {n}"
        try:
            row: Any = json.loads(line)
        except ValueError as error:
            raise EfficientEQAError(f"{where} is not JSON: {error}", fix=FIX) from None
        if not isinstance(row, dict) or not isinstance(row.get("question"), str) \
                or not row["question"].strip() or not isinstance(row.get("scene"), str):
            raise EfficientEQAError(f"{where} needs a question and a scene", fix=FIX)
        qid = str(row.get("id") or f"{path.stem}/{len(questions):03d}")
        if qid in ids:
            raise EfficientEQAError(f"{where}: id {qid!r} is used twice",
                                    fix="give each question its own id")
        ids.add(qid)
        alternatives = row.get("alternatives") or ()
        questions.append(EvalQuestion(
            id=qid, dataset=str(path), scene=_scene(row["scene"], path.parent),
            question=row["question"].strip(), answer=str(row.get("answer") or ""),
            category=str(row.get("category") or "open"),
            alternatives=tuple(str(a) for a in alternatives)))
    if not questions:
        raise EfficientEQAError(f"{path} holds no question", fix=FIX)
    return questions
