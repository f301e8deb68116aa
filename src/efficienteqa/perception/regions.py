"""The semantic sensor's objects and floor as points in the world (DESIGN 5): the regions it adds
to the episode's instance map (``object_regions``) and its sightings of rooms, the target's
things and doors (``sightings``).

Apart from the frame text (``perception.semantic``) because these are not words: they are what
the instance map, the explorer and the gate read, and the pixel perception reuses them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from efficienteqa.envs.base import SceneLabels
from efficienteqa.geometry import backproject
from efficienteqa.mapping.instances import Region
from efficienteqa.perception.base import Sighting, Sightings
from efficienteqa.perception.floor import floor_view, where_words
from efficienteqa.perception.visible import (
    REFERENCE_AREA_PX,
    FrameDescription,
    NoiseConfig,
    scaled_min_pixels,
    visible_objects,
)
from efficienteqa.question import Target

if TYPE_CHECKING:
    from efficienteqa.observation import Observation

SIGHTING_STRIDE = 4  # floor and object points of a sighting: every 4th pixel each way
GLIMPSE_PIXELS = 20  # at 640x480: an object of the target this large is a sighting


def object_regions(obs: Observation, labels: SceneLabels, described: FrameDescription,
                   confidence: dict[int, float] | None = None, keyed: bool = True,
                   noise: NoiseConfig | None = None) -> list[Region]:
    """The frame's objects of at least GLIMPSE_PIXELS (scaled), as the sightings take them, as
    regions of an instance map (``mapping.instances``): world points of every
    SIGHTING_STRIDE-th pixel each way, the room where the frame shows it (as the text says),
    its colour, what the text says it stands on (``described``), whether the frame cuts it,
    ``confidence`` per instance id (default 1) and, when ``keyed``, its id as the key."""
    if obs.instance is None:
        return []
    h, w = obs.depth_m.shape
    k = SIGHTING_STRIDE
    glimpse = max(1, round(GLIMPSE_PIXELS * h * w / REFERENCE_AREA_PX))
    found = visible_objects(obs, labels, glimpse, noise)
    if not found:
        return []
    intrinsics = obs.intrinsics.astype(np.float64).copy()
    intrinsics[:2] /= k
    points = backproject(obs.depth_m[k // 2::k, k // 2::k], intrinsics, obs.cam_to_world)
    small = obs.instance[k // 2::k, k // 2::k]
    valid = obs.depth_m[k // 2::k, k // 2::k] > 0
    boxes = ndimage.find_objects(np.where(obs.instance > 0, obs.instance, 0))
    rooms = set(described.rooms_in_view)
    camera_xy = (float(obs.cam_to_world[0, 3]), float(obs.cam_to_world[1, 3]))
    order = {o.instance_id: n for n, o in enumerate(found)}
    under = {o.instance_id: o.support_id for o in described.objects}
    out = []
    for o in found:
        mask = (small == o.instance_id) & valid
        if mask.any():
            p = points[mask]
        else:  # a sliver between the strided pixels: all of its own
            full = (obs.instance == o.instance_id) & (obs.depth_m > 0)
            p = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[full]
        box = boxes[o.instance_id - 1]
        cut = box is not None and (box[1].start == 0 or box[1].stop == w or box[0].start == 0)
        where = where_words(o.label, rooms, described.room, camera_xy)
        support = under.get(o.instance_id)
        out.append(Region(o.label.category, p,
                          1.0 if confidence is None else confidence.get(o.instance_id, 1.0),
                          o.label.colour,
                          where[len("in the "):] if where and where.startswith("in the ") else None,
                          o.instance_id if keyed else None,
                          order.get(support) if support is not None else None, cut))
    return out


def sightings(obs: Observation, labels: SceneLabels, target: Target,
              noise: NoiseConfig | None = None) -> Sightings:
    """What the frame shows of the rooms (floor points per room, as ``floor_view`` names them),
    of the target's things (objects whose category the question names, from GLIMPSE_PIXELS
    scaled) and of the doors (where each is; no room through it: the floor beyond says):
    only what the frame shows, like the text."""
    h, w = obs.depth_m.shape
    k = SIGHTING_STRIDE
    points = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)
    view = floor_view(obs, labels, points)
    index = view.room_index[::k, ::k]
    xy = points[::k, ::k, :2]
    floor = {room: xy[index == n] for n, room in enumerate(view.rooms) if (index == n).any()}
    things: list[Sighting] = []
    doors: list[Sighting] = []
    wanted = target.things
    if obs.instance is not None:
        glimpse = max(1, round(GLIMPSE_PIXELS * h * w / REFERENCE_AREA_PX))
        rooms = set(view.in_view(scaled_min_pixels(h, w)))
        here = labels.room_at(obs.pose.x, obs.pose.y)
        camera_xy = (float(obs.cam_to_world[0, 3]), float(obs.cam_to_world[1, 3]))
        for o in visible_objects(obs, labels, glimpse, noise):
            door = o.label.category == "door"  # where it is only: the rooms it joins are
            # what the floor beyond shows, never the label's
            if not door and not any(target.is_a(t, o.label.category) for t in wanted):
                continue
            mask = (obs.instance == o.instance_id) & (obs.depth_m > 0)
            rows, cols = np.nonzero(mask)
            p = points[mask]
            cut = bool(cols.min() == 0 or cols.max() == w - 1 or rows.min() == 0)
            place = (float(np.median(p[:, 0])), float(np.median(p[:, 1])))
            top = float(np.percentile(p[:, 2], 98))
            if door:
                doors.append(Sighting("door", place, top, o.pixels, cut, None))
            if any(target.is_a(t, o.label.category) for t in wanted):
                where = where_words(o.label, rooms, here, camera_xy)
                room = where[len("in the "):] if where and where.startswith("in the ") else None
                things.append(Sighting(o.label.category, place, top, o.pixels, cut, room))
    return Sightings(floor, tuple(things), tuple(doors))
