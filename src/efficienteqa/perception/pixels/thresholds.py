"""Per-category region thresholds for the pixel perception, chosen on validation houses (DESIGN 9,
learned perception).

One threshold for every category cost objects: a region's confidence is low where the network is
right but the category is hard (chairs, sinks, toilets) and high where it is wrong but the
category is common. Here every region the network proposes is scored once on validation frames
(its category, its interior confidence, whether it is *right*: half its pixels on true objects
of its category), and every object in view records which regions of its category cover it. A
category's threshold is then the one that maximises F1 of *found* (the kept regions cover half
the object) and *right*; a category with fewer than MIN_OBJECTS objects in view keeps the
global MIN_CONFIDENCE. The thresholds are written into the weights' record (the .json beside
the .pt), so they travel with the network they were chosen for.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.envs.base import SceneLabels
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import backproject
from efficienteqa.observation import Observation
from efficienteqa.perception.pixels.evaluate import COVER, ORACLE_PIXELS
from efficienteqa.perception.pixels.fusion import ObjectEvidence
from efficienteqa.perception.pixels.jobs import ThresholdJob
from efficienteqa.perception.pixels.segment import (
    MIN_CONFIDENCE,
    PixelClasses,
    fused_support,
    regions_of,
    scaled_intrinsics,
)
from efficienteqa.perception.visible import scaled_min_pixels, visible_objects

GRID = tuple(round(0.05 * k, 2) for k in range(4, 19))  # 0.2 ... 0.9, the thresholds tried
MIN_OBJECTS = 8  # fewer objects of a category in view: its threshold stays MIN_CONFIDENCE


@dataclass
class Candidates:
    """Per category: the proposed regions as (confidence, right, fused evidence) and the
    objects in view as lists of (confidence, share of the object covered, fused evidence) of
    the regions that cover them (fused evidence 0 where frames were scored alone)."""

    regions: dict[str, list[tuple[float, bool, float]]] = field(
        default_factory=lambda: defaultdict(list))
    objects: dict[str, list[list[tuple[float, float, float]]]] = field(
        default_factory=lambda: defaultdict(list))

    def f1(self, category: str, threshold: float, fused_min: float = math.inf
           ) -> tuple[float, float, float]:
        """(recall, precision, F1) of ``category`` when its regions need ``threshold``, or
        ``fused_min`` of fused evidence."""
        objects = self.objects.get(category, [])
        found = sum(sum(share for sure, share, fused in cover
                        if sure >= threshold or fused >= fused_min) >= COVER
                    for cover in objects)
        kept = [right for sure, right, fused in self.regions.get(category, [])
                if sure >= threshold or fused >= fused_min]
        recall = found / len(objects) if objects else 0.0
        precision = sum(kept) / len(kept) if kept else 0.0
        f1 = 2 * recall * precision / (recall + precision) if recall + precision else 0.0
        return recall, precision, f1


Classify = Callable[[np.ndarray, np.ndarray], PixelClasses]


def collect(frames: Iterable[tuple[Observation, SceneLabels, Any]], classify: Classify,
            progress: Callable[[int], None] | None = None,
            episodes: Callable[[Observation], bool] | None = None) -> Candidates:
    """Score every region the network proposes on ``frames`` (each with its true labels; what
    follows them is not read). With ``episodes`` (true where a frame starts a new walk), the
    regions' evidence is also fused over the frames of each walk."""
    out = Candidates()
    evidence: ObjectEvidence | None = None
    for n, (obs, truth, *_) in enumerate(frames, start=1):
        if episodes is not None and (evidence is None or episodes(obs)):
            evidence = ObjectEvidence()
        _add_frame(obs, truth, classify(obs.rgb, obs.depth_m), out, evidence)
        if progress is not None:
            progress(n)
    return out


def _add_frame(obs: Observation, truth: SceneLabels, classes: PixelClasses,
               out: Candidates, evidence: ObjectEvidence | None = None) -> None:
    assert obs.instance is not None, "choosing thresholds needs the frame's true instances"
    h, w = obs.depth_m.shape
    sh, sw = classes.category.shape
    fy, fx = h // sh, w // sw
    names = list(classes.categories)
    depth_small = obs.depth_m[fy // 2::fy, fx // 2::fx]
    regions = regions_of(classes.category, depth_small, names.index("door"), classes.confidence)
    points = backproject(depth_small, scaled_intrinsics(obs.intrinsics, fy, fx), obs.cam_to_world)
    fused = fused_support(regions, points, evidence)
    every = visible_objects(obs, truth, 1)
    true_category = np.full((h, w), "", dtype=object)
    for o in every:
        true_category[obs.instance == o.instance_id] = o.label.category
    listed = scaled_min_pixels(h, w)  # the describer lists regions this large
    masks = []
    for (category, mask, sure), together in zip(regions, fused):
        full = np.repeat(np.repeat(mask, fy, axis=0), fx, axis=1) & (obs.depth_m > 0)
        masks.append((names[category], full, sure, together))
        if int(full.sum()) >= listed:
            right = float(np.mean(true_category[full] == names[category])) >= COVER
            out.regions[names[category]].append((sure, right, together))
    oracle = max(4, round(ORACLE_PIXELS * h * w / (640 * 480)))
    for o in every:
        if o.pixels < oracle:
            continue
        obj = obs.instance == o.instance_id
        cover = [(sure, float((full & obj).sum()) / o.pixels, together)
                 for name, full, sure, together in masks
                 if name == o.label.category and (full & obj).any()]
        out.objects[o.label.category].append(cover)


def choose(candidates: Candidates) -> dict[str, dict[str, Any]]:
    """Per category with at least MIN_OBJECTS objects in view and some F1: the threshold of
    best F1 (the lowest of equal ones) with its recall and precision, and those of
    MIN_CONFIDENCE."""
    chosen: dict[str, dict[str, Any]] = {}
    for category in sorted(candidates.objects):
        if len(candidates.objects[category]) < MIN_OBJECTS:
            continue
        scored = [(candidates.f1(category, t), t) for t in GRID]
        (recall, precision, f1), best = max(scored, key=lambda s: (s[0][2], -s[1]))
        if f1 == 0.0:  # never found and right at any threshold: nothing to choose by
            continue
        r0, p0, f0 = candidates.f1(category, MIN_CONFIDENCE)
        chosen[category] = {"threshold": best, "objects": len(candidates.objects[category]),
                            "recall": round(recall, 3), "precision": round(precision, 3),
                            "f1": round(f1, 3), "recall_at_default": round(r0, 3),
                            "precision_at_default": round(p0, 3), "f1_at_default": round(f0, 3)}
    return chosen


def overall(candidates: Candidates, thresholds: dict[str, float],
            fused_min: float = math.inf) -> tuple[float, float]:
    """Recall and precision over every category with ``thresholds`` (MIN_CONFIDENCE else)
    and ``fused_min``."""
    found = objects = right = kept = 0
    for category in set(candidates.objects) | set(candidates.regions):
        t = thresholds.get(category, MIN_CONFIDENCE)
        for cover in candidates.objects.get(category, []):
            objects += 1
            found += sum(share for sure, share, fused in cover
                         if sure >= t or fused >= fused_min) >= COVER
        for sure, ok, fused in candidates.regions.get(category, []):
            if sure >= t or fused >= fused_min:
                kept += 1
                right += ok
    return found / max(objects, 1), right / max(kept, 1)


def write_thresholds(weights: Path, chosen: dict[str, dict[str, Any]],
                     about: dict[str, Any]) -> Path:
    """Record ``chosen`` in the weights' .json ("region_thresholds", and how they were chosen
    in "region_thresholds_record"); the .pt and its sha256 are untouched."""
    from efficienteqa.perception.pixels.net import metadata_path

    path = metadata_path(Path(weights))
    try:
        meta = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise EfficientEQAError(f"cannot read the weights record {path}: {exc}") from None
    meta["region_thresholds"] = {c: v["threshold"] for c, v in chosen.items()}
    meta["region_thresholds_record"] = {**about, "per_category": chosen}
    path.write_text(json.dumps(meta, indent=2) + "\n")
    return path


@dataclass
class Choice:
    """Thresholds chosen for the weights ``path`` on validation houses (``choose``), with the
    recall and precision over every category before and after, and how they were chosen."""

    path: Path
    chosen: dict[str, dict[str, Any]]
    before: tuple[float, float]
    after: tuple[float, float]
    about: dict[str, Any]

    def lines(self) -> list[str]:
        """A line per category, and one for them all."""
        lines = [f"{category}: {c['threshold']:.2f} ({c['objects']} objects; found "
                 f"{c['recall_at_default']:.0%} -> {c['recall']:.0%}, right "
                 f"{c['precision_at_default']:.0%} -> {c['precision']:.0%})"
                 for category, c in self.chosen.items()]
        b, a = self.before, self.after
        return lines + [f"all: found {b[0]:.1%} -> {a[0]:.1%}, right {b[1]:.1%} -> {a[1]:.1%} "
                        f"(houses {self.about['houses']}, {self.about['frames_per_house']} "
                        "frames each)"]

    def write(self) -> Path:
        """Record the thresholds in the weights' .json (``write_thresholds``)."""
        return write_thresholds(self.path, self.chosen, self.about)


def choose_on(job: ThresholdJob, progress: Callable[[int, int], None] | None = None) -> Choice:
    """``efficienteqa perception thresholds``: each category's threshold chosen on the
    validation houses ``job.seeds`` for ``job.weights`` (default: the committed ones);
    ``Choice.write`` records them. ``progress(done, total)`` follows the frames."""
    from dataclasses import replace

    from efficienteqa.perception.pixels.backend import WEIGHTS, PixelPerception
    from efficienteqa.perception.pixels.evaluate import heldout_frames
    from efficienteqa.perception.pixels.houses import VALIDATION_SEEDS, parse_seeds

    seeds, frames_per_house, seed, weights = job.seeds, job.frames_per_house, job.seed, job.weights
    houses = parse_seeds(seeds)
    if houses.start not in VALIDATION_SEEDS or houses.stop - 1 not in VALIDATION_SEEDS:
        raise EfficientEQAError(f"houses {seeds} are not validation houses",
                                fix=f"choose on houses within {VALIDATION_SEEDS.start}-"
                                    f"{VALIDATION_SEEDS.stop - 1}")
    if frames_per_house < 1:
        raise EfficientEQAError("--frames-per-house must be at least 1")
    path = weights or WEIGHTS
    unthresholded = PixelPerception.load(path).classify
    total = len(houses) * frames_per_house
    if progress is not None:
        progress(0, total)
    candidates = collect(heldout_frames(houses, frames_per_house, seed),
                         lambda rgb, depth: replace(unthresholded(rgb, depth), min_confidence={}),
                         progress=None if progress is None else lambda n: progress(n, total))
    chosen = choose(candidates)
    before = overall(candidates, {})
    after = overall(candidates, {c: v["threshold"] for c, v in chosen.items()})
    about = {"houses": seeds, "frames_per_house": frames_per_house, "seed": seed,
             "grid": list(GRID), "min_objects": MIN_OBJECTS, "criterion": "best F1",
             "found_right_before": [round(v, 4) for v in before],
             "found_right_after": [round(v, 4) for v in after]}
    return Choice(path, chosen, before, after, about)
