"""Episodic-memory export: a frozen split's houses as recorded walks, for answer-only methods.

``efficienteqa scenes export-walks SPLIT OUT`` writes::

    OUT/
      questions.jsonl   one question a line (``datasets.questions_file``'s format; also the
                        split's id, accepted answers and oracle steps), scene "recorded:walks/SEED"
      walks/SEED/       a walk folder (``envs.recorded.folder``): rgb/ PNG, depth/ 16-bit PNG in
                        millimetres, instance/ ids, labels.json, poses.jsonl (stamp: the frame's
                        index in seconds)

so ``efficienteqa eval --eval.dataset OUT/questions.jsonl`` grades answer-only methods (OpenEQA's
EM-EQA setting) without the simulator, and ``efficienteqa ask Q --scene recorded:OUT/walks/SEED``
replays one walk.

The walk of a house is fixed by the split, and the same for every question of the house:

1. four views at the robot's start pose (its heading, then turned 90, 180 and 270 degrees);
2. a tour of the oracle poses of the split's questions on the house (the poses the split
   records, from which each question's evidence is in view), nearest first by path length
   (ties: the split's order), along the navigation grid's shortest paths in moves of at most
   3 m, each view facing the way it moved, each leg ending at its oracle pose facing the
   evidence.

It is an oracle's walk, not an explorer's: it sees every question's evidence (what an
answer-only benchmark needs), and it does not single out any one question's (the house's
questions share it). ``--limit`` chooses questions, never changes a walk.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.datasets.manifest import house_digest
from efficienteqa.datasets.splits import frozen_split, load_frozen, packaged_manifest
from efficienteqa.datasets.synthetic import SPLIT_ASSETS, house_of
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D, wrap_angle

if TYPE_CHECKING:
    from efficienteqa.envs.synthetic.env import SyntheticEnv

STEP_M = 3.0  # the longest move between two views, as the oracle counts steps
LOOK_AROUND = 4  # views at the start pose, evenly turned
QUESTIONS_FILE = "questions.jsonl"
WALKS = "walks"


@dataclass
class Exported:
    questions: int
    houses: int
    frames: int
    path: Path


def _legs(path: np.ndarray, goal: Pose2D) -> list[Pose2D]:
    """Views every ``STEP_M`` along ``path`` (K, 2 metres), facing the way it goes, then
    ``goal`` itself."""
    pts = [np.asarray(path[0], float)]
    for p in np.asarray(path, float)[1:]:
        if np.linalg.norm(p - pts[-1]) > 1e-9:  # no zero-length segments
            pts.append(p)
    seg = [float(np.linalg.norm(b - a)) for a, b in zip(pts, pts[1:])]
    total, out = sum(seg), []
    d, k, passed = STEP_M, 0, 0.0
    while d < total - 1e-6:
        while passed + seg[k] < d:
            passed, k = passed + seg[k], k + 1
        a, b = pts[k], pts[k + 1]
        p = a + (b - a) * ((d - passed) / seg[k])
        out.append(Pose2D(float(p[0]), float(p[1]), math.atan2(b[1] - a[1], b[0] - a[0])))
        d += STEP_M
    return [*out, goal]


def walk_poses(env: SyntheticEnv, goals: list[Pose2D]) -> list[Pose2D]:
    """The house's walk (module docstring) through ``goals`` (in the split's order); a goal no
    path reaches is left out."""
    from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M
    from efficienteqa.mapping.navgrid import path_length

    start = env.start
    poses = [Pose2D(start.x, start.y, float(wrap_angle(start.yaw + k * 2 * math.pi / LOOK_AROUND)))
             for k in range(LOOK_AROUND)]
    here, todo = (start.x, start.y), list(goals)
    while todo:
        paths = [env.grid.shortest_path(here, (g.x, g.y), ROBOT_RADIUS_M) for g in todo]
        reachable = [(path_length(p), i) for i, p in enumerate(paths) if p is not None]
        if not reachable:
            break
        _, i = min(reachable)
        path, goal = paths[i], todo.pop(i)
        assert path is not None
        poses += _legs(path, goal)
        here = (goal.x, goal.y)
    return poses


def _row(q: EvalQuestion, seed: int) -> dict[str, Any]:
    return {"id": q.id, "question": q.question, "answer": q.answer,
            "alternatives": list(q.alternatives), "category": q.category,
            "scene": f"recorded:{WALKS}/{seed}", "accepted": list(q.accepted),
            "oracle_steps": q.oracle_steps}


def _check_out(out: Path) -> None:
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise EfficientEQAError(f"{out} exists and is not an empty folder; an export is never "
                                "written over", fix="remove it or give another OUT")


def export_walks(name: str, out: Path, limit: int | None = None,
                 progress: Callable[[int, int], None] | None = None) -> Exported:
    """Write the walks of the houses of the split's first ``limit`` questions (all by default)
    and their questions file under ``out`` (module docstring); ``progress`` gets (houses done,
    houses). Fails before writing anything where a house is no longer the manifest's."""
    from efficienteqa.envs.recorded.write import WalkRecorder
    from efficienteqa.envs.synthetic.env import SyntheticEnv

    if limit is not None and limit < 1:
        raise EfficientEQAError(f"--limit must be at least 1, got {limit}")
    split = frozen_split(name)
    _check_out(out)
    questions = load_frozen(split.name)
    chosen = questions[:limit]
    seeds = list(dict.fromkeys(house_of(q) for q in chosen))
    houses = packaged_manifest(split)["houses"]
    frames = 0
    for n, seed in enumerate(seeds, 1):
        with SyntheticEnv.from_seed(seed, SPLIT_ASSETS) as env:
            if house_digest(env.house) != houses[str(seed)]["digest"]:
                raise EfficientEQAError(f"house {seed} of {split.name} is no longer generated as "
                                        "its manifest fixes it",
                                        fix=f"run efficienteqa scenes verify {split.name}")
            goals = [Pose2D(*q.source["oracle_pose"]) for q in questions
                     if house_of(q) == seed and q.source.get("oracle_pose")]
            with WalkRecorder(out / WALKS / str(seed), labels=env.scene_labels(),
                              depth_encoding="16UC1") as recorder:
                for k, pose in enumerate(walk_poses(env, goals)):
                    recorder.add(env.observe(pose), stamp_ns=k * 1_000_000_000)
            if recorder.error:
                raise EfficientEQAError(recorder.error, fix="free space on the disk of OUT")
            frames += recorder.frames
        if progress:
            progress(n, len(seeds))
    text = "".join(json.dumps(_row(q, house_of(q))) + "\n" for q in chosen)
    (out / QUESTIONS_FILE).write_text(text)
    return Exported(len(chosen), len(seeds), frames, out / QUESTIONS_FILE)
