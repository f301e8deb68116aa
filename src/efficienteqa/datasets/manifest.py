"""A frozen split's manifest: what fixes its houses and questions, and one sha256 over it all.

``datasets/manifests/SPLIT.json`` holds, for each house of the split (``houses``, by seed):

- ``digest``: the sha256 of the house as the generator makes it, before anything is rendered
  (``House.to_json()``: rooms, doors, walls, every object's category, model, name, colour,
  state, room, position, size and yaw, the start pose, the generator's notes), every number
  rounded to 0.001 (1 mm, 1 mrad), keys sorted; ``rooms`` and ``objects``, its counts;
- ``start_view``: the episode's first frame (640x480 at the robot's start pose, ``pose`` in
  metres and radians): the pixels of each instance id covering at least 0.1 % of it, and the
  median depth (metres, 1 mm);

for each question (``questions``, in the split's order): id, house, category, wording,
reference answer, alternatives, accepted answers, evidence ids, oracle steps and oracle pose
(``question_entry``); and ``sha256``, over everything else (canonical JSON: keys sorted, no
spaces, UTF-8). ``efficienteqa scenes verify`` (``verify``) regenerates and compares.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.datasets.splits import (
    MANIFEST_DIR,
    SPLITS,
    FrozenSplit,
    frozen_split,
    integrity_problems,
    manifest_sha256,
    packaged_manifest,
    question_entry,
    row_problems,
    sha256_of,
)
from efficienteqa.datasets.synthetic import SPLIT_ASSETS, generator_version, house_of, load_split
from efficienteqa.errors import EfficientEQAError

if TYPE_CHECKING:
    from efficienteqa.envs.synthetic.env import SyntheticEnv
    from efficienteqa.envs.synthetic.house import House

FORMAT = "efficienteqa-split-manifest/1"
# The start view is compared loosely (renders differ across Mesa versions and GPUs): each
# instance id's pixels within PIXEL_TOLERANCE of the frame's, the median depth within
# DEPTH_TOLERANCE_M; ids under MIN_SHARE of the frame are not recorded.
MIN_SHARE = 0.001
PIXEL_TOLERANCE = 0.01
DEPTH_TOLERANCE_M = 0.01
COMPARED = {
    "exactly": "each house's digest (the generated house before rendering, numbers to 1 mm) and "
               "start pose; each question's id, wording, category, reference, alternatives, "
               "accepted answers, evidence ids, oracle steps and oracle pose (the last two "
               "counted on quarter-size instance renders)",
    "loosely": f"the start view's pixels per instance id (within {PIXEL_TOLERANCE:.0%} of the "
               f"frame) and median depth (within {DEPTH_TOLERANCE_M * 100:.0f} cm)",
    "not": "colours of rendered pixels",
}
Progress = Callable[[int], None]


def _rounded(value: Any) -> Any:
    """``value`` with every float rounded to 0.001 (and -0.0 as 0.0), tuples as lists."""
    if isinstance(value, float):
        return round(value, 3) + 0.0
    if isinstance(value, dict):
        return {str(k): _rounded(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_rounded(v) for v in value]
    return value


def house_digest(house: House) -> str:
    """The sha256 of the generated house (module docstring)."""
    return sha256_of(_rounded(house.to_json()))


def start_view(env: SyntheticEnv) -> dict[str, Any]:
    """The episode's first frame, summarised (module docstring)."""
    obs, _ = env.reset()
    instance = obs.instance
    assert instance is not None  # a synthetic house renders instance ids
    ids, counts = np.unique(instance[instance > 0], return_counts=True)
    keep = counts >= MIN_SHARE * instance.size
    depth = obs.depth_m[obs.depth_m > 0]
    return {"pose": _rounded([obs.pose.x, obs.pose.y, obs.pose.yaw]),
            "size": [int(obs.rgb.shape[1]), int(obs.rgb.shape[0])],
            "pixels": {str(int(i)): int(c) for i, c in zip(ids[keep], counts[keep])},
            "depth_median_m": round(float(np.median(depth)), 3) if depth.size else 0.0}


def start_view_problems(seed: int, live: dict[str, Any], fixed: dict[str, Any]) -> list[str]:
    """Where the start views differ: the pose or size at all, pixels or depth beyond the
    tolerances."""
    if live["pose"] != fixed.get("pose") or live["size"] != fixed.get("size"):
        return [f"house {seed}: start view at {live['pose']} ({live['size']}), manifest "
                f"{fixed.get('pose')} ({fixed.get('size')})"]
    problems = []
    allowed = PIXEL_TOLERANCE * live["size"][0] * live["size"][1]
    a, b = live["pixels"], fixed.get("pixels", {})
    off = {i: (a.get(i, 0), b.get(i, 0)) for i in sorted({*a, *b}, key=int)
           if abs(a.get(i, 0) - b.get(i, 0)) > allowed}
    if off:
        problems.append(f"house {seed}: start view pixels of instance "
                        + ", ".join(f"{i} {n} (manifest {m})" for i, (n, m) in off.items())
                        + f", beyond {allowed:.0f}")
    depth = fixed.get("depth_median_m", 0.0)
    if abs(live["depth_median_m"] - depth) > DEPTH_TOLERANCE_M:
        problems.append(f"house {seed}: start view median depth {live['depth_median_m']} m, "
                        f"manifest {depth} m")
    return problems


def build_manifest(split: str, file: str, questions: list[EvalQuestion],
                   progress: Progress | None = None) -> dict[str, Any]:
    """The manifest of split ``split`` (package file ``file``) holding ``questions``; opens
    each house once (about 2 s)."""
    from efficienteqa.envs.synthetic.env import SyntheticEnv

    houses: dict[str, Any] = {}
    seeds = sorted({house_of(q) for q in questions})
    for n, seed in enumerate(seeds, 1):
        with SyntheticEnv.from_seed(seed, SPLIT_ASSETS) as env:
            houses[str(seed)] = {"digest": house_digest(env.house),
                                 "rooms": len(env.house.layout.rooms),
                                 "objects": len(env.house.objects), "start_view": start_view(env)}
        if progress:
            progress(n)
    from efficienteqa.datasets.splits import SPLITS

    body = {"format": FORMAT, "split": split, "use": SPLITS[split].use, "file": file,
            "assets": SPLIT_ASSETS,
            "built_with": {"generator": generator_version()}, "compared": COMPARED,
            "seeds": seeds, "houses": houses, "questions": [question_entry(q) for q in questions]}
    return {**body, "sha256": manifest_sha256(body)}


def dumps(manifest: dict[str, Any]) -> str:
    """The manifest as JSON with one line per key, house and question (a readable diff)."""
    def one(value: Any) -> str:
        return json.dumps(value, ensure_ascii=False)

    lines = []
    for key, value in manifest.items():
        if isinstance(value, dict) and key == "houses":
            inner = [f"  {one(k)}: {one(v)}" for k, v in value.items()]
        elif isinstance(value, list) and key == "questions":
            inner = [f"  {one(v)}" for v in value]
        else:
            lines.append(f" {one(key)}: {one(value)}")
            continue
        opening, closing = ("{", "}") if isinstance(value, dict) else ("[", "]")
        lines.append(f" {one(key)}: {opening}\n" + ",\n".join(inner) + f"\n {closing}")
    return "{\n" + ",\n".join(lines) + "\n}\n"


def write_manifest(manifest: dict[str, Any], folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{manifest['split']}.json"
    path.write_text(dumps(manifest))
    return path


# -- verify ------------------------------------------------------------------------------------
@dataclass
class Verified:
    """What ``verify`` checked and every mismatch it found, one line each."""

    split: str
    houses: int = 0
    questions: int = 0
    mismatches: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def line(self) -> str:
        """``scenes verify``'s line for the split: reproduced, or how many mismatches."""
        state = f"{len(self.mismatches)} mismatches" if self.mismatches else "reproduced"
        return (f"{self.split}: {self.houses} houses, {self.questions} questions {state} "
                f"({self.seconds:.0f} s)")


def to_verify(names: Sequence[str] = (), manifest: Path | None = None,
              limit: int | None = None) -> tuple[list[FrozenSplit], dict[str, Any] | None]:
    """``scenes verify``'s splits (``names``, default every frozen split) and the manifest read
    from ``manifest`` (None: each split's packaged one), checked before any house is built."""
    chosen = [frozen_split(name) for name in names] if names else list(SPLITS.values())
    if manifest is not None and len(chosen) != 1:
        raise EfficientEQAError("--manifest checks one split", fix="name the split it belongs to")
    if limit is not None and limit < 1:
        raise EfficientEQAError(f"--limit must be at least 1, got {limit}")
    if manifest is None:
        return chosen, None
    try:
        return chosen, json.loads(manifest.read_text())
    except (OSError, ValueError) as error:
        raise EfficientEQAError(f"cannot read the manifest {manifest}: {error}",
                                fix="give a manifest written by "
                                    "scripts/make_synthetic_split.py") from None


def verify(split: FrozenSplit, manifest: dict[str, Any] | None = None, limit: int | None = None,
           progress: Progress | None = None) -> Verified:
    """Regenerate the split's houses (the first ``limit`` of its seeds) and their questions
    on this machine and compare them with ``manifest`` (the packaged one by default): the
    manifest's own sha256 and the committed digest, the split file's questions, then per house
    what ``COMPARED`` says. ``progress`` gets the number of houses done."""
    from efficienteqa.datasets.synthetic import to_eval_question
    from efficienteqa.envs.synthetic.env import SyntheticEnv
    from efficienteqa.envs.synthetic.oracle import annotate
    from efficienteqa.scenes import synthetic_questions

    start = time.perf_counter()
    manifest = packaged_manifest(split) if manifest is None else manifest
    done = Verified(split.name)
    done.mismatches += integrity_problems(split, manifest)
    done.mismatches += row_problems(split, manifest, load_split(split.file))
    fixed_houses = manifest.get("houses") or {}
    seeds = sorted(fixed_houses, key=int)[:limit]
    for n, seed in enumerate(seeds, 1):
        fixed = fixed_houses[seed]
        entries = [e for e in manifest.get("questions") or [] if str(e.get("house_seed")) == seed]
        with SyntheticEnv.from_seed(int(seed), SPLIT_ASSETS) as env:
            if house_digest(env.house) != fixed.get("digest"):
                done.mismatches.append(f"house {seed}: generated with digest "
                                       f"{house_digest(env.house)}, manifest {fixed.get('digest')}")
            live = {q.id: q for q in synthetic_questions(env, oracle=False)}
            wanted = {str(e["id"]).partition("/")[2] for e in entries}
            seen = {q.id for q in annotate(env, [q for i, q in live.items() if i in wanted])}
            for entry in entries:
                qid = str(entry["id"]).partition("/")[2]
                q = live.get(qid)
                if q is None or (q.evidence and qid not in seen):
                    why = "is no longer generated" if q is None else "has evidence never seen"
                    done.mismatches.append(f"{entry['id']} {why} in house {seed}")
                    continue
                now = question_entry(to_eval_question(q, split.name, SPLIT_ASSETS))
                for key in sorted({*now, *entry}):
                    if json.dumps(now.get(key)) != json.dumps(entry.get(key)):
                        done.mismatches.append(f"{entry['id']}: {key} is {now.get(key)!r}, "
                                               f"manifest {entry.get(key)!r}")
            done.mismatches += start_view_problems(int(seed), start_view(env),
                                                   fixed.get("start_view") or {})
        done.houses, done.questions = n, done.questions + len(entries)
        if progress:
            progress(n)
    done.seconds = time.perf_counter() - start
    return done


__all__ = ["COMPARED", "MANIFEST_DIR", "Verified", "build_manifest", "house_digest",
           "manifest_sha256", "question_entry", "verify", "write_manifest"]
