"""House -> triangles and lights for the renderer (floors, walls, ceilings, doors, furniture)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from efficienteqa.envs.synthetic.catalog import Catalog
from efficienteqa.envs.synthetic.colours import recoloured
from efficienteqa.envs.synthetic.house import House, PlacedObject
from efficienteqa.envs.synthetic.layout import WALL_HEIGHT_M, Wall
from efficienteqa.envs.synthetic.mesh import MeshPart, box_part, pose_matrix, rgb3
from efficienteqa.envs.synthetic.scene_geometry import PointLight, SceneGeometry
from efficienteqa.envs.synthetic.textures import floor_texture, wall_texture

FLOOR_KIND = {
    "living room": "wood", "dining room": "wood", "office": "wood", "bedroom": "carpet",
    "kitchen": "tiles", "bathroom": "tiles", "hallway": "stone",
}
TEXTURE_TILE_M = 1.5  # one texture repeat per 1.5 m of floor or wall
DOOR_SIZE_M = (0.86, 0.04, 2.06)
DOOR_COLOUR = (0.55, 0.36, 0.2)
LAMP_LIGHT = (1.0, 0.85, 0.6)


def _textured(part: MeshPart, texture: np.ndarray) -> MeshPart:
    assert part.uvs is not None
    return replace(part, texture=texture, uvs=part.uvs / TEXTURE_TILE_M)


def _wall_part(wall: Wall, texture: np.ndarray) -> MeshPart:
    length = math.hypot(wall.x1 - wall.x0, wall.y1 - wall.y0)
    box = box_part((length, wall.thickness_m, wall.z1 - wall.z0), (0.93, 0.91, 0.86),
                   centre=(0.0, 0.0, (wall.z0 + wall.z1) / 2), material="wall")
    yaw = math.atan2(wall.y1 - wall.y0, wall.x1 - wall.x0)
    centre = pose_matrix((wall.x0 + wall.x1) / 2, (wall.y0 + wall.y1) / 2, 0.0, yaw)
    return _textured(box, texture).transformed(centre)


def door_parts() -> list[MeshPart]:
    """A wooden panel with a metal handle, in the model frame (bottom centre origin)."""
    w, d, h = DOOR_SIZE_M
    panel = box_part((w, d, h), DOOR_COLOUR, centre=(0, 0, h / 2), material="door")
    handle = box_part((0.12, d + 0.05, 0.03), (0.8, 0.8, 0.78), centre=(w / 2 - 0.1, 0, 1.0),
                      material="handle")
    return [panel, handle]


def object_parts(obj: PlacedObject, catalog: Catalog) -> list[MeshPart]:
    """An object's parts in the world frame, recoloured and lit according to its state."""
    parts = door_parts() if obj.category == "door" else catalog.mesh(obj.model_key)
    if obj.colour_rgb is not None:
        parts = recoloured(parts, obj.colour_rgb)
    if obj.state in ("on", "off"):
        lit = set(catalog.entry(obj.model_key).state_materials)
        parts = [_switched(p, obj.state == "on", obj.category == "tv") if p.material in lit else p
                 for p in parts]
    matrix = pose_matrix(obj.x, obj.y, obj.z, obj.yaw)
    return [p.transformed(matrix, instance_id=obj.id) for p in parts]


def _switched(part: MeshPart, on: bool, screen: bool) -> MeshPart:
    """A screen or lamp shade: glowing when on; when off a screen is black and a shade dim."""
    if on:
        return replace(part, emissive=1.0, colour=_glow(part.colour))
    if screen:
        return replace(part, colour=(0.02, 0.02, 0.02), texture=None)
    return replace(part, colour=rgb3(0.55 * c for c in part.colour))


def _glow(colour: tuple[float, float, float]) -> tuple[float, float, float]:
    """A lit screen or bulb: bright, slightly tinted by its own colour."""
    c = np.asarray(colour)
    return rgb3(np.clip(0.75 + 0.25 * c / max(c.max(), 1e-3), 0, 1))


def build_geometry(house: House, catalog: Catalog) -> SceneGeometry:
    """All triangles of the house in the world frame, plus one light per room and per lit lamp."""
    parts: list[MeshPart] = []
    walls_tex = wall_texture(house.seed)
    for room in house.layout.rooms:
        size = (room.x1 - room.x0, room.y1 - room.y0)
        centre = (*room.centre, -0.025)
        floor = box_part((*size, 0.05), (1.0, 1.0, 1.0), centre=centre, material="floor")
        parts.append(_textured(floor, floor_texture(FLOOR_KIND.get(room.type, "wood"),
                                                    house.seed * 31 + room.id)))
        parts.append(box_part((*size, 0.05), (0.96, 0.96, 0.95),
                              centre=(*room.centre, WALL_HEIGHT_M + 0.025), material="ceiling"))
    parts += [_wall_part(w, walls_tex) for w in house.layout.walls]
    for obj in house.objects:
        parts += object_parts(obj, catalog)
    lights = [
        # No shadows: the radius just reaches the room's floor corners, barely past its walls.
        PointLight((*r.centre, WALL_HEIGHT_M - 0.2), intensity=0.6,
                   radius_m=math.hypot(math.hypot(r.x1 - r.x0, r.y1 - r.y0) / 2, WALL_HEIGHT_M) + 0.3)
        for r in house.layout.rooms
    ]
    lights += [
        PointLight((o.x, o.y, o.top_z - 0.1), colour=LAMP_LIGHT, intensity=0.5, radius_m=3.0)
        for o in house.objects if o.state == "on" and "lamp" in o.category
    ]
    return SceneGeometry(parts=parts, lights=lights)
