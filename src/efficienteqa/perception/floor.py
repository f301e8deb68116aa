"""Which rooms a frame shows, and where an object is in words the frame supports (DESIGN 5).

A room is "in view" when enough of its floor is (structure pixels at floor height, named by the
scene's floor plan). The robot's room is named when its floor or its furniture is in view; any
other room, the room of an object or of a lettered point, and the rooms a door joins only when
that room's floor is in view (for a point: near the point). A closed door names at most the
room on the camera's side of it.

Apart from the frame text (``perception.semantic``) because the world points of the instance
map and the sightings (``perception.regions``) and the pixel perception name rooms the same way.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from efficienteqa.envs.base import ObjectLabel, SceneLabels
from efficienteqa.geometry import backproject

if TYPE_CHECKING:
    from efficienteqa.observation import Observation

FLOOR_TOLERANCE_M = 0.05  # structure pixels this close to z = 0 are floor
ROOM_CELL_M = 0.1  # floor points are grouped on this grid before looking up their room
_CELL_OFFSET = 1 << 20  # keeps cell indices non-negative for the 1-D cell key


@dataclass(frozen=True)
class FloorView:
    """The floor a frame shows: ``rooms`` (names), ``room_index`` (H, W) the index in ``rooms``
    of each floor pixel's room (-1: not floor, or floor of no room) and ``depth_m`` the median
    depth of each room's floor pixels."""

    rooms: tuple[str, ...]
    room_index: np.ndarray
    depth_m: tuple[float, ...]

    def pixels(self, mask: np.ndarray | None = None) -> dict[str, int]:
        """Floor pixels per room (within ``mask`` when given)."""
        index = self.room_index if mask is None else self.room_index[mask]
        counts = np.bincount(index[index >= 0].ravel(), minlength=len(self.rooms))
        return {name: int(n) for name, n in zip(self.rooms, counts)}

    def in_view(self, min_pixels: int, mask: np.ndarray | None = None) -> tuple[str, ...]:
        """Rooms with at least ``min_pixels`` floor pixels (within ``mask``), nearest first."""
        counts = self.pixels(mask)
        near_first = sorted(zip(self.depth_m, self.rooms))
        return tuple(name for _, name in near_first if counts[name] >= min_pixels)


def floor_view(obs: Observation, labels: SceneLabels, points: np.ndarray | None = None
               ) -> FloorView:
    """The rooms whose floor the frame shows: structure pixels (instance 0) at floor height,
    each named by ``labels.room_at`` at the centre of its ROOM_CELL_M cell. ``points``: the
    frame's back-projection, when the caller has it."""
    h, w = obs.depth_m.shape
    if points is None:
        points = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)
    floor = (obs.depth_m > 0) & (np.abs(points[..., 2]) < FLOOR_TOLERANCE_M)
    if obs.instance is not None:
        floor &= obs.instance == 0
    index = np.full((h, w), -1, np.int64)
    if not floor.any():
        return FloorView((), index, ())
    cells = np.floor(points[floor][:, :2] / ROOM_CELL_M).astype(np.int64) + _CELL_OFFSET
    unique, inverse = np.unique(cells[:, 0] * (2 * _CELL_OFFSET) + cells[:, 1],
                                return_inverse=True)  # one int key per cell: a fast 1-D unique
    i, j = np.divmod(unique, 2 * _CELL_OFFSET)
    names = [labels.room_at((a - _CELL_OFFSET + 0.5) * ROOM_CELL_M,
                            (b - _CELL_OFFSET + 0.5) * ROOM_CELL_M) for a, b in zip(i, j)]
    rooms = tuple(sorted({n for n in names if n is not None}))
    code = {name: k for k, name in enumerate(rooms)}
    per_cell = np.array([code[n] if n is not None else -1 for n in names], np.int64)
    index[floor] = per_cell[inverse.ravel()]
    depth = obs.depth_m[floor]
    medians = tuple(float(np.median(depth[index[floor] == k])) for k in range(len(rooms)))
    return FloorView(rooms, index, medians)


def where_words(label: ObjectLabel, in_view: set[str], robot_room: str | None,
           camera_xy: tuple[float, float]) -> str | None:
    """Where an object is, in words the frame supports: a door by the rooms it joins whose floor
    is in view (a closed door only by the room on the camera's side), anything else by its room
    when that room's floor is in view or it is the robot's room the frame shows."""
    sides = label.door
    if sides is not None:
        if label.state == "open":
            rooms = [r for r in sides.rooms if r is not None and r in in_view]
        else:
            near = sides.side(*camera_xy)
            rooms = [near] if near is not None and near in in_view else []
        if len(rooms) == 2:
            return f"between the {rooms[0]} and the {rooms[1]}"
        return f"in a wall of the {rooms[0]}" if rooms else None
    room = label.room
    if room is not None and (room in in_view or room == robot_room):
        return f"in the {room}"
    return None


def open_door_leads(labels: list[ObjectLabel], in_view: set[str],
                     camera_xy: tuple[float, float]) -> list[str]:
    """Where the open doors among ``labels`` lead: the room beyond each (the side away from the
    camera), when that room's floor is in the frame; a closed door leads nowhere in view."""
    leads: list[str] = []
    for label in labels:
        sides = label.door
        if sides is None or label.state != "open":
            continue
        near = sides.side(*camera_xy)
        beyond = [r for r in sides.rooms if r is not None and r != near and r in in_view]
        leads += [r for r in beyond if r not in leads]
    return leads
