"""Synthetic-house questions: the fixed, versioned split and live generation for any seeds.

The split ``synthetic`` v1 is package data (``synthetic_v1.jsonl``), built once by
``scripts/make_synthetic_split.py``: a header line (``format``, ``version``, ``generator``
version, ``seeds`` used, ``house_sizes``, ``category_counts``, the ``selection`` rule) followed by
one ``EvalQuestion.to_dict()`` per line, in interleaved order (categories in turn, houses spread).
"No" existence questions have no evidence and no oracle steps; ``source["no_evidence"]`` says so.
Loading it is a file read; rendering houses happens only in the runner, which calls
``check_question`` to make sure the generator still produces each question (a split is only
meaningful while it does).

The split ``synthetic-paraphrase`` v1 (``synthetic_paraphrase_v1.jsonl``, written by hand) asks
the main table's questions (the split's first 48) the way people speak: everyday synonyms,
conversational openings, typos, relations to nearby things. Each row keeps its original's id,
house, start, references and evidence (checked against the split on loading), so a run pairs
with the original's by id; ``source["original"]`` holds the original's id and wording (which
``check_question`` looks up), ``source["paraphrase_style"]`` the kind of re-phrasing.

The split ``synthetic-test`` v1 (``synthetic_test_v1.jsonl``) is the held-out test split, built
the same way on houses of seeds 5000-5039 (``TEST_SEEDS`` reserves 5000-5999): never used for
tuning or for choosing anything, only for reporting. Both frozen splits are fixed by a
checksummed manifest (``datasets.splits``).

Seed ranges: 0-20 belong to development benchmarks and >= 1000 to calibration, so the split
draws from 100-999; 2000-2999 are held out for studies, 3000-3999 are perception's own.
``synthetic:SEEDS`` generates any houses live (about 5 s each) and caches
their questions per seed, keyed by a digest of the generator's source.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import replace
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from efficienteqa.cache import cache_dir
from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS
from efficienteqa.envs.synthetic.questions import CATEGORIES, Question
from efficienteqa.errors import EfficientEQAError

if TYPE_CHECKING:
    from efficienteqa.scenes import Scene

log = logging.getLogger(__name__)

SPLIT_VERSION = "v1"
SPLIT_DATASET = f"synthetic-{SPLIT_VERSION}"
SPLIT_FILE = f"synthetic_{SPLIT_VERSION}.jsonl"
SPLIT_ASSETS = DEFAULT_ASSETS
SPLIT_SEEDS = range(100, 1000)  # 0-20: development benchmarks; >= 1000: calibration
# The held-out test split: houses no experiment, benchmark or calibration has looked at. Never
# tune on them: a number measured here is reported, not acted on.
TEST_VERSION = "v1"
TEST_DATASET = f"synthetic-test-{TEST_VERSION}"
TEST_FILE = f"synthetic_test_{TEST_VERSION}.jsonl"
TEST_SEEDS = range(5000, 6000)
LIVE_DATASET = "synthetic"
HEADER_FORMAT = "efficienteqa-synthetic-split"
PARAPHRASE_DATASET = f"synthetic-paraphrase-{SPLIT_VERSION}"
PARAPHRASE_FILE = f"synthetic_paraphrase_{SPLIT_VERSION}.jsonl"
PARAPHRASE_FORMAT = "efficienteqa-paraphrase-split"
PARAPHRASE_STYLES = ("synonyms", "conversational", "typos", "relations")
_PARAPHRASE_KEYS = frozenset({"original", "paraphrase_style"})  # what a re-phrasing adds to source
REBUILD = "rebuild the split with scripts/make_synthetic_split.py under a new version"
# What decides a house and its questions: the generator, the question rules, the oracle.
_GENERATOR_SOURCES = ("envs/synthetic", "scenes.py", "geometry.py", "mapping/navgrid.py")


def generator_version() -> str:
    """A digest of the generator's source files: live-cache entries from other code are stale."""
    root = resources.files("efficienteqa")
    digest = hashlib.sha256()
    for part in _GENERATOR_SOURCES:
        node = root.joinpath(part)
        files = sorted(node.iterdir(), key=lambda f: f.name) if node.is_dir() else [node]
        for f in files:
            if f.name.endswith(".py"):
                digest.update(f"{part}/{f.name}\0".encode() + f.read_bytes())
    return "gen-" + digest.hexdigest()[:12]


def to_eval_question(q: Question, dataset: str, assets: str) -> EvalQuestion:
    """A generated question as an EvalQuestion, with its accepted answers (the ``rule`` judge's
    key); ``source`` keeps what the oracle knows.

    ``source["no_evidence"]`` marks "no" existence answers: nothing to see, so no oracle steps.
    """
    return EvalQuestion(
        id=f"{dataset}/{q.id}", dataset=dataset, scene=f"synthetic:{q.house_seed}",
        question=q.question, answer=q.answer, category=q.category,
        alternatives=tuple(q.alternatives), accepted=tuple(q.accepted), oracle_steps=q.oracle_steps,
        source={"house_seed": q.house_seed, "question_id": q.id, "assets": assets,
                "evidence": list(q.evidence), "no_evidence": not q.evidence,
                "oracle_pose": list(q.oracle_pose) if q.oracle_pose else None})


# -- ordering and selection --------------------------------------------------------------------
Q = TypeVar("Q", Question, EvalQuestion)


def house_of(q: Question | EvalQuestion) -> int:
    return q.house_seed if isinstance(q, Question) else int(q.source["house_seed"])


def _greedy(pools: dict[str, list[Q]], slots: Iterable[str], max_per_house: int | None = None
            ) -> tuple[list[Q], list[str]]:
    """Fill each slot from its pool with the question whose house has been used least (ties: the
    pool's order). Returns the picks in slot order and the slots that found nothing."""
    used: Counter[int] = Counter()
    picks: list[Q] = []
    unfilled: list[str] = []
    for slot in slots:
        options = [q for q in pools.get(slot, [])
                   if max_per_house is None or used[house_of(q)] < max_per_house]
        if not options:
            unfilled.append(slot)
            continue
        best = min(options, key=lambda q: used[house_of(q)])
        pools[slot].remove(best)
        used[house_of(best)] += 1
        picks.append(best)
    return picks, unfilled


def interleave(questions: Sequence[Q]) -> list[Q]:
    """All ``questions``, categories in turn and houses spread, so any prefix stays balanced."""
    seen = {q.category for q in questions}
    order = [c for c in CATEGORIES if c in seen] + sorted(seen - set(CATEGORIES))
    pools: dict[str, list[Q]] = {c: [] for c in order}
    for q in sorted(questions, key=house_of):  # stable: keeps each house's own order
        pools[q.category].append(q)
    rounds = max((len(p) for p in pools.values()), default=0)
    picks, _ = _greedy(pools, [c for _ in range(rounds) for c in order])
    return picks


def select_split(questions: Sequence[Question], per_category: int, existence_no: int,
                 max_per_house: int) -> list[Question]:
    """The split: ``per_category`` questions of every category, in interleaved order.

    Every question has evidence (hence oracle steps) except ``existence_no`` existence questions
    answered "no", spread evenly over the existence rounds. Deterministic: pools are in seed
    order and ties go to the lower seed.
    """
    pools: dict[str, list[Question]] = {c: [] for c in (*CATEGORIES, "existence:no")}
    for q in sorted(questions, key=lambda q: q.house_seed):
        if q.oracle_steps is not None and q.category in pools:
            pools[q.category].append(q)
        elif q.category == "existence" and not q.evidence:
            pools["existence:no"].append(q)
    slots = []
    for r in range(per_category):
        no_here = (r + 1) * existence_no // per_category > r * existence_no // per_category
        slots += ["existence:no" if c == "existence" and no_here else c for c in CATEGORIES]
    picks, unfilled = _greedy(pools, slots, max_per_house)
    if unfilled:
        raise EfficientEQAError(f"too few candidates for the split: {dict(Counter(unfilled))} unfilled",
                                fix="scan more house seeds")
    return picks


# -- the fixed split ---------------------------------------------------------------------------
def _split_lines(name: str = SPLIT_FILE) -> list[str]:
    try:
        text = resources.files("efficienteqa.datasets").joinpath(name).read_text()
    except FileNotFoundError:
        raise EfficientEQAError(f"the package file {name} is missing",
                                fix="reinstall efficienteqa (package data must include *.jsonl)") from None
    return [line for line in text.splitlines() if line.strip()]


def split_header(file: str = SPLIT_FILE) -> dict[str, Any]:
    """A split's first line: version, generator version, seeds, category counts, selection."""
    header = json.loads(_split_lines(file)[0])
    if header.get("format") != HEADER_FORMAT:
        raise EfficientEQAError(f"{file} has no split header", fix=REBUILD)
    return header


def load_split(file: str = SPLIT_FILE) -> list[EvalQuestion]:
    """A fixed split in its interleaved order (a prefix of any length stays balanced); the
    manifest's checks are ``splits.load_frozen``'s."""
    lines = _split_lines(file)
    return [EvalQuestion.from_dict(json.loads(line)) for line in lines[1:]]


def load_paraphrase_split() -> list[EvalQuestion]:
    """The main table's questions re-phrased by hand, in the split's order (module docstring).

    Fails unless every row is its original but for the wording and the dataset: a re-phrasing
    whose references drifted from the split would be graded against another question.
    """
    lines = _split_lines(PARAPHRASE_FILE)
    header = json.loads(lines[0])
    if header.get("format") != PARAPHRASE_FORMAT or header.get("of") != SPLIT_DATASET:
        raise EfficientEQAError(f"{PARAPHRASE_FILE} does not re-phrase {SPLIT_DATASET}",
                                fix="write the paraphrase split again for the current split")
    originals = {q.id: q for q in load_split()}
    questions = [EvalQuestion.from_dict(json.loads(line)) for line in lines[1:]]
    for q in questions:
        original = originals.get(q.source.get("original", {}).get("id", ""))
        extra = {k: v for k, v in q.source.items() if k not in _PARAPHRASE_KEYS}
        if original is None or original.id != q.id or original.question != q.original_question \
                or replace(q, dataset=original.dataset, question=original.question) != original \
                or extra != original.source:
            raise EfficientEQAError(f"{q.id} of {PARAPHRASE_FILE} is no longer a re-phrasing of "
                                    f"{SPLIT_DATASET}'s question with the same references",
                                    fix="write the paraphrase split again for the current split")
    return questions


def write_split(questions: Sequence[Question], header: dict[str, Any], path: Path,
                dataset: str = SPLIT_DATASET) -> None:
    """Header line plus one EvalQuestion per line (the package file the loader reads);
    ``dataset`` names the split and its version ("synthetic-test-v1")."""
    rows = [to_eval_question(q, dataset, SPLIT_ASSETS).to_dict() for q in questions]
    header = {"format": HEADER_FORMAT, "version": dataset.rpartition("-")[2], "dataset": dataset,
              "assets": SPLIT_ASSETS, **header, "questions": len(rows),
              "houses": len({q.house_seed for q in questions}),
              "category_counts": dict(Counter(q.category for q in questions))}
    path.write_text("".join(json.dumps(r) + "\n" for r in [header, *rows]))


def check_question(scene: Scene, question: EvalQuestion) -> None:
    """Fail unless ``scene`` (``scenes.open_scene(question.scene)``) still generates the question
    with the same answer: a split from another generator asks things the house no longer has.
    A re-phrased question is checked by its original wording.

    Oracle step counts may drift (a few pixels of rendering); that is logged, not fatal, where
    the scene was opened with them.
    """
    from efficienteqa.envs.synthetic.env import SyntheticEnv
    from efficienteqa.envs.synthetic.noise import NoisyEnv

    env = scene.env.env if isinstance(scene.env, NoisyEnv) else scene.env  # the house under noise
    if not isinstance(env, SyntheticEnv):
        raise EfficientEQAError(f"{question.id} is asked in a synthetic house, not in {scene.name}",
                                fix=f"open {question.scene}")
    seed = question.source.get("house_seed")
    if seed is not None and env.house.seed != seed:
        raise EfficientEQAError(f"{question.id} belongs to house {seed}, not {scene.name}",
                                fix=f"open {question.scene}")
    wording = question.original_question  # a re-phrasing is not the generator's: its original is
    live = next((q for q in scene.questions if q.question == wording), None)
    if live is None or live.answer != question.answer:
        now = "no longer asked" if live is None else f"now answered {live.answer!r}"
        raise EfficientEQAError(f"{question.id}: {wording!r} (answer {question.answer!r}) "
                                f"is {now} in {scene.name}: the house generator changed", fix=REBUILD)
    if live.oracle_steps is not None and live.oracle_steps != question.oracle_steps:
        log.warning("%s: oracle steps now %s, split says %s", question.id, live.oracle_steps,
                    question.oracle_steps)


# -- live generation for arbitrary seeds --------------------------------------------------------
# Houses a dataset may name at once: each is generated (about a second) before any question is
# picked, since the questions of all of them are interleaved.
MAX_SEEDS = 5000


def parse_seeds(spec: str) -> list[int]:
    """"3", "0-9", "1,4,7" (and mixes such as "0-3,8") -> sorted unique seeds. ValueError for a
    spec that is not one, or names more than ``MAX_SEEDS`` houses (checked before listing them)."""
    seeds: set[int] = set()
    for part in spec.split(","):
        lo, dash, hi = part.strip().partition("-")
        if not lo.isdigit() or (dash and not hi.isdigit()):
            raise ValueError(part)
        first, last = int(lo), int(hi) if dash else int(lo)
        if last < first:
            raise ValueError(part)
        if last - first + 1 + len(seeds) > MAX_SEEDS:
            raise ValueError(f"more than {MAX_SEEDS} houses")
        seeds.update(range(first, last + 1))
    return sorted(seeds)


def _house_questions(seed: int, assets: str) -> list[Question]:
    from efficienteqa.envs.synthetic.env import SyntheticEnv
    from efficienteqa.scenes import synthetic_questions

    with SyntheticEnv.from_seed(seed, assets) as env:
        return synthetic_questions(env)


def load_seeds(seeds: Sequence[int], assets: str = DEFAULT_ASSETS) -> list[EvalQuestion]:
    """Every question of the given houses, interleaved; generated once, then read from the cache
    (a progress bar shows when several houses must be generated)."""
    folder = cache_dir("datasets", "synthetic", assets)
    version = generator_version()
    cached = {s: folder / f"{s}-{version}.jsonl" for s in seeds}
    todo = [s for s in seeds if not cached[s].is_file()]
    if todo:
        from rich.progress import Progress

        with Progress(disable=len(todo) < 2, transient=True) as bar:
            task = bar.add_task(f"generating {len(todo)} synthetic houses", total=len(todo))
            for seed in todo:
                rows = [to_eval_question(q, LIVE_DATASET, assets).to_dict()
                        for q in _house_questions(seed, assets)]
                tmp = folder / f".{cached[seed].name}.{os.getpid()}.tmp"
                tmp.write_text("".join(json.dumps(r) + "\n" for r in rows))
                tmp.replace(cached[seed])
                for stale in folder.glob(f"{seed}-gen-*.jsonl"):
                    if stale != cached[seed]:
                        stale.unlink(missing_ok=True)
                bar.advance(task)
    return interleave([EvalQuestion.from_dict(json.loads(line))
                       for seed in seeds for line in cached[seed].read_text().splitlines()])
