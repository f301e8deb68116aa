"""How much of a room the robot's views covered, on the 2-D maps (explore.target's "searched").

A room's extent is not known in advance: frames show parts of its floor (the perception names
the room of each floor pixel). Its extent here is the convex hull of the floor cells seen so far
(rooms are convex as a rule, and the hull grows with every glimpse); the coverage is the share
of that hull's unoccupied cells that the map has explored (seen in the bottom centre of some
frame, ``MapState.explored``). Floor seen only far off, or hidden behind furniture, or a corner
no frame reached, counts as not covered.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay, QhullError


def hull_mask(cells: np.ndarray) -> np.ndarray:
    """The cells (bool grid, same shape) inside the convex hull of the True cells of ``cells``
    (the cells themselves where they span no area)."""
    ij = np.argwhere(cells)
    if len(ij) < 3:
        return cells.copy()
    lo, hi = ij.min(axis=0), ij.max(axis=0) + 1
    try:
        hull = Delaunay(ij.astype(float))
    except QhullError:  # all on a line
        return cells.copy()
    ii, jj = np.mgrid[lo[0]:hi[0], lo[1]:hi[1]]
    inside = hull.find_simplex(np.stack([ii.ravel(), jj.ravel()], axis=1).astype(float)) >= 0
    out = cells.copy()
    out[lo[0]:hi[0], lo[1]:hi[1]] |= inside.reshape(ii.shape)
    return out


def room_coverage(floor_seen: np.ndarray, explored: np.ndarray, occupied: np.ndarray) -> float:
    """The share of the room's extent (the hull of ``floor_seen``, less ``occupied`` cells)
    that is ``explored``; 0 when nothing of it was seen."""
    extent = hull_mask(floor_seen) & ~occupied
    total = int(extent.sum())
    return float((extent & explored).sum() / total) if total else 0.0
