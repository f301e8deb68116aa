"""The semantic sensor of a synthetic house: object labels and room names (``envs.base.SceneLabels``)."""

from __future__ import annotations

from efficienteqa.envs.base import DoorSides, ObjectLabel
from efficienteqa.envs.synthetic.house import House
from efficienteqa.envs.synthetic.layout import Door, Layout

_PROBE_M = 0.3  # how far across the wall line a door's side is looked up


def door_sides(layout: Layout, door: Door) -> DoorSides:
    """The rooms a door joins (room_a first; None for the outside) and its wall line."""
    names = {r.id: r.name for r in layout.rooms}
    normal = (0.0, 1.0) if door.axis == "x" else (1.0, 0.0)
    room_a = layout.rooms[door.room_a]
    if not room_a.contains(door.x + _PROBE_M * normal[0], door.y + _PROBE_M * normal[1]):
        normal = (-normal[0], -normal[1])
    return DoorSides((names[door.room_a], names.get(door.room_b)), door.x, door.y, normal)


class HouseLabels:
    """``SceneLabels`` of a synthetic house (doors are objects of category "door")."""

    def __init__(self, house: House) -> None:
        self._layout = house.layout
        rooms = {r.id: r.name for r in house.layout.rooms}
        sides = {int(obj): door_sides(house.layout, house.layout.doors[int(door)])
                 for door, obj in house.meta.get("door_objects", {}).items()}
        self._labels = {o.id: ObjectLabel(o.category, o.colour or None, o.state,
                                          rooms.get(o.room_id), sides.get(o.id))
                        for o in house.objects}

    def label(self, instance_id: int) -> ObjectLabel | None:
        return self._labels.get(int(instance_id))

    def room_at(self, x: float, y: float) -> str | None:
        room = self._layout.room_at(x, y)
        return room.name if room is not None else None

    def objects(self) -> dict[int, ObjectLabel]:
        """Every object's label by instance id (what a recording of the house carries)."""
        return dict(self._labels)

    def rooms(self) -> list[tuple[str, list[tuple[float, float]]]]:
        """Each room's name and floor polygon (its wall centre lines), in ``room_at``'s order."""
        return [(r.name, [(r.x0, r.y0), (r.x1, r.y0), (r.x1, r.y1), (r.x0, r.y1)])
                for r in self._layout.rooms]
