"""Your own questions: a JSON Lines file, one question a line, for ``eval`` and ``ask --episode``.

::

    {"question": "What colour is the sofa?", "answer": "blue", "scene": "recorded:walk.mcap"}
    {"question": "Is the stove on?", "scene": "recorded:walk.mcap", "id": "stove"}

``question`` and ``scene`` are needed (any scene ``ask --scene`` takes: a recorded walk, a
synthetic house); ``answer`` (the reference, graded by the judge; without it the episode is run
and not graded), ``alternatives`` (other right answers), ``id`` (default: the file's name and
the row, "questions/000"; it names the episode's folder, so it is refused when it cannot: ``.``,
``..``, a control character, over ``MAX_ID_BYTES``), ``category`` (default "open") and
``accepted`` (the answers the rule judge accepts, as the synthetic questions and ``scenes
export-walks`` carry them; with them, and a category of the synthetic questions, the exact rule
judge grades too, beside LLM-Match or alone with ``--eval.judge none``) are optional. A
recording's path is read relative to the questions file's folder unless it is absolute. A line
that cannot be read is one error naming the file and the line, before any episode.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.errors import EfficientEQAError
from efficienteqa.records import read_json

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


# An id names its episode's folder (``eval.runner.episode_folder``: "/" becomes "__"): it must
# be a name a file system takes, inside the run's folder.
MAX_ID_BYTES = 200


def _id_problem(qid: str) -> str | None:
    """Why ``qid`` cannot name an episode's folder, or None."""
    if qid in (".", ".."):
        return "names no folder of its own (it is . or ..)"
    if any(ord(c) < 32 or ord(c) == 127 for c in qid):
        return "holds a control character"
    size = len(qid.replace("/", "__").encode("utf-8", "surrogatepass"))
    if size > MAX_ID_BYTES:
        return f"is {size} bytes long, over {MAX_ID_BYTES}"
    return None


def _alternatives(value: Any) -> tuple[str, ...] | None:
    """The other right answers a row gives (a list of answers, or one), None when it gives
    something else."""
    if value is None:
        return ()
    if isinstance(value, str):
        return (value,) if value.strip() else ()
    if isinstance(value, list) and all(isinstance(a, (str, int, float)) and not isinstance(a, bool)
                                       for a in value):
        return tuple(str(a) for a in value)
    return None


def _kind(value: Any) -> str:
    """What a JSON value is, in a few words (a scalar as itself)."""
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, list):
        return "a list"
    return json.dumps(value)[:40]


def _lines(path: Path) -> list[bytes]:
    try:
        return path.read_bytes().splitlines()
    except OSError as error:
        raise EfficientEQAError(f"cannot read the questions file {path}: "
                                f"{error.strerror or error}", fix="check its path and rights") from None


def load_questions_file(path: Path) -> list[EvalQuestion]:
    """The questions of ``path``; one ``EfficientEQAError`` naming the file and the line for a
    line that is not UTF-8, not JSON (or nested too deep), or holds a row that cannot be run,
    before any episode."""
    if not path.is_file():
        raise EfficientEQAError(f"questions file {path} does not exist",
                                fix="give a .jsonl file of questions, " + FIX)
    questions: list[EvalQuestion] = []
    ids: set[str] = set()
    for n, raw in enumerate(_lines(path), 1):
        where = f"{path} line {n}"
        try:
            line = raw.decode("utf-8")
        except UnicodeDecodeError as error:
            raise EfficientEQAError(f"{where} is not UTF-8 text (byte {error.start + 1}: "
                                    f"{raw[error.start:error.start + 4]!r})",
                                    fix="save the file as UTF-8") from None
        if not line.strip():
            continue
        try:
            row: Any = read_json(line)
        except ValueError as error:
            raise EfficientEQAError(f"{where} is not JSON: {error}", fix=FIX) from None
        if not isinstance(row, dict) or not isinstance(row.get("question"), str) \
                or not row["question"].strip() or not isinstance(row.get("scene"), str):
            raise EfficientEQAError(f"{where} needs a question and a scene", fix=FIX)
        given = row.get("id")
        if isinstance(given, bool) or not isinstance(given, (str, int, type(None))):
            raise EfficientEQAError(f"{where}: id is {_kind(given)}, not text",
                                    fix='write e.g. "id": "sofa-colour"')
        qid = str(given or f"{path.stem}/{len(questions):03d}")
        why = _id_problem(qid)
        if why is not None:
            raise EfficientEQAError(f"{where}: id {qid[:60]!r} {why}",
                                    fix="give an id of letters, digits and punctuation, at most "
                                        f"{MAX_ID_BYTES} bytes")
        if qid in ids:
            raise EfficientEQAError(f"{where}: id {qid!r} is used twice",
                                    fix="give each question its own id")
        ids.add(qid)
        alternatives = _alternatives(row.get("alternatives"))
        if alternatives is None:
            given = row["alternatives"]
            said = ("holds something other than answers" if isinstance(given, list)
                    else f"is {_kind(given)}, not a list of answers")
            raise EfficientEQAError(f"{where}: alternatives {said}",
                                    fix='write e.g. "alternatives": ["navy", "dark blue"]')
        accepted = _alternatives(row.get("accepted"))
        if accepted is None:
            raise EfficientEQAError(f"{where}: accepted is {_kind(row['accepted'])}, not a list "
                                    "of answers", fix='write e.g. "accepted": ["blue", "navy"]')
        questions.append(EvalQuestion(
            id=qid, dataset=str(path), scene=_scene(row["scene"], path.parent),
            question=row["question"].strip(), answer=str(row.get("answer") or ""),
            category=str(row.get("category") or "open"), alternatives=alternatives,
            accepted=accepted))
    if not questions:
        raise EfficientEQAError(f"{path} holds no question", fix=FIX)
    return questions
