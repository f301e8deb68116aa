"""HM-EQA (ExploreEQA's 500 questions on HM3D scenes), read from its two published csv files.

The files are third-party data: they are never copied into this repository. They come from an
explicit folder, ``$EFFICIENTEQA_HM_EQA``, or are downloaded once (pinned to one commit and
checked against its digest) into ``cache_dir("datasets", "hm-eqa")``.

Open-vocabulary mode (the paper's): the ground truth is the text of the answer letter's choice;
the one row whose answer is the filler "(Do not choose this option)" (row 161) has no usable
answer and is left out, so 499 questions. No choices are attached, so no method can peek at them.

Closed-set mode: every row with a valid letter is kept, row 161 included (500 questions), because
ExploreEQA's published closed-set numbers are over all 500; it is flagged with
``source["filler_answer"] = True`` so that a runner can leave it out or report it apart.
``choices`` holds the four texts in letter order (fillers included, so letters keep their places).
"""

from __future__ import annotations

import ast
import csv
import hashlib
import logging
import math
import os
from pathlib import Path
from typing import Any

import httpx

from efficienteqa.cache import cache_dir
from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.errors import EfficientEQAError
from efficienteqa.vc.parse import CHOICE_LETTERS as LETTERS

log = logging.getLogger(__name__)

NAME = "hm-eqa"
QUESTIONS_CSV = "questions.csv"
POSES_CSV = "scene_init_poses.csv"
ENV_VAR = "EFFICIENTEQA_HM_EQA"
FILLER = "(Do not choose this option)"
# Stanford-ILIAD/explore-eqa, the commit the files were published at (18381da).
COMMIT = "18381da3370c5f7729594f10ebc49b5644bbb88c"
URL = "https://raw.githubusercontent.com/Stanford-ILIAD/explore-eqa/{commit}/data/{name}"
# sha256 of each file with CRLF line ends read as LF: a pinned download must match it exactly.
DIGESTS = {
    QUESTIONS_CSV: "78c5e24f9d0e60971ae0cff69e342a9df0d5781bf375f499dca8e46ca21561e6",
    POSES_CSV: "471662647a8b3e12f261574b8863de9299043c17090159d551156f8778782757",
}
QUESTION_COLUMNS = ("scene", "floor", "question", "choices", "answer", "label")
POSE_COLUMNS = ("scene_floor", "init_x", "init_y", "init_z", "init_angle")
FIX_MALFORMED = "use the published file (delete a cached copy to download it again)"
FIX_PATH = f"pass --eval.hm-eqa-path FOLDER (holding {QUESTIONS_CSV} and {POSES_CSV}) or set {ENV_VAR}"


def load_hm_eqa(path: Path | None = None, *, closed_set: bool = False) -> list[EvalQuestion]:
    """The HM-EQA questions in csv row order, ids ``hm-eqa/NNN`` (the csv row index)."""
    folder = resolve_folder(path)
    poses = read_poses(folder / POSES_CSV)
    questions = read_questions(folder / QUESTIONS_CSV, poses, closed_set=closed_set)
    missing = [q.id for q in questions if q.source["habitat_position"] is None]
    if missing:  # the scene's own start is a fallback the Habitat adapter decides on
        log.warning("%d of %d HM-EQA questions have no start pose in %s (e.g. %s)",
                    len(missing), len(questions), folder / POSES_CSV, ", ".join(missing[:3]))
    return questions


def resolve_folder(path: Path | None = None) -> Path:
    """An explicit folder, else ``$EFFICIENTEQA_HM_EQA``, else the cache (downloading there)."""
    if path is not None:
        return _check_folder(Path(path), "--eval.hm-eqa-path")
    if os.environ.get(ENV_VAR):
        return _check_folder(Path(os.environ[ENV_VAR]), ENV_VAR)
    folder = cache_dir("datasets", NAME)
    download(folder)
    return folder


def _check_folder(folder: Path, given_by: str) -> Path:
    missing = [name for name in (QUESTIONS_CSV, POSES_CSV) if not (folder / name).is_file()]
    if missing:
        raise EfficientEQAError(f"HM-EQA folder {folder} (from {given_by}) lacks {', '.join(missing)}",
                                fix=FIX_PATH)
    return folder


def _http_client() -> httpx.Client:
    """One place to build the client, so tests can hand in a fake transport."""
    return httpx.Client(timeout=30.0, follow_redirects=True)


def download(folder: Path) -> None:
    """Fetch whichever of the two files ``folder`` lacks; each appears complete or not at all."""
    wanted = [name for name in (QUESTIONS_CSV, POSES_CSV) if not (folder / name).is_file()]
    if not wanted:
        return
    with _http_client() as client:
        for name in wanted:
            url = URL.format(commit=COMMIT, name=name)
            log.info("downloading %s", url)
            try:
                response = client.get(url)
                response.raise_for_status()
            except httpx.HTTPError as exc:
                reason = (str(exc).splitlines() or [type(exc).__name__])[0]
                raise EfficientEQAError(f"HM-EQA download failed: {url}: {reason}",
                                        fix=FIX_PATH) from None
            data = response.content
            digest = hashlib.sha256(data.replace(b"\r\n", b"\n")).hexdigest()
            if digest != DIGESTS[name]:
                raise EfficientEQAError(f"HM-EQA download of {url} is not the published file "
                                        f"(sha256 {digest[:12]}..., expected {DIGESTS[name][:12]}...)",
                                        fix=FIX_PATH)
            tmp = folder / f".{name}.{os.getpid()}.tmp"
            tmp.write_bytes(data)
            os.replace(tmp, folder / name)


def _rows(path: Path, columns: tuple[str, ...]) -> list[tuple[str, int, dict[str, str]]]:
    """(where, row index, row): ``where`` names file, row and line for error messages."""
    with open(path, newline="", encoding="utf-8-sig") as f:
        reader = csv.DictReader(f)
        try:
            absent = [c for c in columns if c not in (reader.fieldnames or [])]
            if absent:
                raise EfficientEQAError(f"{path}: missing column(s) {', '.join(absent)}",
                                        fix=f"the header must name {', '.join(columns)}")
            return [(f"{path}: row {i} (line {reader.line_num})", i, row)
                    for i, row in enumerate(reader)]
        except UnicodeDecodeError as error:
            raise EfficientEQAError(f"{path}: not UTF-8 text (byte {error.start})",
                                    fix=FIX_MALFORMED) from None
        except csv.Error as error:  # e.g. a field over csv's size limit, a stray NUL
            raise EfficientEQAError(f"{path}: line {reader.line_num}: {error}",
                                    fix=FIX_MALFORMED) from None


# How much of a bad field an error line quotes (a choices field nested 5,000 deep made a line of
# over 3 kB).
SHOWN = 80


def _shown(value: object) -> str:
    """``value``'s repr for an error line, cut to ``SHOWN`` characters."""
    text = repr(value)
    return text if len(text) <= SHOWN else f"{text[:SHOWN]}... ({len(text)} characters)"


def _bad(where: str, what: str) -> EfficientEQAError:
    return EfficientEQAError(f"{where}: {what}", fix=FIX_MALFORMED)


def read_poses(path: Path) -> dict[str, dict[str, Any]]:
    """``{"<scene>_<floor>": {"habitat_position": [x, y, z], "habitat_yaw": rad}}`` (y up)."""
    poses: dict[str, dict[str, Any]] = {}
    for where, _, row in _rows(path, POSE_COLUMNS):
        try:
            x, y, z, yaw = (float(row[c]) for c in POSE_COLUMNS[1:])
        except (TypeError, ValueError):
            raise _bad(where, "init_x/init_y/init_z/init_angle must be numbers") from None
        if not all(math.isfinite(v) for v in (x, y, z, yaw)):
            raise _bad(where, "pose is not finite")
        poses[row["scene_floor"]] = {"habitat_position": [x, y, z], "habitat_yaw": yaw}
    return poses


def read_questions(path: Path, poses: dict[str, dict[str, Any]], *, closed_set: bool = False
                   ) -> list[EvalQuestion]:
    """Rows of ``questions.csv`` as EvalQuestions (see the module docstring for the two modes)."""
    out = []
    for where, index, row in _rows(path, QUESTION_COLUMNS):
        question = (row["question"] or "").strip()
        scene = (row["scene"] or "").strip()
        if not question or not scene:
            raise _bad(where, "empty scene or question")
        try:
            choices = ast.literal_eval(row["choices"] or "")
        except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
            raise _bad(where, f"choices is not a Python list literal: {_shown(row['choices'])}") from None
        if not (isinstance(choices, list | tuple) and choices and len(choices) <= len(LETTERS)
                and all(isinstance(c, str) for c in choices)):
            raise _bad(where, f"choices must be a list of strings: {_shown(row['choices'])}")
        letter = (row["answer"] or "").strip().upper()
        if len(letter) != 1 or letter not in LETTERS[: len(choices)]:
            raise _bad(where, f"answer {_shown(row['answer'])} is not one of "
                                    f"{', '.join(LETTERS[: len(choices)])}")
        answer = choices[LETTERS.index(letter)].strip()
        filler = answer == FILLER
        if filler and not closed_set:
            continue  # no open-vocabulary ground truth (row 161)
        floor = (row["floor"] or "").strip()
        key = f"{scene}_{floor}"
        pose = poses.get(key, {"habitat_position": None, "habitat_yaw": None})
        source: dict[str, Any] = {"floor": int(floor) if floor.isdigit() else floor,
                                  "scene_floor": key, **pose, "letter": letter}
        if closed_set:
            source["filler_answer"] = filler
        out.append(EvalQuestion(
            id=f"{NAME}/{index:03d}", dataset=NAME, scene=f"hm3d:{scene}", question=question,
            answer=answer, category=(row["label"] or "").strip(),
            choices=tuple(c.strip() for c in choices) if closed_set else (), source=source))
    return out
