"""Floor plans: rectangular rooms tiling a rectangle, doors between them, walls around them.

Pure and seeded: ``generate_layout(rng, n_rooms)`` returns the same plan for the same generator
state. Coordinates are metres in the canonical frame, the house spans [0, width] x [0, depth].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

WALL_THICKNESS_M = 0.1
WALL_HEIGHT_M = 2.7
DOOR_WIDTH_M = 1.0  # wide enough for a robot planning on a 0.1 m map
DOOR_HEIGHT_M = 2.1
MIN_ROOM_SIDE_M = 2.8
HALLWAY_WIDTH_M = 1.6

# Non-hallway room types in the order they are added as houses grow.
ROOM_PROGRAM = (
    "living room", "kitchen", "bedroom", "bathroom", "dining room", "office", "bedroom",
    "bathroom",
)
SECOND_NAMES = {"bedroom": "guest bedroom", "bathroom": "guest bathroom"}


@dataclass(frozen=True)
class Room:
    """An axis-aligned room; (x0, y0)-(x1, y1) are the wall centre lines."""

    id: int
    type: str
    name: str
    x0: float
    y0: float
    x1: float
    y1: float

    @property
    def area_m2(self) -> float:
        return (self.x1 - self.x0) * (self.y1 - self.y0)

    @property
    def centre(self) -> tuple[float, float]:
        return ((self.x0 + self.x1) / 2, (self.y0 + self.y1) / 2)

    def contains(self, x: float, y: float, margin: float = 0.0) -> bool:
        return self.x0 + margin <= x <= self.x1 - margin and self.y0 + margin <= y <= self.y1 - margin


@dataclass(frozen=True)
class Door:
    """A door opening in a wall. ``axis`` is the wall direction ("x": wall along x).

    (x, y) is the opening centre on the wall line; room_b = -1 for the front door.
    """

    id: int
    room_a: int
    room_b: int
    x: float
    y: float
    axis: str
    width_m: float = DOOR_WIDTH_M
    open: bool = True

    @property
    def interval(self) -> tuple[float, float]:
        """The opening along the wall line."""
        c = self.x if self.axis == "x" else self.y
        return (c - self.width_m / 2, c + self.width_m / 2)


@dataclass(frozen=True)
class Wall:
    """A straight wall box from z = z0 to z1 with its centre line (x0, y0)-(x1, y1)."""

    x0: float
    y0: float
    x1: float
    y1: float
    z0: float = 0.0
    z1: float = WALL_HEIGHT_M
    thickness_m: float = WALL_THICKNESS_M


@dataclass(frozen=True)
class Layout:
    width_m: float
    depth_m: float
    rooms: tuple[Room, ...]
    doors: tuple[Door, ...]
    walls: tuple[Wall, ...]

    def room_at(self, x: float, y: float) -> Room | None:
        for room in self.rooms:
            if room.contains(x, y):
                return room
        return None


def generate_layout(rng: np.random.Generator, n_rooms: int) -> Layout:
    """A connected plan of ``n_rooms`` rooms (5-9; a hallway is one of them from 6 up)."""
    if not 5 <= n_rooms <= 9:
        raise ValueError(f"n_rooms must be 5-9, got {n_rooms}")
    has_hallway = n_rooms >= 6
    n_plain = n_rooms - int(has_hallway)
    for _ in range(100):  # rejection sampling keeps every room at least MIN_ROOM_SIDE_M wide
        area = n_plain * rng.uniform(13.0, 18.0) + (6.0 if has_hallway else 0.0)
        aspect = rng.uniform(1.25, 1.6)
        width = round(float(np.sqrt(area * aspect)), 1)
        depth = round(area / width, 1)
        if has_hallway:
            depth = max(depth, 2 * MIN_ROOM_SIDE_M + HALLWAY_WIDTH_M + 0.4)
            rects = _corridor_plan(rng, width, depth, n_plain)
        else:
            rects = _bsp(rng, (0.0, 0.0, width, depth), n_plain)
        if min(min(r[2] - r[0], r[3] - r[1]) for r in rects[:n_plain]) >= MIN_ROOM_SIDE_M - 0.05:
            break
    types = _assign_types(rng, rects[: n_plain])
    rooms = [Room(i, t, n, *r) for i, (r, (t, n)) in enumerate(zip(rects, types))]
    if has_hallway:
        rooms.append(Room(len(rooms), "hallway", "hallway", *rects[-1]))
    doors = _place_doors(rng, rooms)
    return Layout(width, depth, tuple(rooms), tuple(doors), tuple(_build_walls(rooms, doors)))


Rect = tuple[float, float, float, float]


def _split_lengths(rng: np.random.Generator, length: float, parts: int) -> list[float]:
    """Cut positions dividing ``length`` into ``parts`` pieces, none under MIN_ROOM_SIDE_M."""
    weights = rng.uniform(0.8, 1.25, parts)
    sizes = MIN_ROOM_SIDE_M + (length - parts * MIN_ROOM_SIDE_M) * weights / weights.sum()
    return [round(float(c), 1) for c in np.cumsum(sizes)[:-1]]


def _bsp(rng: np.random.Generator, rect: Rect, n: int) -> list[Rect]:
    """Split ``rect`` recursively into ``n`` rooms, cutting across the longer side."""
    if n == 1:
        return [rect]
    x0, y0, x1, y1 = rect
    n_left = n // 2 if rng.random() < 0.5 else n - n // 2
    along_x = (x1 - x0) >= (y1 - y0)
    span = (x1 - x0) if along_x else (y1 - y0)
    frac = n_left / n * rng.uniform(0.85, 1.15)
    cut = float(np.clip(span * frac, n_left * MIN_ROOM_SIDE_M, span - (n - n_left) * MIN_ROOM_SIDE_M))
    cut = round(cut, 1)
    if along_x:
        return _bsp(rng, (x0, y0, x0 + cut, y1), n_left) + _bsp(rng, (x0 + cut, y0, x1, y1), n - n_left)
    return _bsp(rng, (x0, y0, x1, y0 + cut), n_left) + _bsp(rng, (x0, y0 + cut, x1, y1), n - n_left)


def _corridor_plan(rng: np.random.Generator, width: float, depth: float, n: int) -> list[Rect]:
    """Rooms on both sides of a hallway that runs along x; the hallway rectangle comes last."""
    rooms_depth = depth - HALLWAY_WIDTH_M  # split between the two sides, neither too shallow
    y_hall = round(float(np.clip(rng.uniform(0.42, 0.58) * rooms_depth, MIN_ROOM_SIDE_M,
                                 rooms_depth - MIN_ROOM_SIDE_M)), 1)
    y_top = y_hall + HALLWAY_WIDTH_M
    n_south = n // 2 + int(rng.random() < 0.5 and n % 2 == 1)
    rects: list[Rect] = []
    for count, (ya, yb) in ((n_south, (0.0, y_hall)), (n - n_south, (y_top, depth))):
        xs = [0.0, *_split_lengths(rng, width, count), width]
        rects += [(xs[i], ya, xs[i + 1], yb) for i in range(count)]
    return [*rects, (0.0, y_hall, width, y_top)]


def _assign_types(rng: np.random.Generator, rects: list[Rect]) -> list[tuple[str, str]]:
    """Living room to the largest room, bathrooms to the smallest, the rest shuffled."""
    program = list(ROOM_PROGRAM[: len(rects)])
    areas = np.array([(r[2] - r[0]) * (r[3] - r[1]) for r in rects])
    order = list(np.argsort(-areas))
    n_bath = program.count("bathroom")
    middle = [t for t in program if t not in ("living room", "bathroom")]
    rng.shuffle(middle)
    by_rank = ["living room", *middle, *["bathroom"] * n_bath]
    types: list[str] = [""] * len(rects)
    for rank, idx in enumerate(order):
        types[idx] = by_rank[rank]
    seen: set[str] = set()
    named = []
    for t in types:
        named.append((t, SECOND_NAMES.get(t, t) if t in seen else t))
        seen.add(t)
    return named


def _shared_edge(a: Room, b: Room) -> tuple[str, float, float, float] | None:
    """(axis, line coordinate, lo, hi) of the wall two rooms share, if at least a door wide."""
    for axis, (a_lo, a_hi, b_lo, b_hi, a_line, b_line) in (
        ("x", (a.x0, a.x1, b.x0, b.x1, (a.y0, a.y1), (b.y0, b.y1))),
        ("y", (a.y0, a.y1, b.y0, b.y1, (a.x0, a.x1), (b.x0, b.x1))),
    ):
        for line in a_line:
            if any(abs(line - other) < 1e-6 for other in b_line):
                lo, hi = max(a_lo, b_lo), min(a_hi, b_hi)
                if hi - lo >= DOOR_WIDTH_M + 0.6:
                    return axis, line, lo, hi
    return None


def _door_on(rng: np.random.Generator, door_id: int, a: Room, b_id: int,
             edge: tuple[str, float, float, float], is_open: bool) -> Door:
    axis, line, lo, hi = edge
    margin = DOOR_WIDTH_M / 2 + 0.3
    centre = round(float(rng.uniform(lo + margin, hi - margin)), 2)
    x, y = (centre, line) if axis == "x" else (line, centre)
    return Door(door_id, a.id, b_id, x, y, axis, open=is_open)


def _place_doors(rng: np.random.Generator, rooms: list[Room]) -> list[Door]:
    """A spanning tree of open doors (every room reachable) plus loop doors that may be closed."""
    cost = {"hallway": 0.0, "living room": 1.0, "dining room": 1.5, "kitchen": 2.0}
    edges = []
    for i, a in enumerate(rooms):
        for b in rooms[i + 1:]:
            edge = _shared_edge(a, b)
            if edge is not None:
                weight = min(cost.get(a.type, 3.0), cost.get(b.type, 3.0)) + rng.uniform(0, 1)
                if "bathroom" in (a.type, b.type) and "hallway" not in (a.type, b.type):
                    weight += 2.0  # bathrooms open onto hallways when there is one
                edges.append((weight, a.id, b.id, edge))
    edges.sort(key=lambda e: e[0])
    parent = list(range(len(rooms)))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    doors: list[Door] = []
    loops = []
    for _, a_id, b_id, edge in edges:
        ra, rb = find(a_id), find(b_id)
        if ra != rb:
            parent[ra] = rb
            doors.append(_door_on(rng, len(doors), rooms[a_id], b_id, edge, is_open=True))
        else:
            loops.append((a_id, b_id, edge))
    if len({find(r.id) for r in rooms}) != 1:
        raise RuntimeError("layout is not connected")  # cannot happen for a tiling; guard anyway
    for idx in rng.permutation(len(loops))[: int(rng.integers(0, 3))]:
        a_id, b_id, edge = loops[int(idx)]
        doors.append(_door_on(rng, len(doors), rooms[a_id], b_id, edge,
                              is_open=bool(rng.random() < 0.4)))
    return doors


def _build_walls(rooms: list[Room], doors: list[Door]) -> list[Wall]:
    """Merge room edges into wall lines, cut door gaps and add lintels above them."""
    lines: dict[tuple[str, float], list[tuple[float, float]]] = {}
    for r in rooms:
        for axis, line, lo, hi in (("x", r.y0, r.x0, r.x1), ("x", r.y1, r.x0, r.x1),
                                   ("y", r.x0, r.y0, r.y1), ("y", r.x1, r.y0, r.y1)):
            lines.setdefault((axis, round(line, 3)), []).append((lo, hi))
    gaps: dict[tuple[str, float], list[tuple[float, float]]] = {}
    for d in doors:
        line = d.y if d.axis == "x" else d.x
        gaps.setdefault((d.axis, round(line, 3)), []).append(d.interval)
    walls: list[Wall] = []
    half = WALL_THICKNESS_M / 2
    for (axis, line), spans in sorted(lines.items()):
        for lo, hi in _subtract(_merge(spans), sorted(gaps.get((axis, line), []))):
            walls.append(_wall(axis, line, lo - half, hi + half))
        for lo, hi in gaps.get((axis, line), []):
            walls.append(_wall(axis, line, lo, hi, z0=DOOR_HEIGHT_M))
    return walls


def _wall(axis: str, line: float, lo: float, hi: float, z0: float = 0.0) -> Wall:
    if axis == "x":
        return Wall(lo, line, hi, line, z0=z0)
    return Wall(line, lo, line, hi, z0=z0)


def _merge(spans: list[tuple[float, float]]) -> list[tuple[float, float]]:
    merged: list[list[float]] = []
    for lo, hi in sorted(spans):
        if merged and lo <= merged[-1][1] + 1e-6:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    return [(lo, hi) for lo, hi in merged]


def _subtract(spans: list[tuple[float, float]], holes: list[tuple[float, float]]):
    """Spans minus holes; pieces shorter than 1 cm are dropped."""
    out = []
    for lo, hi in spans:
        cur = lo
        for h_lo, h_hi in holes:
            if h_hi <= cur or h_lo >= hi:
                continue
            if h_lo - cur > 0.01:
                out.append((cur, h_lo))
            cur = max(cur, h_hi)
        if hi - cur > 0.01:
            out.append((cur, hi))
    return out
