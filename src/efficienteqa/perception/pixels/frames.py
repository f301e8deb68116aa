"""The labelled frames of one house: the label vocabulary, the labels of one observation, the
poses of a house's frames and their rendering.

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

Kept apart from the shards (``dataset``): pictures, benchmarks and the evaluation pose and label
single frames without writing a data folder.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from efficienteqa.envs.synthetic.colours import PALETTE
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M
from efficienteqa.envs.synthetic.layout import ROOM_PROGRAM, SECOND_NAMES
from efficienteqa.envs.synthetic.vocabulary import SURFACE_CATEGORIES, VOCABULARY
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D, backproject
from efficienteqa.perception.floor import FLOOR_TOLERANCE_M
from efficienteqa.perception.pixels.houses import training_env
from efficienteqa.perception.pixels.net import IGNORE, VOID, WALL, Vocabulary, half_size
from efficienteqa.perception.pixels.segment import FLOOR_PREFIX

STATES = ("on", "off", "open", "closed")
SURFACE_RANGE_M = (0.8, 1.6)
DOOR_RANGE_M = (1.0, 2.5)
_TRIES = 200  # pose draws per wanted pose before falling back to a random view


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

