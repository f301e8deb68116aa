"""Evaluation datasets by name: every one is read into a list of ``EvalQuestion``.

- ``synthetic`` (``synthetic-v1``): the fixed, versioned split of synthetic houses (package
  data, instant), checked against its manifest (``splits``).
- ``synthetic-test`` (``synthetic-test-v1``): the held-out test split (houses 5000-5039), never
  used for tuning; checked the same way.
- ``synthetic-paraphrase``: the split's first 48 questions (the main table) re-phrased by hand
  the way people speak; same episodes and references, pairs with ``synthetic`` by id.
- ``synthetic:SEEDS``: the questions of any houses ("synthetic:3", "synthetic:0-9",
  "synthetic:1,4,7"), generated live once and cached.
- ``hm-eqa``: ExploreEQA's HM-EQA questions (open-vocabulary; ``closed_set`` for the A-D mode).
- ``FILE.jsonl``: your own questions, each with its scene (e.g. a recorded walk;
  ``questions_file``).
"""

from __future__ import annotations

from pathlib import Path

from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS
from efficienteqa.errors import EfficientEQAError

DATASETS = {
    "synthetic": "the fixed, versioned synthetic split (package data; seeds 100 and up); "
                 "also synthetic-v1",
    "synthetic-test": "the held-out test split (seeds 5000-5039; never tune on it); also "
                      "synthetic-test-v1",
    "synthetic-paraphrase": "the main table's 48 questions re-phrased by hand (same episodes)",
    "synthetic:SEEDS": "live questions of any houses: synthetic:3, synthetic:0-9, synthetic:1,4,7",
    "hm-eqa": "HM-EQA (500 questions on HM3D; needs the Habitat back-end to run)",
    "FILE.jsonl": "your own questions, one JSON line each: question, scene (recorded:WALK.mcap), "
                  "answer (optional)",
}
_FIX = ("use one of: synthetic, synthetic-test, synthetic-paraphrase, synthetic:3, synthetic:0-9, "
        "synthetic:1,4,7, hm-eqa, or a FILE.jsonl of questions")

# The frozen splits' names and aliases (``splits.SPLITS``, ``splits.ALIASES``; a test keeps
# them equal without importing the splits here).
_FROZEN = ("synthetic", "synthetic-v1", "synthetic-test", "synthetic-test-v1")

__all__ = ["DATASETS", "EvalQuestion", "find_question", "load_dataset"]


def load_dataset(name: str, *, path: Path | None = None, limit: int | None = None,
                 closed_set: bool = False, assets: str = DEFAULT_ASSETS) -> list[EvalQuestion]:
    """The questions of dataset ``name`` in its own order; ``limit`` keeps the first N (the
    synthetic orders interleave categories and houses, so a prefix stays balanced).

    ``path``: the HM-EQA folder (else ``$EFFICIENTEQA_HM_EQA``, else a cached download).
    ``closed_set``: HM-EQA's four-choice mode. ``assets``: the synthetic furniture ("sh3d", or
    "builtin" boxes for live seeds; the fixed split exists for "sh3d" only).
    """
    if limit is not None and limit < 0:
        raise EfficientEQAError(f"limit must be >= 0, got {limit}", fix="pass --eval.limit N with N >= 0")
    kind, colon, arg = name.strip().partition(":")
    from efficienteqa.datasets.questions_file import is_questions_file, load_questions_file

    if is_questions_file(name):
        if closed_set:
            raise EfficientEQAError(f"dataset {name!r} has no closed-set mode", fix="use hm-eqa")
        questions = load_questions_file(Path(name.strip()))
        return questions if limit is None else questions[:limit]
    if closed_set and kind != "hm-eqa":
        raise EfficientEQAError(f"dataset {name!r} has no closed-set mode", fix="use hm-eqa")
    if kind == "hm-eqa" and not colon:
        from efficienteqa.datasets.hm_eqa import load_hm_eqa

        questions = load_hm_eqa(path, closed_set=closed_set)
    elif kind in _FROZEN and not colon:
        from efficienteqa.datasets import splits, synthetic

        if assets != synthetic.SPLIT_ASSETS:
            raise EfficientEQAError(f"the synthetic split is defined for assets "
                                    f"{synthetic.SPLIT_ASSETS!r}, not {assets!r}",
                                    fix="use synthetic:SEEDS with these assets")
        questions = splits.load_frozen(kind)
    elif kind == "synthetic-paraphrase" and not colon:
        from efficienteqa.datasets import synthetic

        if assets != synthetic.SPLIT_ASSETS:
            raise EfficientEQAError(f"the paraphrase split is defined for assets "
                                    f"{synthetic.SPLIT_ASSETS!r}, not {assets!r}",
                                    fix=f"use --assets {synthetic.SPLIT_ASSETS}")
        questions = synthetic.load_paraphrase_split()
    elif kind == "synthetic":
        from efficienteqa.datasets import synthetic

        try:
            seeds = synthetic.parse_seeds(arg)
        except ValueError as error:
            if "houses" in str(error):
                raise EfficientEQAError(
                    f"dataset {name!r} names {error}: every house is generated before the "
                    "questions are picked", fix=f"name at most {synthetic.MAX_SEEDS} seeds, "
                    "e.g. synthetic:2000-2099 --eval.limit 50") from None
            raise EfficientEQAError(f"dataset {name!r}: {arg!r} is not a list of seeds",
                                    fix=_FIX) from None
        questions = synthetic.load_seeds(seeds, assets)
    else:
        raise EfficientEQAError(f"unknown dataset {name!r}", fix=_FIX)
    return questions if limit is None else questions[:limit]


def find_question(questions: list[EvalQuestion], key: str) -> EvalQuestion:
    """The question with id ``key`` ("hm-eqa/012"), or at row ``key`` of the list ("12")."""
    by_id = {q.id: q for q in questions}
    if key in by_id:
        return by_id[key]
    if key.isdigit() and int(key) < len(questions):
        return questions[int(key)]
    example = questions[0].id if questions else "an id"
    raise EfficientEQAError(f"no question {key!r} in the dataset ({len(questions)} questions)",
                            fix=f"give an id such as {example}, or a row number below {len(questions)}")
