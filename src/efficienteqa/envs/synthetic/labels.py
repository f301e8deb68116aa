"""The semantic sensor of a synthetic house: object labels and room names (``envs.base.SceneLabels``)."""

from __future__ import annotations

from efficienteqa.envs.base import ObjectLabel
from efficienteqa.envs.synthetic.house import House


class HouseLabels:
    """``SceneLabels`` of a synthetic house (doors are objects of category "door")."""

    def __init__(self, house: House) -> None:
        self._layout = house.layout
        rooms = {r.id: r.name for r in house.layout.rooms}
        doors = {int(obj): house.layout.doors[int(door)]
                 for door, obj in house.meta.get("door_objects", {}).items()}
        places = {obj: f"between the {rooms[d.room_a]} and "
                       + (f"the {rooms[d.room_b]}" if d.room_b in rooms else "the outside")
                  for obj, d in doors.items() if d.room_a in rooms}
        self._labels = {o.id: ObjectLabel(o.category, o.colour or None, o.state,
                                          rooms.get(o.room_id), places.get(o.id))
                        for o in house.objects}

    def label(self, instance_id: int) -> ObjectLabel | None:
        return self._labels.get(int(instance_id))

    def room_at(self, x: float, y: float) -> str | None:
        room = self._layout.room_at(x, y)
        return room.name if room is not None else None
