"""Room-appropriate furniture placement without collisions.

Objects stand against walls, in front of / beside / facing other objects, around tables, or on
surfaces. Yaws are multiples of 90 deg, so footprints are axis-aligned boxes and collision tests
are exact. Doorways (0.9 m each side) stay clear.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from efficienteqa.envs.synthetic.catalog import Catalog, CatalogEntry
from efficienteqa.envs.synthetic.house import MOUNTED_Z_M, PlacedObject
from efficienteqa.envs.synthetic.layout import WALL_THICKNESS_M, Layout, Room
from efficienteqa.envs.synthetic.mesh import MeshPart
from efficienteqa.envs.synthetic.programme import ROOM_RULES, SMALL_PER_SURFACE, SURFACES, Rule
from efficienteqa.envs.synthetic.vocabulary import SMALL_CATEGORIES

DOOR_CLEARANCE_M = 0.9
OVERHEAD_CELL_M = 0.05  # resolution of the "something above the top surface" mask


# (point on the inner wall line, inward normal, lo, hi along the wall)
_Wall = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], float, float]


@dataclass
class _Box:
    x0: float
    y0: float
    x1: float
    y1: float

    def overlaps(self, other: _Box) -> bool:
        return self.x0 < other.x1 and other.x0 < self.x1 and self.y0 < other.y1 and other.y0 < self.y1

    def inside(self, other: _Box) -> bool:
        return (self.x0 >= other.x0 - 1e-6 and self.y0 >= other.y0 - 1e-6
                and self.x1 <= other.x1 + 1e-6 and self.y1 <= other.y1 + 1e-6)


def _aabb(x: float, y: float, w: float, d: float, yaw: float, pad: float = 0.0) -> _Box:
    quarter = round(yaw / (math.pi / 2)) % 2
    hx, hy = ((w, d) if quarter == 0 else (d, w))
    return _Box(x - hx / 2 - pad, y - hy / 2 - pad, x + hx / 2 + pad, y + hy / 2 + pad)


def _front(yaw: float) -> np.ndarray:
    """World direction of a model's front (local -y) at this yaw."""
    return np.array([math.sin(yaw), -math.cos(yaw)])


def _yaw_facing(direction: np.ndarray) -> float:
    """The yaw that turns a model's front towards ``direction``."""
    return math.atan2(direction[1], direction[0]) + math.pi / 2


class _RoomFurnisher:
    def __init__(self, room: Room, keep_out: list[_Box], catalog: Catalog,
                 rng: np.random.Generator, next_id: int) -> None:
        half = WALL_THICKNESS_M / 2
        self.room, self.catalog, self.rng = room, catalog, rng
        self.interior = _Box(room.x0 + half, room.y0 + half, room.x1 - half, room.y1 - half)
        self.blocked = list(keep_out)
        self.placed: list[PlacedObject] = []
        self.next_id = next_id
        self.tables: dict[int, list[int]] = {}
        self._overhead: dict[tuple[str, float], np.ndarray] = {}

    def run(self, rules: tuple[Rule, ...]) -> None:
        for rule in rules:
            if self.rng.random() > rule.p:
                continue
            count = int(self.rng.integers(rule.count[0], rule.count[1] + 1))
            entry_cat = next((c for c in rule.categories if self.catalog.by_category(c)), None)
            if entry_cat is None:
                continue
            anchors = [o for o in self.placed if rule.anchor and o.category in _aliases(rule.anchor)]
            if rule.anchor and not anchors:
                continue
            if rule.placement == "around":
                self._around(entry_cat, anchors[0])
                continue
            for i in range(count):
                anchor = anchors[i % len(anchors)] if anchors else None
                self._place(entry_cat, rule.placement, anchor)

    def _entry(self, category: str) -> CatalogEntry:
        options = self.catalog.by_category(category)
        return options[int(self.rng.integers(len(options)))]

    def _add(self, entry: CatalogEntry, x: float, y: float, yaw: float, z: float | None = None,
             support: PlacedObject | None = None, ignore: PlacedObject | None = None
             ) -> PlacedObject | None:
        """Place ``entry`` if its footprint is free; mounted objects only avoid each other."""
        w, d, _ = entry.size_m
        z = entry.elevation_m if z is None else z
        box = _aabb(x, y, w, d, yaw)
        if support is None:
            mounted = z >= MOUNTED_Z_M
            if not box.inside(self.interior):
                return None
            if not mounted and any(box.overlaps(b) for b in self.blocked):
                return None
            if any(box.overlaps(_aabb(*o.footprint())) for o in self.placed
                   if o.support_id is None and (o.z >= MOUNTED_Z_M) == mounted and o is not ignore):
                return None
        obj = PlacedObject(
            id=self.next_id, category=entry.category, model_key=entry.key, name=entry.name,
            room_id=self.room.id, x=round(x, 3), y=round(y, 3), z=round(z, 3),
            yaw=round(yaw % (2 * math.pi), 4), size_m=entry.size_m, colour=entry.colour,
            licence=entry.licence, support_id=support.id if support else None,
        )
        self.next_id += 1
        self.placed.append(obj)
        return obj

    def _walls(self) -> list[_Wall]:
        """(point on the inner wall line, inward normal, lo, hi along the wall) for 4 walls."""
        b = self.interior
        return [
            (np.array([0.0, b.y0]), np.array([0.0, 1.0]), b.x0, b.x1),
            (np.array([0.0, b.y1]), np.array([0.0, -1.0]), b.x0, b.x1),
            (np.array([b.x0, 0.0]), np.array([1.0, 0.0]), b.y0, b.y1),
            (np.array([b.x1, 0.0]), np.array([-1.0, 0.0]), b.y0, b.y1),
        ]

    def _against_wall(self, entry: CatalogEntry, wall: _Wall, t: float) -> PlacedObject | None:
        point, normal, _, _ = wall
        along = 0 if normal[0] == 0 else 1
        pos = point + normal * (entry.size_m[1] / 2 + 0.02)
        pos[along] = t
        return self._add(entry, pos[0], pos[1], _yaw_facing(normal))

    def _place(self, category: str, placement: str, anchor: PlacedObject | None) -> None:
        """A random model of the category; if it does not fit, the others, smallest first."""
        first = self._entry(category)
        others = sorted((e for e in self.catalog.by_category(category) if e is not first),
                        key=lambda e: e.size_m[0] * e.size_m[1])
        for entry in (first, *others):
            if self._try(entry, placement, anchor) is not None:
                return

    def _try(self, entry: CatalogEntry, placement: str, anchor: PlacedObject | None
             ) -> PlacedObject | None:
        w, d, _ = entry.size_m
        if placement == "ceiling":
            cx, cy = (anchor.x, anchor.y) if anchor else self.room.centre
            return self._add(entry, cx, cy, anchor.yaw if anchor else 0.0,
                             z=max(entry.elevation_m, 1.9))
        if placement == "wall":
            return self._sampled(lambda: self._wall_sample(entry))
        if placement == "centre":
            return self._sampled(lambda: self._centre_sample(entry))
        if anchor is None:  # every other placement is relative to an anchor
            return None
        if placement == "on":
            return self._on(entry, anchor)
        if placement == "above":
            back = np.array([anchor.x, anchor.y]) - _front(anchor.yaw) * (anchor.size_m[1] - d) / 2
            return self._add(entry, back[0], back[1], anchor.yaw, z=max(entry.elevation_m, MOUNTED_Z_M))
        if placement in ("front", "faces"):
            f = _front(anchor.yaw)
            gap = 0.4 if placement == "front" else -0.1  # a chair slides under its desk
            c = np.array([anchor.x, anchor.y]) + f * (anchor.size_m[1] / 2 + gap + d / 2)
            yaw = anchor.yaw if placement == "front" else anchor.yaw + math.pi
            return self._add(entry, c[0], c[1], yaw, ignore=anchor if placement == "faces" else None)
        if placement == "beside":
            side = np.array([math.cos(anchor.yaw), math.sin(anchor.yaw)])
            c = np.array([anchor.x, anchor.y]) - _front(anchor.yaw) * (anchor.size_m[1] - d) / 2
            for sign in self.rng.permutation([-1.0, 1.0]):
                pos = c + sign * side * (anchor.size_m[0] / 2 + w / 2 + 0.05)
                if obj := self._add(entry, pos[0], pos[1], anchor.yaw):
                    return obj
            return None
        if placement == "opposite":
            return self._sampled(lambda: self._opposite_sample(entry, anchor))
        raise ValueError(f"unknown placement {placement!r}")

    @staticmethod
    def _sampled(sample: Callable[[], PlacedObject | None], tries: int = 40) -> PlacedObject | None:
        """The first placement that fits among ``tries`` random ones."""
        for _ in range(tries):
            if (obj := sample()) is not None:
                return obj
        return None

    def _wall_sample(self, entry: CatalogEntry) -> PlacedObject | None:
        """Against a random wall, at a random point along it."""
        w = entry.size_m[0]
        wall = self._walls()[int(self.rng.integers(4))]
        if wall[3] - wall[2] < w:
            return None
        return self._against_wall(entry, wall, self.rng.uniform(wall[2] + w / 2, wall[3] - w / 2))

    def _centre_sample(self, entry: CatalogEntry) -> PlacedObject | None:
        """Near the room centre, its long side along the room's."""
        w, d, _ = entry.size_m
        cx, cy = self.room.centre
        long_x = (self.interior.x1 - self.interior.x0) >= (self.interior.y1 - self.interior.y0)
        yaw = 0.0 if long_x == (w >= d) else math.pi / 2
        return self._add(entry, cx + self.rng.normal(0, 0.2), cy + self.rng.normal(0, 0.2), yaw)

    def _opposite_sample(self, entry: CatalogEntry, anchor: PlacedObject) -> PlacedObject | None:
        """On the wall the anchor faces, near the anchor's position along it."""
        f = _front(anchor.yaw)
        wall = next(wl for wl in self._walls() if np.allclose(wl[1], -f, atol=1e-3))
        along = 0 if wall[1][0] == 0 else 1
        return self._against_wall(entry, wall, (anchor.x, anchor.y)[along] + self.rng.normal(0, 0.3))

    def _on(self, entry: CatalogEntry, support: PlacedObject) -> PlacedObject | None:
        """On the support's top surface, clear of its siblings and of any part of the support
        that rises above that surface (the upper shelves of a bookcase, a cabinet's tall side)."""
        top = self.catalog.entry(support.model_key).top_m or support.size_m[2]
        sw, sd, _ = support.size_m
        w, d, _ = entry.size_m
        if w > sw + 0.02 or d > sd + 0.02:
            return None
        key = (support.model_key, round(entry.size_m[2], 2))
        if key not in self._overhead:
            self._overhead[key] = overhead_mask(self.catalog.mesh(support.model_key), top,
                                                support.size_m, clear_m=entry.size_m[2] + 0.02)
        overhead = self._overhead[key]
        siblings = [o for o in self.placed if o.support_id == support.id]
        rot = np.array([[math.cos(support.yaw), -math.sin(support.yaw)],
                        [math.sin(support.yaw), math.cos(support.yaw)]])
        for _ in range(20):
            half_free = np.maximum([(sw - w) / 2 * 0.8, (sd - d) / 2 * 0.8], 0.0)
            local = self.rng.uniform(-half_free, half_free)
            if _covered(overhead, support.size_m, local, (w, d)):
                continue
            x, y = np.array([support.x, support.y]) + rot @ local
            box = _aabb(x, y, w, d, support.yaw, pad=0.03)
            if any(box.overlaps(_aabb(*o.footprint())) for o in siblings):
                continue
            return self._add(entry, x, y, support.yaw, z=support.z + top, support=support)
        return None

    def _around(self, category: str, table: PlacedObject) -> None:
        """Chairs along the table's long sides, facing it; the count is recorded."""
        entry = self._entry(category)
        tw, td, _ = table.size_m
        long_local = 0 if tw >= td else 1
        length = max(tw, td)
        per_side = max(1, int(length // 0.6))
        rot = np.array([[math.cos(table.yaw), -math.sin(table.yaw)],
                        [math.sin(table.yaw), math.cos(table.yaw)]])
        seats = []
        for side in (1.0, -1.0):
            for k in range(per_side):
                off = np.zeros(2)
                off[long_local] = (k + 0.5) * length / per_side - length / 2
                off[1 - long_local] = side * ((td if long_local == 0 else tw) / 2 + entry.size_m[1] / 2 - 0.1)
                facing = -np.sign(off[1 - long_local]) * np.eye(2)[1 - long_local]
                seats.append((np.array([table.x, table.y]) + rot @ off, rot @ facing))
        wanted = int(self.rng.integers(2, len(seats) + 1))
        chairs: list[int] = []
        for idx in self.rng.permutation(len(seats)):
            if len(chairs) == wanted:
                break
            pos, facing = seats[int(idx)]
            chair = self._add(entry, pos[0], pos[1], _yaw_facing(facing), ignore=table)
            if chair:
                chairs.append(chair.id)
        self.tables[table.id] = chairs


def overhead_mask(parts: list[MeshPart], top_m: float, size_m: tuple[float, float, float],
                  clear_m: float, cell_m: float = OVERHEAD_CELL_M) -> np.ndarray:
    """(ny, nx) bool over a model's footprint in its local frame (cells of ``cell_m`` from
    (-width/2, -depth/2)): True where part of the model lies between 3 cm and ``clear_m``
    above ``top_m`` (the next shelf up, a cabinet's tall side), so an object that tall would
    cut into it. Triangles are sampled densely enough that large panels leave no gaps."""
    w, d, _ = size_m
    nx, ny = max(1, math.ceil(w / cell_m)), max(1, math.ceil(d / cell_m))
    mask = np.zeros((ny, nx), bool)
    for part in parts:
        tri = part.positions[part.faces]
        z = tri[:, :, 2]
        tri = tri[(z.max(axis=1) > top_m + 0.03) & (z.min(axis=1) < top_m + clear_m)]
        tri = tri[:, :, :2].astype(float)
        if not len(tri):
            continue
        longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
        for k in np.unique(np.clip(np.ceil(longest / cell_m), 1, 60).astype(int)):
            u, v = np.meshgrid(np.linspace(0, 1, k + 1), np.linspace(0, 1, k + 1))
            keep = u + v <= 1 + 1e-9
            bary = np.stack([u[keep], v[keep], 1 - u[keep] - v[keep]], axis=1)
            group = tri[np.ceil(np.clip(longest / cell_m, 1, 60)).astype(int) == k]
            pts = np.einsum("sb,tbc->tsc", bary, group).reshape(-1, 2)
            j = np.clip(((pts[:, 0] + w / 2) / cell_m).astype(int), 0, nx - 1)
            i = np.clip(((pts[:, 1] + d / 2) / cell_m).astype(int), 0, ny - 1)
            mask[i, j] = True
    # A solid block crossing the band shows only its walls: its inside is enclosed, so fill it.
    return ndimage.binary_fill_holes(mask)


def _covered(mask: np.ndarray, support_size: tuple[float, float, float],
             centre: np.ndarray, size: tuple[float, float]) -> bool:
    """Whether a (w, d) box centred at ``centre`` (support frame) touches a masked cell."""
    sw, sd, _ = support_size
    ny, nx = mask.shape
    j0, j1 = (int((centre[0] + s * size[0] / 2 + sw / 2) / OVERHEAD_CELL_M) for s in (-1, 1))
    i0, i1 = (int((centre[1] + s * size[1] / 2 + sd / 2) / OVERHEAD_CELL_M) for s in (-1, 1))
    return bool(mask[max(i0, 0):min(i1, ny - 1) + 1, max(j0, 0):min(j1, nx - 1) + 1].any())


def _aliases(category: str) -> tuple[str, ...]:
    return {"dining table": ("dining table", "table")}.get(category, (category,))


def furnish(layout: Layout, catalog: Catalog, rng: np.random.Generator
            ) -> tuple[list[PlacedObject], dict[int, list[int]]]:
    """Objects for every room, and {table id: chair ids} for the dining tables. Doorways stay
    clear; the start pose is chosen afterwards where the floor is open."""
    keep_out = [
        _Box(d.x - d.width_m / 2 - 0.1, d.y - DOOR_CLEARANCE_M, d.x + d.width_m / 2 + 0.1,
             d.y + DOOR_CLEARANCE_M) if d.axis == "x" else
        _Box(d.x - DOOR_CLEARANCE_M, d.y - d.width_m / 2 - 0.1, d.x + DOOR_CLEARANCE_M,
             d.y + d.width_m / 2 + 0.1)
        for d in layout.doors
    ]
    objects: list[PlacedObject] = []
    tables: dict[int, list[int]] = {}
    small = sorted(c for c in catalog.categories() if c in SMALL_CATEGORIES)
    for room in layout.rooms:
        furnisher = _RoomFurnisher(room, keep_out, catalog, rng, next_id=len(objects) + 1)
        furnisher.run(ROOM_RULES.get(room.type, ()))
        for surface in [o for o in furnisher.placed if o.category in SURFACES and o.support_id is None]:
            for _ in range(int(rng.integers(SMALL_PER_SURFACE[0], SMALL_PER_SURFACE[1] + 1))):
                if small:
                    furnisher._on(furnisher._entry(small[int(rng.integers(len(small)))]), surface)
        objects += furnisher.placed
        tables.update(furnisher.tables)
    return objects, tables
