"""A generated house as plain data: layout, objects with attributes, start pose; JSON in and out."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from efficienteqa.envs.synthetic.layout import Door, Layout, Room, Wall
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D

HOUSE_FORMAT = 1
MOUNTED_Z_M = 1.0  # objects hung at least this high (wall cabinets, lamps) leave the floor free


# The furniture of a synthetic house unless told otherwise: the Sweet Home 3D package's CC0
# catalogue. "sh3d-all" adds its CC-BY 3.0 catalogues (about three times the meshes, credited in
# the scene's ATTRIBUTION.md); "builtin" is coloured boxes, for tests.
DEFAULT_ASSETS = "sh3d"
ALL_CATALOGUES = "sh3d-all"
ASSETS = (DEFAULT_ASSETS, ALL_CATALOGUES, "builtin")


def check_assets(assets: str) -> None:
    """One clear error for assets no house is furnished with (before any house is built)."""
    if assets not in ASSETS:
        raise EfficientEQAError(f"unknown assets {assets!r}",
                                fix=f"use one of {', '.join(ASSETS)}")


@dataclass
class PlacedObject:
    """One object in the house. (x, y, z) is the bottom centre in metres; yaw in radians turns
    the model's front (local -y) about +z. ``id`` is its instance id in rendered frames (>= 1).
    ``support_id`` is the object it stands on (small objects on tables, a TV on its stand)."""

    id: int
    category: str
    model_key: str
    name: str
    room_id: int
    x: float
    y: float
    z: float
    yaw: float
    size_m: tuple[float, float, float]
    colour: str
    licence: str
    state: str | None = None
    colour_rgb: tuple[float, float, float] | None = None  # set when recoloured
    support_id: int | None = None

    @property
    def on_floor(self) -> bool:
        """Stands on the floor (not on another object, not mounted on a wall or ceiling)."""
        return self.support_id is None and self.z < MOUNTED_Z_M

    @property
    def top_z(self) -> float:
        return self.z + self.size_m[2]

    def footprint(self) -> tuple[float, float, float, float, float]:
        """(cx, cy, width_m, depth_m, yaw_rad) of the object's footprint on the floor."""
        return (self.x, self.y, self.size_m[0], self.size_m[1], self.yaw)


@dataclass
class House:
    seed: int
    layout: Layout
    objects: list[PlacedObject]
    start: Pose2D
    assets: str = DEFAULT_ASSETS  # "sh3d" (the furniture package) or "builtin" (boxes, for tests)
    meta: dict[str, Any] = field(default_factory=dict)

    def room(self, room_id: int) -> Room:
        return self.layout.rooms[room_id]

    def object(self, object_id: int) -> PlacedObject:
        return self._by_id()[object_id]

    def _by_id(self) -> dict[int, PlacedObject]:
        return {o.id: o for o in self.objects}

    def to_json(self) -> dict[str, Any]:
        return {
            "format": HOUSE_FORMAT,
            "seed": self.seed,
            "assets": self.assets,
            "size_m": [self.layout.width_m, self.layout.depth_m],
            "floor_area_m2": round(sum(r.area_m2 for r in self.layout.rooms), 2),
            "rooms": [asdict(r) for r in self.layout.rooms],
            "doors": [asdict(d) for d in self.layout.doors],
            "walls": [asdict(w) for w in self.layout.walls],
            "objects": [asdict(o) for o in self.objects],
            "start": asdict(self.start),
            "meta": self.meta,
        }

    def save(self, path: Path) -> None:
        path.write_text(json.dumps(self.to_json(), indent=1))

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> House:
        if data.get("format") != HOUSE_FORMAT:
            raise EfficientEQAError(
                f"house file has format {data.get('format')!r}, expected {HOUSE_FORMAT}",
                fix="regenerate it with `efficienteqa scenes generate`",
            )
        layout = Layout(
            width_m=data["size_m"][0],
            depth_m=data["size_m"][1],
            rooms=tuple(Room(**r) for r in data["rooms"]),
            doors=tuple(Door(**d) for d in data["doors"]),
            walls=tuple(Wall(**w) for w in data["walls"]),
        )
        objects = [
            PlacedObject(**{**o, "size_m": tuple(o["size_m"]),
                            "colour_rgb": tuple(o["colour_rgb"]) if o["colour_rgb"] else None})
            for o in data["objects"]
        ]
        return cls(data["seed"], layout, objects, Pose2D(**data["start"]), data["assets"],
                   data.get("meta", {}))

    @classmethod
    def load(cls, path: Path) -> House:
        try:
            data = json.loads(Path(path).read_text())
            return cls.from_json(data)
        except (OSError, json.JSONDecodeError, KeyError, TypeError) as exc:
            raise EfficientEQAError(f"cannot read house file {path}: {exc}") from exc
