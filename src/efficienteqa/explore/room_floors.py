"""The floor each room showed, on the explore map's grid: what the steering knows of where the
rooms are (``target.TargetExplorer``). Each frame's sightings name the floor points of the rooms
in view (``Sightings.floor``); they are kept per room as a boolean grid, so that a point's room,
the rooms near a door, a room's size and its middle are a look-up.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from efficienteqa.mapping.grid import GridSpec

MIN_NEAR_CELLS = 3  # a room counts as near a point with this many of its floor cells close


class RoomFloors:
    """Per room, the grid cells whose floor a frame showed (afresh when the grid changes)."""

    def __init__(self) -> None:
        self.spec: GridSpec | None = None
        self.cells: dict[str, np.ndarray] = {}  # room -> bool grid

    def add(self, spec: GridSpec, floor: Mapping[str, np.ndarray]) -> None:
        """One frame's floor points of each room in view (world xy)."""
        if self.spec is None or self.spec.shape != spec.shape:
            self.spec, self.cells = spec, {}
        for room, xy in floor.items():
            if not len(xy):
                continue
            grid = self.cells.setdefault(room, np.zeros(spec.shape, bool))
            i, j = spec.world_to_cell(np.asarray(xy))
            ok = spec.contains((i, j))
            grid[i[ok], j[ok]] = True

    def room_at(self, xy: tuple[float, float] | np.ndarray, within_m: float = 0.0) -> str | None:
        """The room whose seen floor holds the point, or with ``within_m`` the room with the
        most seen floor within that many metres (None when no frame showed any)."""
        window = self.window(xy, within_m)
        if window is None:
            return None
        counts = {room: int(g[window].sum()) for room, g in self.cells.items()}
        best = max(counts, key=lambda k: counts[k], default=None)
        return best if best is not None and counts[best] > 0 else None

    def near(self, xy: np.ndarray, within_m: float) -> set[str]:
        """The rooms with seen floor within ``within_m`` of ``xy`` (MIN_NEAR_CELLS each)."""
        window = self.window(xy, within_m)
        if window is None:
            return set()
        return {room for room, g in self.cells.items() if g[window].sum() >= MIN_NEAR_CELLS}

    def size(self, room: str) -> int:
        """How many cells of ``room``'s floor frames showed."""
        return int(self.cells[room].sum()) if room in self.cells else 0

    def middle(self, spec: GridSpec, room: str) -> np.ndarray:
        """The world point in the middle of ``room``'s seen floor."""
        return spec.cell_to_world(np.argwhere(self.cells[room])).mean(axis=0)

    def window(self, xy: np.ndarray | tuple[float, float], within_m: float
               ) -> tuple[slice, slice] | None:
        """The map cells within ``within_m`` of ``xy`` each way, as slices; None off the map
        (or before any frame)."""
        if self.spec is None:
            return None
        i, j = (int(v) for v in self.spec.world_to_cell(np.asarray(xy, float)))
        r = int(round(within_m / self.spec.resolution_m))
        rows, cols = self.spec.shape
        i0, i1, j0, j1 = max(i - r, 0), min(i + r + 1, rows), max(j - r, 0), min(j + r + 1, cols)
        return None if i0 >= i1 or j0 >= j1 else (slice(i0, i1), slice(j0, j1))
