"""A simulator's semantic sensor carried in a recording, as JSON (optional).

A recording of a simulated walk may carry what the simulator knew: an instance id per pixel
(the ``/efficienteqa/instance`` topic, or ``instance/*.npy`` in a folder) and this JSON (the
``/efficienteqa/labels`` topic, or ``labels.json``)::

    {"format": "efficienteqa-labels/1",
     "objects": [{"id": 12, "category": "sofa", "colour": "blue", "state": null,
                  "room": "living room", "door": null}, ...],
     "rooms": [{"name": "kitchen", "polygon": [[x, y], ...]}, ...]}

``door``, for doors, is ``{"rooms": [a, b], "x": .., "y": .., "normal": [nx, ny]}``. A floor
point is in the first room whose polygon holds it (edges included). With both, a recording
replays with the semantic-sensor perception (``--backends.perception semantic``); a robot's
recording has neither and is read with the pixel or image perceptions.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from efficienteqa.envs.base import DoorSides, ObjectLabel, SceneLabels
from efficienteqa.errors import EfficientEQAError

LABELS_FORMAT = "efficienteqa-labels/1"


Point = tuple[float, float]


def _box(polygon: list[Point]) -> tuple[float, float, float, float] | None:
    """(x0, y0, x1, y1) of an axis-aligned box (the synthetic houses' rooms), else None."""
    xs, ys = {x for x, _ in polygon}, {y for _, y in polygon}
    if len(polygon) != 4 or len(xs) != 2 or len(ys) != 2:
        return None
    return min(xs), min(ys), max(xs), max(ys)


def _inside(polygon: list[Point], x: float, y: float) -> bool:
    """Whether (x, y) lies in the polygon or on its edges (even-odd rule)."""
    inside = False
    n = len(polygon)
    for k in range(n):
        x0, y0 = polygon[k]
        x1, y1 = polygon[(k + 1) % n]
        cross = (x1 - x0) * (y - y0) - (y1 - y0) * (x - x0)
        if cross == 0 and min(x0, x1) <= x <= max(x0, x1) and min(y0, y1) <= y <= max(y0, y1):
            return True  # on an edge
        if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
    return inside


class RecordedLabels:
    """``SceneLabels`` read back from a recording."""

    def __init__(self, objects: Mapping[int, ObjectLabel],
                 rooms: Iterable[tuple[str, Sequence[Sequence[float]]]] = ()) -> None:
        self._objects = dict(objects)
        self._rooms = [(name, [(float(p[0]), float(p[1])) for p in polygon])
                       for name, polygon in rooms]
        self._boxes = [(name, _box(polygon)) for name, polygon in self._rooms]

    def label(self, instance_id: int) -> ObjectLabel | None:
        return self._objects.get(int(instance_id))

    def room_at(self, x: float, y: float) -> str | None:
        """The first room whose polygon holds (x, y), edges included (a box: tested exactly)."""
        for (name, box), (_, polygon) in zip(self._boxes, self._rooms):
            if box is not None:
                if box[0] <= x <= box[2] and box[1] <= y <= box[3]:
                    return name
            elif _inside(polygon, x, y):
                return name
        return None

    def categories(self) -> list[str]:
        """Every object category of the scene (the perception's vocabulary)."""
        return sorted({o.category for o in self._objects.values()})

    def objects(self) -> dict[int, ObjectLabel]:
        return dict(self._objects)

    def rooms(self) -> list[tuple[str, list[Point]]]:
        return [(name, list(polygon)) for name, polygon in self._rooms]

    @classmethod
    def from_json(cls, data: Any, source: str) -> RecordedLabels:
        """Labels from the JSON above; anything else is one line naming ``source``."""
        fix = f"write the labels as {LABELS_FORMAT} (see efficienteqa.envs.recorded.labels)"
        try:
            if not isinstance(data, dict) or data.get("format") != LABELS_FORMAT:
                raise ValueError(f"not {LABELS_FORMAT}")
            objects = {}
            for o in data.get("objects") or []:
                door = o.get("door")
                sides = None if door is None else DoorSides(
                    (door["rooms"][0], door["rooms"][1]), float(door["x"]), float(door["y"]),
                    (float(door["normal"][0]), float(door["normal"][1])))
                objects[int(o["id"])] = ObjectLabel(str(o["category"]), o.get("colour"),
                                                    o.get("state"), o.get("room"), sides)
            rooms = []
            for r in data.get("rooms") or []:
                polygon = [(float(x), float(y)) for x, y in r["polygon"]]
                if len(polygon) < 3:
                    raise ValueError(f"room {r.get('name')!r} has no polygon of 3 or more points")
                rooms.append((str(r["name"]), polygon))
        except (KeyError, TypeError, ValueError, IndexError) as error:
            raise EfficientEQAError(f"cannot read the object labels of {source}: {error}",
                                    fix=fix) from None
        return cls(objects, rooms)


def labels_json(labels: SceneLabels, seen: Iterable[int] = ()) -> dict[str, Any]:
    """The JSON of ``labels``: every object where the labels list them (``objects()``), else
    the instance ids ``seen`` in the frames; the rooms where the labels give their polygons
    (``rooms()``), else none (``room_at`` then says None everywhere on replay)."""
    listed = getattr(labels, "objects", None)
    if callable(listed):
        table: dict[int, ObjectLabel] = dict(listed())
    else:
        table = {}
        for i in sorted(set(seen)):
            found = labels.label(i)
            if found is not None:
                table[int(i)] = found
    objects = []
    for i, o in sorted(table.items()):
        door = None if o.door is None else {"rooms": list(o.door.rooms), "x": o.door.x,
                                            "y": o.door.y, "normal": list(o.door.normal)}
        objects.append({"id": int(i), "category": o.category, "colour": o.colour,
                        "state": o.state, "room": o.room, "door": door})
    polygons = getattr(labels, "rooms", None)
    rooms = ([{"name": name, "polygon": [list(p) for p in polygon]}
              for name, polygon in polygons()] if callable(polygons) else [])
    return {"format": LABELS_FORMAT, "objects": objects, "rooms": rooms}
