"""What each visible object stands on or in, read off the frame alone (DESIGN 5).

The frame text says it ("a white desk lamp (on) on the brown nightstand", and the support's own
entry "..., with a white desk lamp on it"), and so does the answerability gate; it is apart from
the text because it is a geometric test of its own, with its own tuning.

The support relation is as honest as the rest: it is read off the frame alone, never off the
scene's own records. Each object's pixels are back-projected to 3D (depth, intrinsics, pose);
A stands on B when both are visible, A's lowest points lie within SUPPORT_GAP_M of B's highest
points (or of a shelf or worktop below B's top: SURFACE_SHARE of B's points at that height), A's
median horizontal position lies within B's visible horizontal extent and A is no wider than B
(both with SUPPORT_MARGIN_M to spare); of several such B, the one whose top is closest to A's
bottom. A is "in" B ("a coffee maker in the white bookshelf", "..., with a grey coffee maker in
it") when it lies wholly within B's height, its median inside B's extent, and B has INSIDE_SHARE
times its pixels: on a shelf whose board A hides (then no "on" B was found). Doors and objects
whose lowest points are near the floor stand on nothing, and a support hidden from the camera is
never named. The answerability gate reads this same relation (``VisibleObject.support_id``),
never one of its own: what it passes is what the model is told (with a VLM over images the
relation is the VLM's own sentence, judged by ``stop.gate``'s model gate). Tuned on the oracle
frames of training houses 0-20: every "What is on ...?" item (28/28) is said to stand on its
surface; 1 of 101 stated relations is wrong. On 1008 frames of random poses of the same houses
(``experiments/relation_bench.py``, objects listed from 60 px), 4 of 339 stated relations are
wrong (2 "on", 2 "in"), all of items over 400 px; at 150-250 px 37 right, none wrong.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from efficienteqa.perception.visible import VisibleObject

if TYPE_CHECKING:
    from efficienteqa.observation import Observation

SUPPORT_GAP_M = 0.08  # A's bottom within this of B's top: A stands on B
SUPPORT_MARGIN_M = 0.1  # A's centre may lie this far outside B's visible horizontal extent
SURFACE_SHARE = 0.1  # or when this share of B's points lies at A's bottom (a shelf, a worktop)
INSIDE_SHARE = 4  # A is "in" B (within B's height and extent) when B has this many times its pixels
ON_FLOOR_M = 0.1  # an object whose bottom is this low stands on the floor
_LOW_PCT, _HIGH_PCT = 2.0, 98.0  # robust "lowest" and "highest" of an object's visible points
STRIDE_WIDTH = 320  # the support test reads every (width // this)-th pixel each way: fewer
# points on large frames (a quarter at 640x480), all of them on small ones


@dataclass(frozen=True)
class Support:
    """What an object stands on (``thing``) and how: "on" its top, a shelf or a worktop seen at
    the object's bottom, or "in" it (within its height and horizontal extent, on a shelf the
    object hides)."""

    thing: VisibleObject
    relation: str


def find_supports(obs: Observation, points: np.ndarray, objects: list[VisibleObject]
              ) -> dict[int, Support]:
    """What each object stands on, as the frame shows it: instance id -> the visible support.
    Only the back-projected pixels of the visible objects are read (see the module docstring)."""
    if obs.instance is None or len(objects) < 2:
        return {}
    k = max(1, obs.depth_m.shape[1] // STRIDE_WIDTH)
    instance, depth, points = obs.instance[::k, ::k], obs.depth_m[::k, ::k], points[::k, ::k]
    valid = (depth > 0) & np.isin(instance, [o.instance_id for o in objects])
    ids, xyz = instance[valid], points[valid]
    order = np.argsort(ids, kind="stable")
    unique, starts = np.unique(ids[order], return_index=True)
    slices = dict(zip(unique.tolist(), np.split(xyz[order], starts[1:])))
    stats = {}  # id -> (z, bottom, top, median xy, min xy, max xy) of its visible points
    objects = [o for o in objects if o.instance_id in slices]  # a sliver may miss the stride
    for o in objects:
        p = slices[o.instance_id]
        bottom, top = np.percentile(p[:, 2], (_LOW_PCT, _HIGH_PCT))
        stats[o.instance_id] = (p[:, 2], float(bottom), float(top), np.median(p[:, :2], axis=0),
                                p[:, :2].min(axis=0), p[:, :2].max(axis=0))
    out: dict[int, Support] = {}
    for a in objects:
        _, bottom, a_top, centre, a_lo, a_hi = stats[a.instance_id]
        if a.label.door is not None or bottom < ON_FLOOR_M:
            continue
        best: tuple[float, VisibleObject, str] | None = None
        for b in objects:
            bz, _, top, _, lo, hi = stats[b.instance_id]
            if (b is a or b.label.door is not None or top < bottom - SUPPORT_GAP_M
                    or np.any(centre < lo - SUPPORT_MARGIN_M) or np.any(centre > hi + SUPPORT_MARGIN_M)
                    or np.any(a_hi - a_lo > hi - lo + 2 * SUPPORT_MARGIN_M)):
                continue  # B is too low, A's centre is not over B, or A is wider than B
            gap, relation = abs(bottom - top), "on"
            if gap > SUPPORT_GAP_M:  # or a shelf or worktop of B below its top, at A's bottom
                if np.mean(np.abs(bz - bottom) <= SUPPORT_GAP_M / 2) >= SURFACE_SHARE:
                    gap = SUPPORT_GAP_M
                elif (float(bz.min()) <= bottom and a_top <= top + SUPPORT_GAP_M
                      and a.pixels * INSIDE_SHARE <= b.pixels
                      and np.all(centre >= lo) and np.all(centre <= hi)):
                    gap, relation = 2 * SUPPORT_GAP_M, "in"  # within B's height: on a shelf
                    # whose board the item hides (a coffee maker in a bookshelf)
                else:
                    continue
            if best is None or gap < best[0]:
                best = (gap, b, relation)
        if best is not None:
            out[a.instance_id] = Support(best[1], best[2])
    return out
