"""How well pixel perception sees, against the semantic sensor's ground truth (DESIGN 9,
learned perception).

Per frame, the objects the semantic sensor lists at the oracle's pixel threshold are the truth,
and the objects pixel perception would describe (at the describer's own threshold) are the
predictions. An object in view is *found* when the predicted regions of its category cover at
least half of its pixels; a predicted object is *right* when at least half of its pixels lie on
true objects of its category. Colour and state are scored on found objects (the predicted object
that overlaps it most), the room type of the floor on the true floor pixels. Colour is scored
twice: the colour head's majority (what the perception says) and the palette name of the
region's median pixel (the alternative it was measured against). Everything is split
by category, by size (furniture and small objects) and by distance (under 2 m, 2-4 m, beyond),
and apart for the objects the generator recoloured (the ones colour questions ask about) and for
those whose mesh was held out of the network's training (``tags``).

Frames are posed as the training frames are (random views, views of loaded surfaces and of
doors), or at the poses of recorded walks (``--poses``: the agent's own, see
``experiments/walk_poses.py``).
"""

from __future__ import annotations

import json
import time
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.envs.base import SceneLabels
from efficienteqa.envs.synthetic.colours import colour_name
from efficienteqa.envs.synthetic.house import ALL_CATALOGUES, DEFAULT_ASSETS
from efficienteqa.envs.synthetic.vocabulary import SMALL_CATEGORIES
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import backproject
from efficienteqa.observation import Observation
from efficienteqa.perception.floor import FLOOR_TOLERANCE_M
from efficienteqa.perception.pixels.backend import PixelPerception
from efficienteqa.perception.pixels.frames import room_type_of
from efficienteqa.perception.pixels.houses import HELDOUT_CATALOGUE, TRAIN_SEEDS
from efficienteqa.perception.pixels.jobs import MeasureJob
from efficienteqa.perception.visible import VisibleObject, visible_objects

ORACLE_PIXELS = 250  # at 640x480: the oracle's "in view" (an evidence object this large)
COVER = 0.5  # a true object is found when its category's predicted pixels cover this share
NEAR_M, FAR_M = 2.0, 4.0
SMALL_WITHIN_M = 3.0  # the small-object target counts objects this close


@dataclass
class Tally:
    """Counts for one slice: found / true objects, right / predicted objects, colours and
    states right / scored."""

    true: int = 0
    found: int = 0
    predicted: int = 0
    right: int = 0
    colour: list[int] = field(default_factory=lambda: [0, 0])
    colour_from_pixels: list[int] = field(default_factory=lambda: [0, 0])
    state: list[int] = field(default_factory=lambda: [0, 0])

    def add(self, other: Tally) -> None:
        self.true += other.true
        self.found += other.found
        self.predicted += other.predicted
        self.right += other.right
        for a, b in ((self.colour, other.colour), (self.state, other.state),
                     (self.colour_from_pixels, other.colour_from_pixels)):
            a[0] += b[0]
            a[1] += b[1]

    def figures(self) -> dict[str, Any]:
        def share(a: int, b: int) -> float | None:
            return round(a / b, 4) if b else None

        return {"recall": share(self.found, self.true), "precision": share(self.right,
                                                                           self.predicted),
                "objects": self.true, "predicted": self.predicted,
                "colour": share(*self.colour), "colour_n": self.colour[1],
                "colour_from_pixels": share(*self.colour_from_pixels),
                "state": share(*self.state), "state_n": self.state[1]}


@dataclass
class Scores:
    """Every tally by slice ("all", "category:<c>", "size:<s>", "distance:<d>",
    "small within 3 m"), the floor's room-type counts and the per-frame times."""

    tallies: dict[str, Tally] = field(default_factory=lambda: defaultdict(Tally))
    floor: list[int] = field(default_factory=lambda: [0, 0])
    seconds: list[float] = field(default_factory=list)
    frames: int = 0

    def to_json(self) -> dict[str, Any]:
        times = sorted(self.seconds)
        return {"frames": self.frames,
                "floor_room_type": round(self.floor[0] / self.floor[1], 4) if self.floor[1]
                else None, "floor_pixels": self.floor[1],
                "median_ms": round(1000 * times[len(times) // 2], 1) if times else None,
                "slices": {k: t.figures() for k, t in sorted(self.tallies.items())}}


Tags = Mapping[int, Sequence[str]]  # instance id -> slices of its own ("recoloured", ...)
RECOLOURED = "recoloured"
HELD_OUT_MESH, TRAINED_MESH = "mesh:held out of training", "mesh:trained on"
# In houses of every catalogue (assets "sh3d-all"), each object's catalogue is one the network's
# training houses showed or one of a style it never saw: the CC-BY catalogues for weights trained
# on the CC0 catalogue's houses, the held-out catalogue for weights trained on every catalogue.
TRAINED_CATALOGUE, UNSEEN_CATALOGUE = "catalogue:trained on", "catalogue:never seen"


def _slices(obj: VisibleObject, small: frozenset[str], tags: Tags) -> list[str]:
    size = "small" if obj.label.category in small else "furniture"
    d = obj.distance_m
    distance = "under 2 m" if d < NEAR_M else "2-4 m" if d < FAR_M else "beyond 4 m"
    out = ["all", f"category:{obj.label.category}", f"size:{size}", f"distance:{distance}",
           f"size:{size}, distance:{distance}", *tags.get(obj.instance_id, ())]
    if size == "small" and d < SMALL_WITHIN_M:
        out.append("small within 3 m")
    return out


def score_frame(obs: Observation, truth: SceneLabels, perception: PixelPerception,
                small: frozenset[str], scores: Scores, tags: Tags | None = None) -> None:
    """Add one frame's counts to ``scores`` (``tags``: extra slices of some true objects)."""
    assert obs.instance is not None, "scoring needs the frame's true instance buffer"
    stripped = Observation(rgb=obs.rgb, depth_m=obs.depth_m, cam_to_world=obs.cam_to_world,
                           intrinsics=obs.intrinsics, pose=obs.pose)
    start = time.perf_counter()
    seen, predicted_labels = perception.read(stripped)
    scores.seconds.append(time.perf_counter() - start)
    scores.frames += 1
    h, w = obs.depth_m.shape
    every = visible_objects(obs, truth, 1)
    oracle = max(4, round(ORACLE_PIXELS * h * w / (640 * 480)))
    true_objects = [o for o in every if o.pixels >= oracle]
    predicted = visible_objects(seen, predicted_labels)
    assert seen.instance is not None
    pred_category = np.full((h, w), "", dtype=object)
    for p in predicted:
        pred_category[seen.instance == p.instance_id] = p.label.category
    true_category = np.full((h, w), "", dtype=object)
    for o in every:
        true_category[obs.instance == o.instance_id] = o.label.category
    for o in true_objects:
        mask = obs.instance == o.instance_id
        same = pred_category[mask] == o.label.category
        tally = Tally(true=1, found=int(same.mean() >= COVER))
        if tally.found:
            ids, counts = np.unique(seen.instance[mask & (pred_category == o.label.category)],
                                    return_counts=True)
            best_id = int(ids[counts.argmax()])
            best = predicted_labels.label(best_id)
            if best is not None and o.label.colour is not None:
                tally.colour = [int(best.colour == o.label.colour), 1]
                hue = colour_name(np.median(obs.rgb[seen.instance == best_id], axis=0) / 255.0)
                tally.colour_from_pixels = [int(hue == o.label.colour), 1]
            if best is not None and o.label.state is not None:
                tally.state = [int(best.state == o.label.state), 1]
        for key in _slices(o, small, tags or {}):
            scores.tallies[key].add(tally)
    for p in predicted:
        mask = seen.instance == p.instance_id
        right = int(np.mean(true_category[mask] == p.label.category) >= COVER)
        for key in ("all", f"category:{p.label.category}",
                    f"size:{'small' if p.label.category in small else 'furniture'}"):
            scores.tallies[key].add(Tally(predicted=1, right=right))
    _score_floor(obs, truth, seen, predicted_labels, scores)


def _score_floor(obs: Observation, truth: SceneLabels, seen: Observation,
                 predicted: SceneLabels, scores: Scores) -> None:
    """Room type of the true floor pixels (every 4th pixel each way), as the predicted labels
    name the room at each pixel's floor point."""
    assert obs.instance is not None and seen.instance is not None
    k = 4
    points = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[::k, ::k]
    floor = ((obs.instance[::k, ::k] == 0) & (obs.depth_m[::k, ::k] > 0)
             & (np.abs(points[..., 2]) < FLOOR_TOLERANCE_M))
    for x, y in points[floor][:, :2]:
        room = truth.room_at(float(x), float(y))
        if room is None:
            continue
        want = room_type_of(room)  # "guest bedroom" is a bedroom: pixels cannot tell whose
        scores.floor[1] += 1
        scores.floor[0] += int(predicted.room_at(float(x), float(y)) == want)


def check_heldout(seeds: Sequence[int]) -> None:
    """One line, before any work, when a house is one the network trained on."""
    trained = [s for s in seeds if s in TRAIN_SEEDS]
    if trained:
        raise EfficientEQAError(f"house {trained[0]} is a training house of the pixel network",
                                fix=f"evaluate on houses outside {TRAIN_SEEDS.start}-"
                                    f"{TRAIN_SEEDS.stop - 1}, e.g. the evaluation split 100-129")


Frame = tuple[Observation, SceneLabels, Tags]
Poses = Mapping[int, Sequence[Sequence[float]]]  # house -> walk poses (x, y, yaw)


def heldout_frames(seeds: Sequence[int], frames_per_house: int, seed: int = 0,
                   poses: Poses | None = None, held_out_meshes: frozenset[str] = frozenset(),
                   assets: str = DEFAULT_ASSETS, trained_on: str = DEFAULT_ASSETS
                   ) -> Iterator[Frame]:
    """Frames of houses the network never saw, with the houses' true labels and each object's
    tags: posed as its training frames are, or ``frames_per_house`` poses spread evenly over
    the house's walk in ``poses``. ``held_out_meshes``: the model keys kept out of training;
    ``assets``: the houses' furniture ("sh3d-all" tags each object with its catalogue, trained
    on or not by the weights' ``trained_on`` assets)."""
    from efficienteqa.envs.synthetic.env import SyntheticEnv
    from efficienteqa.geometry import Pose2D
    from efficienteqa.perception.pixels.frames import house_poses

    check_heldout(seeds)
    if poses is not None:
        missing = [h for h in seeds if not poses.get(h)]
        if missing:
            raise EfficientEQAError(f"the poses file has no walk of house {missing[0]}",
                                    fix="evaluate the houses it holds, or record their walks: "
                                        "python -m experiments.walk_poses")
    for house in seeds:
        with SyntheticEnv.from_seed(house, assets) as env:
            labels = env.scene_labels()
            tags = object_tags(env.house.objects, held_out_meshes,
                               unseen_catalogue(env.catalog, trained_on)
                               if assets == ALL_CATALOGUES else None)
            if poses is None:
                chosen = [p for _, p in house_poses(env, frames_per_house,
                                                    np.random.default_rng([seed, house]))]
            else:
                walk = poses[house]
                picks = np.linspace(0, len(walk) - 1, min(frames_per_house, len(walk)))
                chosen = [Pose2D(*map(float, walk[int(round(i))])) for i in picks]
            for pose in chosen:
                yield env.observe(pose), labels, tags


def unseen_catalogue(catalog: Any, trained_on: str) -> Callable[[str], bool]:
    """Whether a model key's catalogue was kept out of the training houses of weights trained
    on ``trained_on`` furniture: every catalogue but the CC0 one for "sh3d", the held-out
    catalogue (``houses.HELDOUT_CATALOGUE``) for "sh3d-all"."""
    if trained_on == ALL_CATALOGUES:
        return lambda key: catalog.entry(key).catalogue == HELDOUT_CATALOGUE
    return lambda key: catalog.entry(key).licence != "CC0-1.0"


def object_tags(objects: Iterable[Any], held_out_meshes: frozenset[str],
                unseen_catalogue: Callable[[str], bool] | None = None) -> dict[int, list[str]]:
    """Per object id: "recoloured" where the generator gave it a palette colour, whether its
    mesh was held out of training (only when some meshes were), and with ``unseen_catalogue``
    (model key -> whether its catalogue was kept out of training) its catalogue's slice."""
    tags: dict[int, list[str]] = {}
    for o in objects:
        mine = [RECOLOURED] if getattr(o, "colour_rgb", None) is not None else []
        if held_out_meshes:
            mine.append(HELD_OUT_MESH if o.model_key in held_out_meshes else TRAINED_MESH)
        if unseen_catalogue is not None and o.category != "door":
            mine.append(UNSEEN_CATALOGUE if unseen_catalogue(o.model_key) else TRAINED_CATALOGUE)
        if mine:
            tags[o.id] = mine
    return tags


def read_poses(path: Any) -> dict[int, list[list[float]]]:
    """The walks of a poses file (``experiments/walk_poses.py``); one-line errors."""
    fix = "record walks with: python -m experiments.walk_poses --out FILE"
    try:
        data = json.loads(path.read_text())
        return {int(h): [list(map(float, p)) for p in walk["poses"]]
                for h, walk in data["houses"].items()}
    except OSError as exc:
        raise EfficientEQAError(f"cannot read the poses file {path}: {exc.strerror}",
                                fix=fix) from None
    except (ValueError, KeyError, TypeError) as exc:
        raise EfficientEQAError(f"unreadable poses file {path}: {exc}", fix=fix) from None


def evaluate(frames: Iterable[Frame], perception: PixelPerception,
             small: frozenset[str] = SMALL_CATEGORIES,
             progress: Callable[[int], None] | None = None) -> Scores:
    scores = Scores()
    for n, (obs, truth, tags) in enumerate(frames, start=1):
        score_frame(obs, truth, perception, small, scores, tags)
        if progress is not None:
            progress(n)
    return scores


def write_scores(scores: Scores, path: Any, about: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({**about, **scores.to_json()}, indent=1) + "\n")



def _pct(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.0f}"


def markdown_table(figures: dict[str, Any], min_objects: int = 10) -> str:
    """The figures as a markdown table: every slice but single categories, then the categories
    with at least ``min_objects`` true objects, commonest first."""
    slices = figures["slices"]
    head = ["| slice | objects | recall % | precision % | colour % (head) | colour % (pixels) "
            "| state % |", "|---|---:|---:|---:|---:|---:|---:|"]

    def row(name: str, f: dict[str, Any]) -> str:
        return (f"| {name} | {f['objects']} | {_pct(f['recall'])} | {_pct(f['precision'])} | "
                f"{_pct(f['colour'])} | {_pct(f['colour_from_pixels'])} | {_pct(f['state'])} |")

    general = [row(k, f) for k, f in slices.items() if not k.startswith("category:")]
    categories = sorted(((k, f) for k, f in slices.items() if k.startswith("category:")
                         and f["objects"] >= min_objects), key=lambda kf: -kf[1]["objects"])
    return "\n".join(head + general + [row(k[len("category:"):], f) for k, f in categories])


def measure(job: MeasureJob, houses: Sequence[int],
            progress: Callable[[int, int], None] | None = None) -> dict[str, Any]:
    """``efficienteqa perception evaluate``: the figures of ``job.weights`` (default: the
    committed ones) on ``job.frames_per_house`` views of each of ``houses`` (``job.seeds``, as
    the user wrote them), posed as training frames or at the walks of ``job.poses``; written
    with how they were made to ``job.out`` where given. The options are checked first, each in one line;
    ``progress(done, total)`` follows the frames."""
    from efficienteqa.perception.pixels.backend import CLOSE_READS
    from efficienteqa.records import check_writable, code_version

    check_heldout(houses)
    if job.assets not in (DEFAULT_ASSETS, ALL_CATALOGUES):
        raise EfficientEQAError(f"--assets {job.assets!r} is not furniture the network reads",
                                fix=f"use {DEFAULT_ASSETS} or {ALL_CATALOGUES}")
    if job.frames_per_house < 1:
        raise EfficientEQAError("--frames-per-house must be at least 1")
    if job.out is not None:
        check_writable(job.out.parent)
    if job.close_reads is not None and job.close_reads < 0:
        raise EfficientEQAError("--close-reads must be 0 or more")
    walks = read_poses(job.poses) if job.poses is not None else None
    perception = PixelPerception.load(
        job.weights, close_reads=CLOSE_READS if job.close_reads is None else job.close_reads)
    held_out = frozenset(perception.record.get("data", {}).get("heldout_model_keys", []))
    trained_on = perception.record.get("data", {}).get("assets", DEFAULT_ASSETS)
    frames = heldout_frames(houses, job.frames_per_house, job.seed, walks, held_out, job.assets,
                            trained_on)
    total = len(houses) * job.frames_per_house
    if progress is not None:
        progress(0, total)
    scores = evaluate(frames, perception,
                      progress=None if progress is None else lambda n: progress(n, total))
    if job.out is not None:
        write_scores(scores, job.out, {
            "houses": job.seeds, "frames_per_house": job.frames_per_house, "seed": job.seed,
            "poses": "walks " + job.poses.name if job.poses else "training-style",
            "weights": str(job.weights or "committed"), "assets": job.assets,
            "close_reads": perception.close_reads.crops, "code_version": code_version()})
    return scores.to_json()


def measured_lines(figures: dict[str, Any], seeds: str, out: Path | None = None) -> list[str]:
    """What ``perception evaluate`` prints: the table, then the frames, the floor's room type
    and the time a frame."""
    return [markdown_table(figures),
            f"{figures['frames']} frames of houses {seeds}; floor room type "
            f"{figures['floor_room_type']}; median {figures['median_ms']} ms a frame"
            + (f" -> {out}" if out else "")]


def read_table(figures: Path) -> str:
    """The markdown table of a JSON file ``perception evaluate --out`` wrote."""
    try:
        data = json.loads(figures.read_text())
    except (OSError, ValueError) as exc:
        raise EfficientEQAError(f"cannot read {figures}: {exc}") from None
    return markdown_table(data)
