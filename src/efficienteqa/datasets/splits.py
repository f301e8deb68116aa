"""The frozen synthetic splits by name, each fixed by its checksummed manifest.

=================================  ==================================  ============================
name (alias)                       houses                              use
=================================  ==================================  ============================
``synthetic-v1`` (``synthetic``)   30 houses, seeds 100-129            the main table (its first
                                                                       48 questions) and studies
``synthetic-test-v1``              houses of seeds 5000-5039           the held-out test split:
(``synthetic-test``)                                                   reported, never tuned on
=================================  ==================================  ============================

A frozen split never changes. Its manifest's sha256 is written here (``FrozenSplit.sha256``);
loading a split checks its manifest against that digest and every question of its file
against the manifest (a file read and a hash: milliseconds). A new generator, whose houses or
questions no longer reproduce (``efficienteqa scenes verify`` says so), makes a new version,
``synthetic-v2``: a new file, manifest and digest beside the old ones, never an edit of them.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from importlib import resources
from typing import Any

from efficienteqa.datasets import synthetic
from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.errors import EfficientEQAError

MANIFEST_DIR = "manifests"
NEW_VERSION = ("build a new version (synthetic-v2, synthetic-test-v2) with "
               "scripts/make_synthetic_split.py --split; a frozen split is never edited")


@dataclass(frozen=True)
class FrozenSplit:
    """A split: its package file, its manifest's name and the manifest's committed sha256."""

    name: str
    file: str
    sha256: str
    use: str

    @property
    def manifest(self) -> str:
        return f"{self.name}.json"


SPLITS = {s.name: s for s in (
    FrozenSplit(synthetic.SPLIT_DATASET, synthetic.SPLIT_FILE,
                "6d736be434c61bad13791520f8e5f4bf7b03aac6250493ded0a00071b8258161",
                "the main table's split (its first 48 questions) and the studies'; houses "
                "100-129"),
    FrozenSplit(synthetic.TEST_DATASET, synthetic.TEST_FILE,
                "c42625e0e9fd8c870b51eef66a88c415ad25cf154db922de8e3ef192d0e04caf",
                "the held-out test split, houses 5000-5039: report on it, never tune or choose "
                "anything on it"),
)}
ALIASES = {"synthetic": synthetic.SPLIT_DATASET, "synthetic-test": synthetic.TEST_DATASET}


def sha256_of(value: Any) -> str:
    """The sha256 of ``value`` as canonical JSON (keys sorted, no spaces, UTF-8)."""
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def manifest_sha256(manifest: dict[str, Any]) -> str:
    """The sha256 over everything in ``manifest`` but its ``sha256``."""
    return sha256_of({k: v for k, v in manifest.items() if k != "sha256"})


def question_entry(q: EvalQuestion) -> dict[str, Any]:
    """What the manifest fixes of a question (as JSON gives it back: lists, not tuples)."""
    pose = q.source.get("oracle_pose")
    return {"id": q.id, "house_seed": synthetic.house_of(q), "category": q.category,
            "question": q.question, "answer": q.answer, "alternatives": list(q.alternatives),
            "accepted": list(q.accepted), "evidence": list(q.source.get("evidence") or []),
            "oracle_steps": q.oracle_steps, "oracle_pose": list(pose) if pose else None}


def frozen_split(name: str) -> FrozenSplit:
    """The split named ``name`` or by its alias ("synthetic-test")."""
    split = SPLITS.get(ALIASES.get(name, name))
    if split is None:
        raise EfficientEQAError(f"no frozen split {name!r}",
                                fix=f"use one of {', '.join([*ALIASES, *SPLITS])}")
    return split


def packaged_manifest(split: FrozenSplit) -> dict[str, Any]:
    """The split's manifest as the package holds it (not yet checked)."""
    node = resources.files("efficienteqa.datasets").joinpath(MANIFEST_DIR).joinpath(split.manifest)
    try:
        data = json.loads(node.read_text())
    except FileNotFoundError:
        raise EfficientEQAError(f"the package file {MANIFEST_DIR}/{split.manifest} is missing",
                                fix="reinstall efficienteqa (package data must include "
                                    "manifests/*.json)") from None
    except ValueError as error:
        raise EfficientEQAError(f"{MANIFEST_DIR}/{split.manifest} is not JSON: {error}",
                                fix=NEW_VERSION) from None
    if not isinstance(data, dict):
        raise EfficientEQAError(f"{MANIFEST_DIR}/{split.manifest} is not a manifest",
                                fix=NEW_VERSION)
    return data


def integrity_problems(split: FrozenSplit, manifest: dict[str, Any]) -> list[str]:
    """Why ``manifest`` is not the split's committed one: its sha256 does not cover its
    content, or is not the digest written in ``SPLITS``."""
    problems = []
    own = manifest_sha256(manifest)
    if manifest.get("split") != split.name:
        problems.append(f"the manifest is {manifest.get('split')!r}'s, not {split.name}'s")
    if manifest.get("sha256") != own:
        problems.append(f"{split.name}: the manifest's content hashes to {own}, not to the "
                        f"sha256 it states ({manifest.get('sha256')}): it was edited")
    elif own != split.sha256:
        problems.append(f"{split.name}: the manifest's sha256 {own} is not the committed "
                        f"{split.sha256}: a frozen split changed")
    return problems


def row_problems(split: FrozenSplit, manifest: dict[str, Any],
                 questions: list[EvalQuestion]) -> list[str]:
    """Where the split file's questions differ from the manifest's (in order, field by field)."""
    fixed = manifest.get("questions") or []
    problems = []
    if len(fixed) != len(questions):
        problems.append(f"{split.file} holds {len(questions)} questions, the manifest "
                        f"{len(fixed)}")
    for n, (q, entry) in enumerate(zip(questions, fixed), 1):
        row = question_entry(q)
        changed = sorted(k for k in {*row, *entry} if row.get(k) != entry.get(k))
        if changed:
            problems.append(f"{split.file} question {n} ({q.id}): {', '.join(changed)} "
                            "differ from the manifest")
    return problems


def load_frozen(name: str) -> list[EvalQuestion]:
    """The questions of a frozen split in its order, after checking its manifest is the
    committed one and fixes every question of the file; one line on the first problem."""
    split = frozen_split(name)
    manifest = packaged_manifest(split)
    questions = synthetic.load_split(split.file)
    problems = integrity_problems(split, manifest) or row_problems(split, manifest, questions)
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise EfficientEQAError(problems[0] + more, fix=NEW_VERSION)
    return questions
