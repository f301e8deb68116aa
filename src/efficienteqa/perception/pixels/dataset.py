"""Training frames for the pixel network, rendered from synthetic houses reserved for it.

Houses 3000-3999 are perception's own: TRAIN_SEEDS for fitting, VALIDATION_SEEDS for choosing
(disjoint from 0-20 development, 100-999 evaluation, 1000-1019 relevancy calibration and
2000-2999 held-out checks). Nothing is trained or tuned on any other house.

Per house, ``frames_per_house`` poses (deterministic by (seed, house seed)): about half random
navigable points and yaws, a quarter close views of surfaces that hold small objects (0.8-1.6 m
away, facing them) and a quarter views towards doors (1-2.5 m before one, facing it, so that the
next room's floor shows through it). Each frame is stored at half size (320x240): RGB averaged
over 2x2 blocks, and depth and labels read at the pixel ``[1::2, 1::2]`` of each block:

- ``category`` (uint8): 0 void (nothing hit), 1 wall (structure that is not floor), a
  "floor:<room type>" class for structure at floor height (named by the room under the pixel),
  "door", then object categories; IGNORE for objects outside the vocabulary and floor of no room;
- ``colour`` (uint8): the object's palette colour, IGNORE on structure, void and colourless
  objects;
- ``state`` (uint8): 0 for an object without a state, 1 + index of its state, IGNORE off objects.

Training houses (TRAIN_SEEDS) break two shortcuts of the generator: ``recolour_share`` of their
colourable objects take one of the generator's recolourings (not only the 2-3 that colour
questions ask about), and the held-out meshes (``heldout_model_keys``) never appear in them: their
objects take another model of the category. Validation houses are rendered as the generator
makes them, so their figures compare with earlier weights'.

Shards of up to SHARD_HOUSES houses are compressed ``.npz`` files; ``meta.json`` holds the
vocabulary, the houses, the frame count, the seed and the code version. Several runs into one
folder (training and validation houses) merge their ``meta.json`` when they agree.
"""

from __future__ import annotations

import hashlib
import json
import math
import multiprocessing
import os
import subprocess
import sys
import time
import zipfile
import zlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.envs.synthetic.catalog import Catalog
from efficienteqa.envs.synthetic.colours import PALETTE
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M
from efficienteqa.envs.synthetic.house import check_assets
from efficienteqa.envs.synthetic.layout import ROOM_PROGRAM, SECOND_NAMES
from efficienteqa.envs.synthetic.vocabulary import SURFACE_CATEGORIES, VOCABULARY
from efficienteqa.errors import EfficientEQAError, first_line
from efficienteqa.geometry import Pose2D, backproject
from efficienteqa.perception.floor import FLOOR_TOLERANCE_M
from efficienteqa.perception.pixels.net import IGNORE, VOID, WALL, Vocabulary, half_size
from efficienteqa.perception.pixels.segment import FLOOR_PREFIX

PERCEPTION_SEEDS = range(3000, 4000)  # every house perception may train or tune on
TRAIN_SEEDS = range(3000, 3900)
VALIDATION_SEEDS = range(3900, 3910)
# What reading a damaged .npz raises: numpy's own errors, the zip archive's and the deflate data's.
SHARD_ERRORS = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error)
STATES = ("on", "off", "open", "closed")
SHARD_HOUSES = 5
SURFACE_RANGE_M = (0.8, 1.6)
DOOR_RANGE_M = (1.0, 2.5)
_TRIES = 200  # pose draws per wanted pose before falling back to a random view
# Share of colourable objects recoloured in training houses: half, so that a category's usual
# colour is no longer its likely colour (the brief asked for at least ~40%; not tuned).
RECOLOUR_SHARE = 0.5
# Share of each category's models held out of training houses (at least one where a category
# has two or more): a fifth keeps 4 of 5 chairs for training; chosen, not tuned.
HELDOUT_SHARE = 0.2
# The catalogue kept out of training whole (with --assets sh3d-all): the smallest of the
# package's CC-BY catalogues with house-worthy pieces (34 models in 24 categories), so that
# training loses the fewest meshes; chosen by size, not tuned.
HELDOUT_CATALOGUE = "KatorLegaz"
ProgressFn = Callable[[int, int], None]


def room_types() -> tuple[str, ...]:
    """Room types in the order of the house program, the hallway last; guest rooms are their type."""
    types = dict.fromkeys(t for t in ROOM_PROGRAM if t not in SECOND_NAMES.values())
    return (*types, "hallway")


def room_type_of(name: str) -> str:
    """"guest bedroom" -> "bedroom"; other names are their type."""
    return {v: k for k, v in SECOND_NAMES.items()}.get(name, name)


def object_categories() -> tuple[str, ...]:
    """The canonical categories a house can hold, after the size splits of ``canonical_category``
    ("lamp" -> floor, table and ceiling lamp; small plants -> potted plant), sorted."""
    cats = set(VOCABULARY.values()) - {"lamp"}
    cats |= {"floor lamp", "table lamp", "ceiling lamp", "potted plant", "coffee table"}
    return tuple(sorted(cats))


def build_vocabulary() -> Vocabulary:
    cats = ("void", "wall", *(FLOOR_PREFIX + t for t in room_types()), "door", *object_categories())
    return Vocabulary(cats, tuple(PALETTE), STATES)


def code_version() -> str:
    """$EFFICIENTEQA_CODE_VERSION (set where a copy of the source runs outside its checkout,
    e.g. on a GPU machine), else ``git describe`` of the checkout this runs from, else the
    package version."""
    if os.environ.get("EFFICIENTEQA_CODE_VERSION"):
        return os.environ["EFFICIENTEQA_CODE_VERSION"]
    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty", "--tags"],
                             cwd=Path(__file__).parent, capture_output=True, text=True, timeout=10)
        if out.returncode == 0 and out.stdout.strip():
            return out.stdout.strip()
    except OSError:
        pass
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("efficienteqa")
    except PackageNotFoundError:
        return "unknown"


def parse_seeds(text: str) -> range:
    """"3000-3199" (inclusive) or "3005" -> a range; seeds must lie in PERCEPTION_SEEDS."""
    fix = f"give a range such as 3000-3199 within {PERCEPTION_SEEDS.start}-{PERCEPTION_SEEDS.stop - 1}"
    try:
        lo_text, _, hi_text = text.strip().partition("-")
        lo = int(lo_text)
        hi = int(hi_text) if hi_text else lo
    except ValueError:
        raise EfficientEQAError(f"cannot read the seed range {text!r}", fix=fix) from None
    if hi < lo:
        raise EfficientEQAError(f"the seed range {text!r} is empty", fix=fix)
    check_seeds(range(lo, hi + 1))
    return range(lo, hi + 1)


def check_seeds(seeds: range) -> None:
    outside = [s for s in (seeds.start, seeds.stop - 1) if s not in PERCEPTION_SEEDS]
    if outside or len(seeds) == 0:
        raise EfficientEQAError(
            f"house seeds {seeds.start}-{seeds.stop - 1} are not all perception training houses",
            fix=f"use seeds within {PERCEPTION_SEEDS.start}-{PERCEPTION_SEEDS.stop - 1} (other "
                "houses are for development and evaluation)")


# -- held-out meshes ----------------------------------------------------------------------------
def heldout_model_keys(catalog: Catalog | None = None) -> frozenset[str]:
    """Model keys kept out of perception training houses: every model of HELDOUT_CATALOGUE (a
    whole style the network never sees), and per catalogue and category with n >= 2 models,
    the max(1, floor(n * HELDOUT_SHARE)) keys of smallest sha256 (stable, chosen by no one).
    Grouping by catalogue keeps the CC0 catalogue's held-out meshes the same whether or not the
    other catalogues are loaded. ``catalog`` defaults to the sh3d furniture catalogue."""
    if catalog is None:
        from efficienteqa.envs.synthetic.env import catalog_for

        catalog = catalog_for("sh3d")
    keys: set[str] = set()
    for category in catalog.categories():
        groups: dict[str, list[str]] = {}
        for e in catalog.by_category(category):
            if e.catalogue == HELDOUT_CATALOGUE:
                keys.add(e.key)
            else:
                groups.setdefault(e.catalogue, []).append(e.key)
        for models in groups.values():
            models.sort(key=lambda k: hashlib.sha256(k.encode()).hexdigest())
            if len(models) >= 2:
                keys.update(models[:max(1, math.floor(len(models) * HELDOUT_SHARE))])
    return frozenset(keys)


def uses_heldout_mesh(house: Any, object_id: int, heldout: frozenset[str] | None = None) -> bool:
    """Whether object ``object_id`` of ``house`` uses a mesh that training houses never show."""
    if heldout is None:
        from efficienteqa.envs.synthetic.env import catalog_for

        heldout = heldout_model_keys(catalog_for(house.assets))
    obj = next((o for o in house.objects if o.id == object_id), None)
    if obj is None:
        raise KeyError(f"house {house.seed} has no object {object_id}")
    return obj.model_key in heldout


def training_env(house_seed: int, assets: str = "sh3d", recolour_share: float = 0.0,
                 hold_out: bool = False) -> Any:
    """The environment of a perception house: recoloured and without the held-out meshes when
    asked (training houses), else the generator's own house."""
    from efficienteqa.envs.synthetic.env import SyntheticEnv, catalog_for
    from efficienteqa.envs.synthetic.generate import generate_house

    catalog = catalog_for(assets)
    if hold_out:
        catalog = catalog.without(heldout_model_keys(catalog))
    house = generate_house(house_seed, catalog, assets, recolour_share=recolour_share)
    return SyntheticEnv(house, catalog)


# -- labels of one frame ------------------------------------------------------------------------
def frame_labels(obs: Any, house: Any, vocab: Vocabulary) -> dict[str, np.ndarray]:
    """The stored arrays of one full-size observation (``rgb``, ``depth``, ``category``,
    ``colour``, ``state``), all at half size."""
    inst = obs.instance[1::2, 1::2].astype(np.int64)
    depth_full = obs.depth_m
    rgb, depth = half_size(obs.rgb, depth_full)
    h, w = depth.shape
    # back-project the labelled pixels with their full-frame coordinates
    points = backproject(depth_full, obs.intrinsics, obs.cam_to_world)[1::2, 1::2]
    category = np.full((h, w), IGNORE, np.uint8)
    colour = np.full((h, w), IGNORE, np.uint8)
    state = np.full((h, w), IGNORE, np.uint8)
    valid = depth > 0
    category[(inst < 0) | ~valid] = VOID
    structure = (inst == 0) & valid
    floor = structure & (np.abs(points[..., 2]) < FLOOR_TOLERANCE_M)
    category[structure & ~floor] = WALL
    floor_code = {t: vocab.index(FLOOR_PREFIX + t) for t in vocab.floor_types}
    layout = house.layout
    for room in layout.rooms:  # rooms tile the plan; the first that holds a point wins
        x, y = points[..., 0], points[..., 1]
        inside = floor & (x >= room.x0) & (x <= room.x1) & (y >= room.y0) & (y <= room.y1)
        inside &= category == IGNORE
        code = floor_code.get(room_type_of(room.type))
        if code is not None:
            category[inside] = code
    ids = np.unique(inst[valid & (inst > 0)])
    colours = {c: i for i, c in enumerate(vocab.colours)}
    states = {s: i + 1 for i, s in enumerate(vocab.states)}
    by_id = {o.id: o for o in house.objects}
    for oid in ids.tolist():
        obj = by_id.get(oid)
        mask = valid & (inst == oid)
        if obj is None:
            continue
        code = vocab.index(obj.category)
        category[mask] = IGNORE if code is None else code
        colour[mask] = colours.get(obj.colour or "", IGNORE)
        state[mask] = 0 if obj.state is None else states.get(obj.state, IGNORE)
    return {"rgb": rgb, "depth": depth.astype(np.float16), "category": category,
            "colour": colour, "state": state}


# -- poses --------------------------------------------------------------------------------------
def _facing(x: float, y: float, tx: float, ty: float) -> float:
    return math.atan2(ty - y, tx - x)


def house_poses(env: Any, n: int, rng: np.random.Generator) -> list[tuple[str, Pose2D]]:
    """``n`` poses: a quarter facing surfaces with small objects, a quarter facing doors, the
    rest random (also where a surface or door view cannot be found)."""
    n_surface, n_door = round(n / 4), round(n / 4)
    nav = env.grid.navigable(ROBOT_RADIUS_M)
    cells = np.argwhere(nav)
    if len(cells) == 0:
        raise EfficientEQAError(f"house {env.house.seed} has no navigable floor")
    spec = env.grid.spec

    def random_pose() -> Pose2D:
        i, j = cells[rng.integers(len(cells))]
        x, y = spec.cell_to_world(np.array([i, j]))
        x += rng.uniform(-0.5, 0.5) * spec.resolution_m
        y += rng.uniform(-0.5, 0.5) * spec.resolution_m
        return Pose2D(float(x), float(y), float(rng.uniform(-math.pi, math.pi)))

    def facing_pose(tx: float, ty: float, lo: float, hi: float,
                    directions: Sequence[tuple[float, float]] | None) -> Pose2D | None:
        for _ in range(_TRIES):
            d = rng.uniform(lo, hi)
            if directions is None:
                a = rng.uniform(-math.pi, math.pi)
                ux, uy = math.cos(a), math.sin(a)
            else:
                ux, uy = directions[int(rng.integers(len(directions)))]
                a = math.atan2(uy, ux) + rng.uniform(-0.5, 0.5)
                ux, uy = math.cos(a), math.sin(a)
            x, y = tx + d * ux, ty + d * uy
            if env.is_navigable(x, y):
                yaw = _facing(x, y, tx, ty) + rng.uniform(-0.25, 0.25)
                return Pose2D(float(x), float(y), float(yaw))
        return None

    objects = env.house.objects
    loaded = {o.support_id for o in objects if o.support_id is not None}
    surfaces = [o for o in objects if o.category in SURFACE_CATEGORIES and o.id in loaded]
    doors = list(env.house.layout.doors)
    poses: list[tuple[str, Pose2D]] = []
    for _ in range(n_surface):
        pose = None
        if surfaces:
            s = surfaces[int(rng.integers(len(surfaces)))]
            pose = facing_pose(s.x, s.y, *SURFACE_RANGE_M, None)
        poses.append(("surface", pose) if pose else ("random", random_pose()))
    for _ in range(n_door):
        pose = None
        if doors:
            d = doors[int(rng.integers(len(doors)))]
            normal = ((0.0, 1.0), (0.0, -1.0)) if d.axis == "x" else ((1.0, 0.0), (-1.0, 0.0))
            pose = facing_pose(d.x, d.y, *DOOR_RANGE_M, normal)
        poses.append(("door", pose) if pose else ("random", random_pose()))
    while len(poses) < n:
        poses.append(("random", random_pose()))
    return poses


# -- rendering ----------------------------------------------------------------------------------
def render_house(house_seed: int, frames: int, seed: int, vocab: Vocabulary,
                 assets: str = "sh3d", recolour_share: float = 0.0,
                 hold_out: bool = False) -> dict[str, np.ndarray]:
    """The stored arrays of ``frames`` views of one house, stacked, plus ``house`` and ``kind``
    (recoloured and without held-out meshes as ``training_env`` makes it)."""
    rng = np.random.default_rng([seed, house_seed])
    with training_env(house_seed, assets, recolour_share, hold_out) as env:
        poses = house_poses(env, frames, rng)
        rows = [frame_labels(env.observe(pose), env.house, vocab) for _, pose in poses]
    out = {k: np.stack([r[k] for r in rows]) for k in rows[0]}
    out["house"] = np.full(len(rows), house_seed, np.int32)
    out["kind"] = np.array([k for k, _ in poses])
    out["pose"] = np.array([(p.x, p.y, p.yaw) for _, p in poses], np.float32)
    return out


def _render_shard(job: tuple[list[int], int, int, dict[str, Any], str, str, float]
                  ) -> tuple[str, int]:
    houses, frames, seed, vocab_json, assets, out, share = job
    vocab = Vocabulary.from_json(vocab_json)
    # only training houses are recoloured and miss the held-out meshes
    parts = [render_house(h, frames, seed, vocab, assets, share if h in TRAIN_SEEDS else 0.0,
                          h in TRAIN_SEEDS) for h in houses]
    arrays = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    path = Path(out) / shard_name(houses)
    tmp = path.with_name(path.stem + ".tmp.npz")
    np.savez_compressed(tmp, **arrays)  # type: ignore[arg-type]
    tmp.replace(path)
    return path.name, len(arrays["house"])


def shard_name(houses: Sequence[int]) -> str:
    return f"houses-{houses[0]}-{houses[-1]}.npz"


def _line_progress(done: int, total: int) -> None:
    sys.stderr.write(f"\rrendered {done}/{total} houses")
    sys.stderr.flush()
    if done == total:
        sys.stderr.write("\n")


def render_dataset(seeds: range, out: Path, frames_per_house: int = 20, seed: int = 0,
                   progress: ProgressFn | bool = True, workers: int = 2,
                   assets: str = "sh3d", recolour_share: float = RECOLOUR_SHARE
                   ) -> dict[str, Any]:
    """Render ``frames_per_house`` frames of every house in ``seeds`` into shards under ``out``
    and merge ``out/meta.json``; returns that metadata. Shards already there are kept."""
    check_seeds(seeds)
    check_assets(assets)
    if frames_per_house < 1:
        raise EfficientEQAError("--frames-per-house must be at least 1")
    if not 0.0 <= recolour_share <= 1.0:
        raise EfficientEQAError("--recolour-share must lie between 0 and 1")
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise EfficientEQAError(f"cannot write to {out}: {exc.strerror}") from None
    vocab = build_vocabulary()
    from efficienteqa.envs.synthetic.env import catalog_for

    heldout = sorted(heldout_model_keys(catalog_for(assets)))
    meta_path = out / "meta.json"
    old = json.loads(meta_path.read_text()) if meta_path.is_file() else None
    if old is not None:
        for key, value in (("vocabulary", vocab.to_json()), ("frames_per_house", frames_per_house),
                           ("seed", seed), ("assets", assets), ("recolour_share", recolour_share),
                           ("heldout_model_keys", heldout)):
            if old.get(key) != value:
                raise EfficientEQAError(f"{out} holds frames rendered with another {key}",
                                        fix="render into a new folder")
    houses = list(seeds)
    jobs = [(houses[i:i + SHARD_HOUSES], frames_per_house, seed, vocab.to_json(), assets, str(out),
             recolour_share) for i in range(0, len(houses), SHARD_HOUSES)]
    todo = [j for j in jobs if not (out / shard_name(j[0])).is_file()]
    report: ProgressFn | None = (_tqdm_progress(len(houses)) if progress is True
                                 else progress or None)
    start = time.perf_counter()
    done = len(houses) - sum(len(j[0]) for j in todo)
    if report:
        report(done, len(houses))
    if workers > 1 and len(todo) > 1:
        ctx = multiprocessing.get_context("spawn")  # one renderer (GL context) per process
        with ctx.Pool(min(workers, len(todo))) as pool:
            for job, _ in zip(todo, pool.imap(_render_shard, todo)):
                done += len(job[0])
                if report:
                    report(done, len(houses))
    else:
        for job in todo:
            _render_shard(job)
            done += len(job[0])
            if report:
                report(done, len(houses))
    all_houses = sorted(set(houses) | set(old["houses"] if old else []))
    meta = {"vocabulary": vocab.to_json(), "frames_per_house": frames_per_house, "seed": seed,
            "assets": assets, "recolour_share": recolour_share, "heldout_model_keys": heldout,
            "houses": all_houses, "frames": len(all_houses) * frames_per_house,
            "size": [240, 320], "code_version": code_version(),
            "train_seeds": [TRAIN_SEEDS.start, TRAIN_SEEDS.stop - 1],
            "validation_seeds": [VALIDATION_SEEDS.start, VALIDATION_SEEDS.stop - 1],
            "minutes": round((time.perf_counter() - start) / 60 + (old or {}).get("minutes", 0), 2)}
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
    return meta


def _tqdm_progress(total: int) -> ProgressFn:
    try:
        from tqdm import tqdm
    except ImportError:
        return _line_progress
    bar = tqdm(total=total, unit="house", desc="rendering")

    def update(done: int, _total: int) -> None:
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return update


def load_shards(data: Path, houses: Sequence[int] | None = None) -> dict[str, np.ndarray]:
    """All frames under ``data`` (of ``houses`` only, when given), concatenated. A shard that
    cannot be read whole (a copy cut short, a disk error) is one line naming it: rendering into
    the folder again renders only the shards that are missing."""
    parts = []
    for path in sorted(Path(data).glob("houses-*.npz")):
        if path.name.endswith(".tmp.npz"):
            continue
        try:
            with np.load(path) as shard:
                keep = np.ones(len(shard["house"]), bool) if houses is None else np.isin(
                    shard["house"], list(houses))
                if keep.any():
                    parts.append({k: shard[k][keep] for k in shard.files})
        except SHARD_ERRORS as exc:
            raise EfficientEQAError(f"{path} is not a readable shard of frames ({first_line(exc)})",
                                    fix="delete it and run the efficienteqa perception dataset "
                                        "command that made the folder again: it renders the "
                                        "missing shards only") from None
    if not parts:
        return {}
    try:
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    except (KeyError, ValueError) as exc:
        raise EfficientEQAError(f"the shards in {data} do not fit together ({first_line(exc)})",
                                fix="render the frames into a new folder") from None
