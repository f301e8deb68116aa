"""Seed -> house: plan, furniture, doors, states, colours, start pose, navigation grid."""

from __future__ import annotations

import math

import numpy as np

from efficienteqa.envs.synthetic.build import DOOR_SIZE_M
from efficienteqa.envs.synthetic.catalog import Catalog
from efficienteqa.envs.synthetic.colours import PALETTE
from efficienteqa.envs.synthetic.furnish import furnish
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS, House, PlacedObject
from efficienteqa.envs.synthetic.layout import Door, Layout, Room, generate_layout
from efficienteqa.envs.synthetic.navigation import rasterise
from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.navgrid import OccupancyGrid

ROBOT_RADIUS_M = 0.2
START_CLEARANCE_M = 1.0
KEEP = frozenset({"bed", "sofa", "refrigerator", "toilet", "table", "dining table", "desk",
                  "wardrobe", "shower", "bathtub"})
GRID_RESOLUTION_M = 0.05
# Categories whose recolouring makes a natural colour question, and the colours used.
COLOURABLE = ("sofa", "armchair", "bed", "office chair", "wardrobe", "refrigerator",
              "vase", "cup", "rug", "cabinet", "desk", "stool", "towel")
RECOLOURS = ("red", "blue", "green", "yellow", "orange", "purple", "pink", "white", "black")
RECOLOUR_STREAM = 7  # rng stream of ``recolour_share`` (any constant apart from the house's)


def generate_house(seed: int, catalog: Catalog, assets: str = DEFAULT_ASSETS, *,
                   recolour_share: float = 0.0) -> House:
    """The house of ``seed``: the same seed and catalogue always give the same house.

    ``recolour_share`` > 0 (perception training houses only) recolours more objects after the
    usual 2-3, see ``recolour_share_of``; 0 leaves every house as it always was."""
    rng = np.random.default_rng(seed)
    layout = generate_layout(rng, int(rng.integers(5, 10)))
    objects, tables = furnish(layout, catalog, rng)
    doors = _door_objects(layout, first_id=len(objects) + 1)
    objects += doors
    for obj in objects:
        kind = catalog.entry(obj.model_key).state_kind if obj.category != "door" else None
        if kind in ("tv", "lamp"):
            obj.state = "on" if rng.random() < 0.5 else "off"
    _recolour(rng, objects, layout)
    if recolour_share > 0:
        # a stream of its own: the house's other draws (start pose) stay as without it
        recolour_share_of(np.random.default_rng([seed, RECOLOUR_STREAM]), objects, recolour_share)
    house = House(seed, layout, objects, Pose2D(0.0, 0.0, 0.0), assets,
                  meta={"chairs_at_table": {str(k): v for k, v in tables.items()},
                        "door_objects": {str(d.id): o.id for d, o in zip(layout.doors, doors)}})
    grid = _reconnect(house)
    start_xy = _start_point(rng, grid, next(r for r in layout.rooms if r.type == "living room"))
    house.start = Pose2D(*start_xy, _informative_yaw(house, grid, start_xy))
    return house


def navigation_grid(house: House, resolution_m: float = GRID_RESOLUTION_M) -> OccupancyGrid:
    """Ground-truth occupancy of the floor: walls (lintels excepted) and floor-standing objects."""
    spec = GridSpec.covering(0.0, 0.0, house.layout.width_m, house.layout.depth_m, resolution_m)
    return rasterise(
        spec,
        [(r.x0, r.y0, r.x1, r.y1) for r in house.layout.rooms],
        [(w.x0, w.y0, w.x1, w.y1, w.thickness_m) for w in house.layout.walls if w.z0 < 0.5],
        [o.footprint() for o in house.objects if o.on_floor],
    )


def _reconnect(house: House, max_removals: int = 12) -> OccupancyGrid:
    """Remove furniture that walls off a doorway (a coffee table too close to a TV stand can
    seal a room): while a doorway's floor lies outside the largest navigable component, the
    floor-standing object nearest to that doorway goes, with what stands on it; key furniture
    (KEEP) only when nothing else stands within 3 m. Floor merely cut off behind furniture is
    left alone. Returns the final navigation grid."""
    doorways = [(d.x, d.y) for d in house.layout.doors if d.open]
    for _ in range(max_removals):
        grid = navigation_grid(house)
        labels, _ = grid.components(ROBOT_RADIUS_M)
        main = np.argmax(np.bincount(labels.ravel())[1:]) + 1
        cut = [xy for xy in doorways if grid.label_at(xy, ROBOT_RADIUS_M) not in (main, 0)]
        if not cut:
            return grid
        movable = [o for o in house.objects if o.on_floor and o.category != "door"]
        if not movable:
            return grid
        distance = {o.id: float(np.hypot(o.x - cut[0][0], o.y - cut[0][1])) for o in movable}
        spare = [o for o in movable if o.category not in KEEP and distance[o.id] <= 3.0]
        victim = min(spare or movable, key=lambda o: distance[o.id])
        gone = {victim.id} | {o.id for o in house.objects if o.support_id == victim.id}
        house.objects = [o for o in house.objects if o.id not in gone]
        tables = house.meta["chairs_at_table"]
        for key in list(tables):
            tables[key] = [c for c in tables[key] if c not in gone]
            if int(key) in gone or not tables[key]:
                del tables[key]
    return navigation_grid(house)


def _start_point(rng: np.random.Generator, grid: OccupancyGrid, room: Room
                 ) -> tuple[float, float]:
    """A point of the furnished living room with START_CLEARANCE_M of free floor around it
    (DESIGN 3.2 treats that disk as free), or the most open points when the room has none."""
    xs, ys = grid.spec.centres()
    labels, _ = grid.components(ROBOT_RADIUS_M)
    main = labels == np.argmax(np.bincount(labels.ravel())[1:]) + 1
    inside = (xs > room.x0) & (xs < room.x1) & (ys > room.y0) & (ys < room.y1) & main
    clearance = np.where(inside, grid.clearance(), 0.0)
    ok = clearance >= min(START_CLEARANCE_M, clearance.max() - 0.1)
    cells = np.argwhere(ok)
    x, y = grid.spec.cell_to_world(cells[int(rng.integers(len(cells)))])
    return round(float(x), 2), round(float(y), 2)


def _door_objects(layout: Layout, first_id: int) -> list[PlacedObject]:
    """A panel per door: in the opening when closed; swung 90 deg into room_a when open."""
    w, d, h = DOOR_SIZE_M
    out = []
    for k, door in enumerate(layout.doors):
        x, y, yaw = _door_panel_pose(layout, door)
        out.append(PlacedObject(
            id=first_id + k, category="door", model_key="builtin/door", name="Door",
            room_id=door.room_a, x=x, y=y, z=0.0, yaw=yaw, size_m=(w, d, h), colour="brown",
            licence="CC0-1.0", state="open" if door.open else "closed"))
    return out


def _door_panel_pose(layout: Layout, door: Door) -> tuple[float, float, float]:
    along = np.array([1.0, 0.0]) if door.axis == "x" else np.array([0.0, 1.0])
    if not door.open:
        return door.x, door.y, 0.0 if door.axis == "x" else math.pi / 2
    room_a = layout.rooms[door.room_a]
    normal = np.array([0.0, 1.0]) if door.axis == "x" else np.array([1.0, 0.0])
    if not room_a.contains(*(np.array([door.x, door.y]) + 0.3 * normal)):
        normal = -normal
    hinge = np.array([door.x, door.y]) - along * (door.width_m / 2 - 0.02)
    centre = hinge + normal * (DOOR_SIZE_M[0] / 2 + 0.03) + along * (DOOR_SIZE_M[1] / 2 + 0.01)
    yaw = math.pi / 2 if door.axis == "x" else 0.0
    return round(float(centre[0]), 3), round(float(centre[1]), 3), yaw


def _recolour(rng: np.random.Generator, objects: list[PlacedObject], layout: Layout) -> None:
    """Give 2-3 uniquely-referable objects one clear palette colour (for colour questions)."""
    counts: dict[tuple[int, str], int] = {}
    for o in objects:
        counts[(o.room_id, o.category)] = counts.get((o.room_id, o.category), 0) + 1
    candidates = [o for o in objects
                  if o.category in COLOURABLE and counts[(o.room_id, o.category)] == 1]
    for idx in rng.permutation(len(candidates))[: int(rng.integers(2, 4))]:
        obj = candidates[int(idx)]
        name = RECOLOURS[int(rng.integers(len(RECOLOURS)))]
        obj.colour, obj.colour_rgb = name, PALETTE[name]


def recolour_share_of(rng: np.random.Generator, objects: list[PlacedObject], share: float) -> int:
    """Recolour objects of COLOURABLE categories (as ``_recolour`` does, to another colour than
    their own) until ``share`` of them (rounded up) carry a recolouring; returns how many changed."""
    colourable = [o for o in objects if o.category in COLOURABLE]
    todo = [o for o in colourable if o.colour_rgb is None]
    extra = max(0, math.ceil(share * len(colourable)) - (len(colourable) - len(todo)))
    for idx in rng.permutation(len(todo))[:extra]:
        obj = todo[int(idx)]
        names = [c for c in RECOLOURS if c != obj.colour]
        name = names[int(rng.integers(len(names)))]
        obj.colour, obj.colour_rgb = name, PALETTE[name]
    return min(extra, len(todo))


def _informative_yaw(house: House, grid: OccupancyGrid, start_xy: tuple[float, float],
                     n_yaws: int = 16) -> float:
    """Face open space where the most objects are in the field of view and in sight."""
    start = np.array(start_xy)
    yaws = np.arange(n_yaws) * (2 * math.pi / n_yaws)
    rays = grid.ray_length(start_xy, yaws)
    half_fov = math.radians(CameraSpec().hfov_deg) / 2 * 0.8
    visible = np.zeros(n_yaws)
    for o in house.objects:
        offset = np.array([o.x, o.y]) - start
        dist = float(np.hypot(*offset))
        if not 1.0 <= dist <= 7.0:
            continue
        near_side = start + offset * (1 - (max(o.size_m[:2]) / 2 + 0.1) / dist)  # off its footprint
        if not grid.line_of_sight(start_xy, (float(near_side[0]), float(near_side[1]))):
            continue
        bearing = math.atan2(offset[1], offset[0])
        diff = np.abs((yaws - bearing + math.pi) % (2 * math.pi) - math.pi)
        visible += diff < half_fov
    score = np.minimum(rays, 4.0) * (1.0 + visible)
    return float(yaws[int(np.argmax(score))])
