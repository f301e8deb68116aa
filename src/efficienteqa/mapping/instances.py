"""Objects as 3-D instances of an episode's map (beyond the paper, DESIGN 9).

A frame shows objects as regions: pixels of one object, or what a perception takes for one. Each
region comes lifted to world points (the perception backprojects its pixels with depth,
intrinsics and pose) and joins the map, which keeps per object instance: the CELL_M voxels (in
3-D: a cup on a table is not the table) its regions covered, its category votes (the regions'
confidences, summed), its colour and room votes, what it stands on (the region relation the
describer computes, as votes for the instance under it), the frames that saw it, its highest
point, and its place (the middle of its voxels' columns: of everything seen of it, not of one
view).

A region joins an instance of its category whose voxels it shares OVERLAP of (of the smaller
set), or whose place lies within ``reach`` (half the instance's size, within REACH_M), best
matches first and one region per instance per frame: two chairs side by side in one view are
two, however close; a region of another category joins one whose voxels and its own share
CROSS_OVERLAP of their union (one chair called an armchair in one view). A region left over that
lies mostly (PIECE) in the voxels of an instance of its category this frame saw is a piece of it
(a chair cut in two by the network). A region that also fits an instance never seen with its own
in one frame, and placed within reach, merges the two. Two instances of different categories
that are mostly the same voxels (ABSORB of the smaller's, ABSORB_LARGER of the larger's) are one
object when one has at most ABSORB_WEAKER of the other's votes: the weaker joins (the network
naming a table's pedestal a chair, or a chair's seat a table).

An instance is *sure* when its category's votes reach SURE: one view the perception is sure of,
or several unsure ones (an object seen unsurely in three views is one sure object).

A perception that knows which regions are one object (the semantic sensor's object ids) says so
with the region's ``key``: one instance per key, nothing merged by place or category. Counting
reads the map (``count``, ``asked_count``): the sure instances of the object within AROUND_M of
a sure support's footprint, not under it (inside its footprint less its rim: a pedestal), in
the room asked about.

Pure numpy and scipy: arrays in, arrays out; the perceptions fill it (``perception.semantic``,
``perception.pixels.backend``, ``perception.sightings``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TypeVar

import numpy as np
from scipy import ndimage

if TYPE_CHECKING:
    from efficienteqa.question import Target

CELL_M = 0.15  # voxel edge: about the smallest objects' size, a chair's seat is 3x3 cells
OVERLAP = 0.25  # a region joins an instance of its category sharing this share of the smaller
# voxel set
CROSS_OVERLAP = 0.5  # ... or one of another category sharing this share of the union
PIECE = 0.5  # a frame's second region with this share of its voxels in one instance is a piece
# of it (a chair's back and legs, cut apart by the network), not another object
REACH_M = (0.2, 0.45)  # or one whose place is within half its own size, clamped to this
ABSORB, ABSORB_LARGER = 0.5, 0.1  # instances of two categories sharing this share of the smaller
# one's voxels and of the larger one's are one object (``InstanceMap._absorb_other_categories``)
ABSORB_WEAKER = 0.5  # ... when one has at most this share of the other's votes
SURE = 0.6  # summed confidence of an instance's category that makes it sure (one sure view)
NEAR_M = 0.6  # instances whose voxels come no nearer a region's place than this are not it
AROUND_M = 1.0  # a count group's member stands this close to its support's footprint ("around
# the table")
_OFFSET = 1 << 15  # keeps cell indices non-negative for the packed key
K = TypeVar("K")


def cell_keys(points: np.ndarray) -> np.ndarray:
    """The packed keys of the CELL_M voxels that world points (N, 3) fall in, unique."""
    if not len(points):
        return np.zeros(0, np.int64)
    cells = np.floor(np.asarray(points, np.float64) / CELL_M).astype(np.int64) + _OFFSET
    return np.unique((cells[:, 0] << 32) | (cells[:, 1] << 16) | cells[:, 2])


@dataclass(frozen=True)
class Region:
    """One object as a frame shows it: its ``category``, world ``points`` (N, 3; any stride),
    the perception's ``confidence`` in the category (0-1), its ``colour`` and ``room`` when
    the perception names them, ``key`` (an identity the perception already knows, as the
    semantic sensor's object ids: one instance per key), ``support`` (the index, among the
    frame's regions, of the region it stands on) and ``cut`` (the frame's edge cuts it)."""

    category: str
    points: np.ndarray = field(repr=False, compare=False)
    confidence: float = 1.0
    colour: str | None = None
    room: str | None = None
    key: int | None = None
    support: int | None = None
    cut: bool = False


@dataclass
class Instance:
    """One object of the map (module docstring)."""

    id: int
    votes: dict[str, float] = field(default_factory=dict)  # category -> summed confidence
    colours: dict[str, float] = field(default_factory=dict)
    rooms: dict[str, float] = field(default_factory=dict)
    supports: dict[int, float] = field(default_factory=dict)  # instance under it -> votes
    cells: set[int] = field(default_factory=set, repr=False)
    frames: list[int] = field(default_factory=list)
    key: int | None = None
    top_m: float = -math.inf  # the highest of its regions' tops (95th percentile of z)
    lo: tuple[int, int] = (1 << 30, 1 << 30)  # the cell columns its voxels span (packed
    hi: tuple[int, int] = (-1, -1)  # indices, for finding the instances near a place)

    @property
    def category(self) -> str:
        return _best(self.votes) or ""

    @property
    def confidence(self) -> float:
        """The summed confidence of its category over the views that saw it."""
        return self.votes.get(self.category, 0.0)

    @property
    def sure(self) -> bool:
        return self.confidence >= SURE

    @property
    def colour(self) -> str | None:
        return _best(self.colours)

    @property
    def room(self) -> str | None:
        return _best(self.rooms)

    @property
    def support(self) -> int | None:
        """The instance it stands on, by the frames' votes (None: on the floor, or unseen)."""
        return _best(self.supports)

    @property
    def views(self) -> int:
        return len(self.frames)

    @property
    def xy(self) -> tuple[float, float]:
        """Its place on the floor: the middle of the columns of its voxels (of what the views
        have seen of it, not of one view: a long table seen by halves is placed at its
        middle)."""
        if not self.cells:
            return (math.nan, math.nan)
        columns = self.columns
        return (float(columns[:, 0].mean()), float(columns[:, 1].mean()))

    @property
    def columns(self) -> np.ndarray:
        """The centres (x, y, metres) of the columns of its voxels, (N, 2)."""
        packed = np.unique(np.fromiter(self.cells, np.int64, len(self.cells)) >> 16)
        return ((np.stack([packed >> 16, packed & 0xFFFF], axis=1) - _OFFSET) + 0.5) * CELL_M

    def _add(self, region: Region, frame: int, cells: np.ndarray, xy: np.ndarray) -> None:
        w = max(region.confidence, 1e-3)
        _vote(self.votes, region.category, region.confidence)
        if region.colour is not None:
            _vote(self.colours, region.colour, w)
        if region.room is not None:
            _vote(self.rooms, region.room, w)
        self.cells.update(cells.tolist())
        self._span(cells)
        self.top_m = max(self.top_m, float(np.percentile(region.points[:, 2], 95)))
        if frame not in self.frames:
            self.frames.append(frame)

    def _span(self, cells: np.ndarray) -> None:
        if len(cells):
            x, y = cells >> 32, (cells >> 16) & 0xFFFF
            self.lo = (min(self.lo[0], int(x.min())), min(self.lo[1], int(y.min())))
            self.hi = (max(self.hi[0], int(x.max())), max(self.hi[1], int(y.max())))

    def _absorb(self, other: Instance) -> None:
        for mine, theirs in ((self.votes, other.votes), (self.colours, other.colours),
                             (self.rooms, other.rooms)):
            for k, v in theirs.items():
                _vote(mine, k, v)
        for i, v in other.supports.items():
            _vote(self.supports, i, v)
        self.cells |= other.cells
        self.lo = (min(self.lo[0], other.lo[0]), min(self.lo[1], other.lo[1]))
        self.hi = (max(self.hi[0], other.hi[0]), max(self.hi[1], other.hi[1]))
        self.top_m = max(self.top_m, other.top_m)
        self.frames = sorted(set(self.frames) | set(other.frames))


def _vote(votes: dict[K, float], key: K, weight: float) -> None:
    votes[key] = votes.get(key, 0.0) + weight


def _best(votes: dict[K, float]) -> K | None:
    """The key with the most votes (ties: the first voted), None for none."""
    return max(votes, key=votes.__getitem__) if votes else None


@dataclass(frozen=True)
class FrameInstances:
    """What one frame added to the map: the instance of each of its regions, in their order,
    and whether the frame's edge cuts it."""

    frame: int
    ids: tuple[int, ...]
    cut: tuple[bool, ...]

    def seen(self, instance_id: int) -> bool:
        return instance_id in self.ids

    def whole(self, instance_id: int) -> bool:
        """In the frame and not cut by its edge (in any of its regions)."""
        return any(i == instance_id and not c for i, c in zip(self.ids, self.cut)) and not any(
            i == instance_id and c for i, c in zip(self.ids, self.cut))


class InstanceMap:
    """An episode's object instances (module docstring). ``add`` one frame's regions at a
    time; ``reset`` as an episode starts."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self._instances: dict[int, Instance] = {}
        self._by_key: dict[int, int] = {}
        self._next = 1
        self._frames = 0
        self._merged: dict[int, int] = {}  # an instance that joined another -> that one

    def __len__(self) -> int:
        return len(self._instances)

    def __iter__(self) -> Iterator[Instance]:
        return iter(list(self._instances.values()))

    def __getitem__(self, instance_id: int) -> Instance:
        return self._instances[instance_id]

    @property
    def ids(self) -> set[int]:
        return set(self._instances)

    def instances(self, sure: bool = True) -> list[Instance]:
        """The instances, the sure ones only unless ``sure`` is False, oldest first."""
        return [i for i in self._instances.values() if i.sure or not sure]

    def add(self, regions: Sequence[Region]) -> FrameInstances:
        """One frame's regions: each joins an instance or starts one (module docstring).
        Regions without points are left out."""
        frame = self._frames
        self._frames += 1
        kept = [r for r in regions if len(r.points)]
        index = {id(r): k for k, r in enumerate(kept)}
        supports = [index.get(id(regions[r.support])) if r.support is not None
                    and 0 <= r.support < len(regions) else None for r in kept]
        cells = [cell_keys(r.points) for r in kept]
        xys = [np.median(r.points[:, :2], axis=0) for r in kept]
        ids: list[int] = [0] * len(kept)  # 0: not yet placed
        for k, r in enumerate(kept):  # an identity the perception knows: its instance
            if r.key is not None:
                if r.key not in self._by_key:
                    self._by_key[r.key] = self._new(r.key)
                ids[k] = self._by_key[r.key]
        # the others: best matches first, one region per instance
        pairs = sorted((-score, k, inst.id) for k, r in enumerate(kept) if r.key is None
                       for inst in self._near(xys[k])
                       for score in (_match(r, cells[k], xys[k], inst),) if score > 0)
        taken: set[int] = set()
        for _, k, i in pairs:
            if not ids[k] and i not in taken:
                ids[k] = i
                taken.add(i)
        for k, r in enumerate(kept):  # a region left over that lies mostly in the voxels of
            if not ids[k] and r.key is None:  # an instance this frame saw: a piece of it
                ids[k] = next((i for i in taken if self._instances[i].category == r.category
                               and _inside(cells[k], self._instances[i])), 0)
            ids[k] = ids[k] or self._new(None)
            self._instances[ids[k]]._add(r, frame, cells[k], xys[k])
        for k, r in enumerate(kept):  # it also fits an instance never seen with its own
            if r.key is None:
                self._bridge(ids[k], r, cells[k], xys[k], set(ids))
        for i in dict.fromkeys(ids):  # one object seen as two categories: the weaker joins
            if i in self._instances:
                self._absorb_other_categories(i)
        ids = [self.current(i) for i in ids]
        for k, r in enumerate(kept):
            below = supports[k]
            if below is not None and ids[below] != ids[k]:
                _vote(self._instances[ids[k]].supports, ids[below], max(r.confidence, 1e-3))
        return FrameInstances(frame, tuple(ids), tuple(r.cut for r in kept))

    def _near(self, xy: np.ndarray) -> list[Instance]:
        """The unkeyed instances a region whose place is ``xy`` may be: those whose voxels
        come within NEAR_M of it."""
        x, y = (np.floor(np.asarray(xy) / CELL_M).astype(np.int64) + _OFFSET).tolist()
        pad = int(math.ceil(NEAR_M / CELL_M))
        return [i for i in self._instances.values() if i.key is None and i.cells
                and i.lo[0] - pad <= x <= i.hi[0] + pad and i.lo[1] - pad <= y <= i.hi[1] + pad]

    def _bridge(self, i: int, region: Region, cells: np.ndarray, xy: np.ndarray,
                this_frame: set[int]) -> None:
        """Instances of the region's category that the region of instance ``i`` also fits,
        never seen with ``i`` in one frame and whose places lie within either's ``reach``,
        join ``i`` (two views of one chair that shared too little to meet)."""
        mine = self._instances[i]
        for other in self._near(xy):
            if (other.id != i and other.id not in this_frame
                    and not set(other.frames) & set(mine.frames)
                    and math.dist(mine.xy, other.xy) <= max(reach(mine), reach(other))
                    and _match(region, cells, xy, other) > 0):
                self._join(mine, other)

    def _join(self, keep: Instance, gone: Instance) -> None:
        keep._absorb(gone)
        del self._instances[gone.id]
        self._merged[gone.id] = keep.id
        for s in self._instances.values():  # what stood on it stands on the one it joined
            if gone.id in s.supports:
                _vote(s.supports, keep.id, s.supports.pop(gone.id))

    def current(self, i: int) -> int:
        """The instance ``i`` is now (the one it joined, if it joined another)."""
        while i in self._merged:
            i = self._merged[i]
        return i

    def _absorb_other_categories(self, i: int) -> None:
        """Instance ``i`` and any instance of another category that is mostly the same
        voxels (ABSORB of the smaller's, ABSORB_LARGER of the larger's: the network naming
        the pedestal of a table a chair, or a chair's seat a table) are one object when one
        has at most ABSORB_WEAKER of the other's votes: the weaker joins the stronger. Keyed
        instances never join."""
        inst = self._instances[i]
        if inst.key is not None:
            return
        for other in self._near(np.asarray(inst.xy)):
            if other.id == i or other.category == inst.category or other.id not in self._instances:
                continue
            shared = len(inst.cells & other.cells)
            small, large = sorted((len(inst.cells), len(other.cells)))
            keep, gone = (inst, other) if inst.confidence >= other.confidence else (other, inst)
            if (shared >= ABSORB * small and shared >= ABSORB_LARGER * large
                    and gone.confidence <= ABSORB_WEAKER * keep.confidence):
                self._join(keep, gone)
                inst = keep

    def _new(self, key: int | None) -> int:
        i = self._next
        self._next += 1
        self._instances[i] = Instance(i, key=key)
        return i

    def group(self, is_member: Callable[[str], bool], supports: Iterable[int],
              within_m: float = AROUND_M, sure: bool = True) -> list[Instance]:
        """The sure instances whose category ``is_member`` accepts and whose place lies within
        ``within_m`` of the footprint (the voxel columns) of any of the instances ``supports``,
        and not under one: inside its footprint less its rim (``under``; the pedestal of a
        table the network calls a chair is not a chair around it)."""
        around = [self._instances[s] for s in supports if s in self._instances]
        return [i for i in self.instances(sure) if is_member(i.category) and i.id not in
                {s.id for s in around} and any(_reaches(i.xy, s, within_m) for s in around)
                and not any(under(i.xy, s) for s in around)]


def _reaches(xy: tuple[float, float], inst: Instance, within_m: float) -> bool:
    """Whether a place lies within ``within_m`` of an instance's footprint."""
    d = inst.columns - np.asarray(xy)
    return bool(len(d)) and float(np.min(np.hypot(d[:, 0], d[:, 1]))) <= within_m


def under(xy: tuple[float, float], inst: Instance) -> bool:
    """Whether a place lies inside an instance's footprint on the floor (the columns of its
    voxels, holes filled) less its rim of one cell."""
    columns = np.array(sorted({(c >> 32, (c >> 16) & 0xFFFF) for c in inst.cells}), np.int64)
    if not len(columns) or math.isnan(xy[0]):
        return False
    lo = columns.min(axis=0) - 1
    grid = np.zeros(tuple(columns.max(axis=0) - lo + 2), bool)
    grid[tuple((columns - lo).T)] = True
    inner = ndimage.binary_erosion(ndimage.binary_fill_holes(ndimage.binary_closing(grid)))
    ij = np.floor(np.asarray(xy) / CELL_M).astype(np.int64) + _OFFSET - lo
    return bool(np.all(ij >= 0) and np.all(ij < inner.shape) and inner[tuple(ij)])


def reach(inst: Instance) -> float:
    """How far from an instance's place a region of its category may lie and still be it:
    half the instance's size on the floor (the side of a square of its floor cells), within
    REACH_M."""
    columns = {c >> 16 for c in inst.cells}
    size = math.sqrt(len(columns)) * CELL_M
    return min(max(size / 2, REACH_M[0]), REACH_M[1])


def _inside(cells: np.ndarray, inst: Instance) -> bool:
    """Whether PIECE of a region's voxels are an instance's."""
    return len(cells) > 0 and sum(1 for c in cells.tolist() if c in inst.cells) >= PIECE * len(cells)


def _match(region: Region, cells: np.ndarray, xy: np.ndarray, inst: Instance) -> float:
    """How well a region fits an instance: 0 for not at all, else larger for more shared
    voxels (module docstring)."""
    if not len(cells) or not inst.cells:
        return 0.0
    shared = sum(1 for c in cells.tolist() if c in inst.cells)
    if region.category != inst.category:
        union = len(cells) + len(inst.cells) - shared
        return shared / union if shared / union >= CROSS_OVERLAP else 0.0
    share = shared / min(len(cells), len(inst.cells))
    near = math.dist((float(xy[0]), float(xy[1])), inst.xy) <= reach(inst)
    if share >= OVERLAP or near:
        return share + 1e-3  # a near region sharing nothing still matches, after any that do
    return 0.0


@dataclass(frozen=True)
class Count:
    """How many sure instances of a kind the map holds in the place asked: ``n``, and the
    support they stand around (None: counted in the room, around nothing)."""

    n: int
    support: int | None


def count(instances: InstanceMap, is_member: Callable[[str], bool],
          is_support: Callable[[str], bool] | None = None,
          in_place: Callable[[Instance], bool] = lambda i: True) -> Count | None:
    """The count a question asks for: the sure members around the sure support (of those
    ``in_place``, the room asked about) with the most of them (ties: the support seen in most
    views), or, with no ``is_support``, the sure members ``in_place``. None when the map holds
    no such support, or no member at all."""
    if is_support is None:
        n = sum(1 for i in instances.instances() if is_member(i.category) and in_place(i))
        return Count(n, None) if n else None
    best: tuple[int, int, int] | None = None
    for s in instances.instances():
        if is_support(s.category) and in_place(s):
            key = (len(instances.group(is_member, [s.id])), s.views, -s.id)
            best = key if best is None or key > best else best
    return Count(best[0], -best[2]) if best is not None else None


def asked_count(instances: InstanceMap | None, target: Target) -> Count | None:
    """The count a count question's target asks for from an episode's instance map: its
    object (``Target.is_a``, aliases included) around its support, when it names one, in the
    room it names (an instance whose room no frame named counts there). None for another kind
    of question, or when the map holds none."""
    if instances is None or target.kind != "count" or not target.object:
        return None
    room = target.room if len(target.rooms) == 1 else None
    obj, support = target.object, target.support
    return count(instances, lambda c: target.is_a(obj, c),
                 (lambda c: target.is_a(support, c)) if support else None,
                 lambda i: room is None or i.room in (None, room))
