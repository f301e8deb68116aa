"""Which messages make each frame of an MCAP walk: what the first pass keeps of the messages
(their stamps, not their pixels), and the pairing of each colour frame with the depth frame
nearest in stamp, its instance ids, intrinsics and pose from /tf. Plain arrays and stamps, kept
apart from the MCAP file's reading (``rosbag``) so the rules of a usable frame read in one place.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from efficienteqa.envs.recorded.mcapwalk import McapOptions
from efficienteqa.envs.recorded.tf import TFTree
from efficienteqa.envs.recorded.walk import RecordedCamera
from efficienteqa.errors import EfficientEQAError


@dataclass(frozen=True)
class Image:
    """What the first pass keeps of an image message (not its pixels)."""

    ordinal: int  # its place among its topic's messages, in the file's log-time order
    stamp: int
    frame_id: str
    width: int
    height: int
    encoding: str


Info = tuple[int, np.ndarray, int, int]  # a camera_info: stamp, K (this project's), width, height


@dataclass(frozen=True)
class Frame:
    """A usable frame: which messages make it, its pose and intrinsics."""

    colour: int
    depth: int
    instance: int | None
    stamp: int
    cam_to_world: np.ndarray
    intrinsics: np.ndarray


def plan(name: str, options: McapOptions, colour_topic: str, depth_topic: str,
         camera_frame: str, colours: list[Image], depths: list[Image], instances: list[Image],
         infos: list[Info], tree: TFTree, labelled: bool
         ) -> tuple[list[Frame], RecordedCamera, str]:
    """Pair each colour frame with its depth, instance ids, intrinsics and pose: the usable
    frames, the camera (of the first) and the note that says how many were dropped and why.
    ``name`` (the file's) and the two topics are named in its errors; ``labelled``: the walk
    has the simulator's labels."""
    o = options
    if not colours:
        raise EfficientEQAError(f"{name}: the colour topic {colour_topic} has no message",
                                fix="record a walk with colour frames")
    sizes = {(c.width, c.height) for c in colours}
    if len(sizes) > 1:
        raise EfficientEQAError(f"{name}: the colour frames change size "
                                f"({', '.join(f'{w}x{h}' for w, h in sorted(sizes))})",
                                fix="record one camera resolution")
    (w, h), = sizes
    if not depths:
        raise EfficientEQAError(f"{name}: the depth topic {depth_topic} has no message",
                                fix="record depth registered to colour")
    other = next(((d.width, d.height) for d in depths if (d.width, d.height) != (w, h)), None)
    if other is not None:
        raise EfficientEQAError(
            f"{name}: colour frames are {w}x{h} and depth frames {other[0]}x{other[1]}: "
            "depth must be registered to colour (the same pixels)",
            fix="record depth aligned to colour, e.g. /camera/aligned_depth_to_color/image_raw")
    if not infos:
        raise EfficientEQAError(f"{name} has no camera_info message",
                                fix="record the colour camera's sensor_msgs/msg/CameraInfo")
    bad = next(((iw, ih) for _, _, iw, ih in infos if (iw, ih) != (w, h)), None)
    if bad is not None:
        raise EfficientEQAError(f"{name}: camera_info is for {bad[0]}x{bad[1]} images, "
                                f"the colour frames are {w}x{h}",
                                fix="name the colour camera's: ?info=TOPIC after the path")
    if any(k[0, 0] <= 0 or k[1, 1] <= 0 for _, k, _, _ in infos):
        raise EfficientEQAError(f"{name}: camera_info has no calibration (K is zero)",
                                fix="calibrate the camera, or record its driver's camera_info")
    tree.chain(o.world, camera_frame)  # no path at all: one line now
    # A frame is placed by its header stamp alone (its pose from /tf, its depth): frames
    # that share a stamp get one pose and one depth. When every colour frame has the same
    # stamp (a driver that leaves header.stamp unset, or zeroes it), the walk cannot be
    # placed at all and would be read as a camera standing still: refused. When only some
    # share one, the rest of the walk is sound: read, with a warning in the note.
    stamps = [c.stamp for c in colours]
    if len(stamps) > 1 and len(set(stamps)) == 1:
        raise EfficientEQAError(
            f"{name}: all {len(stamps)} colour frames of {colour_topic} have the stamp "
            f"{stamps[0] / 1e9:.9f} s, so they cannot be placed (each would get the same "
            "pose and depth)", fix="record with the camera driver's stamps (header.stamp)")
    shared = len(stamps) - len(set(stamps))
    depth_stamps = np.array([d.stamp for d in depths])
    depth_order = np.argsort(depth_stamps, kind="stable")
    inst_stamps = np.array([i.stamp for i in instances])
    inst_order = np.argsort(inst_stamps, kind="stable")
    info_stamps = np.array([s for s, _, _, _ in infos])
    depth_tol = int(o.depth_tolerance_ms * 1e6)
    tf_tol = int(o.tf_tolerance_ms * 1e6)
    frames: list[Frame] = []
    no_depth = no_pose = 0
    for c in sorted(colours, key=lambda c: c.stamp):
        d = nearest(depth_stamps[depth_order], c.stamp, depth_tol)
        if d is None:
            no_depth += 1
            continue
        pose = tree.lookup(o.world, camera_frame, c.stamp, tf_tol)
        if pose is None:
            no_pose += 1
            continue
        i = nearest(inst_stamps[inst_order], c.stamp, depth_tol) if len(instances) else None
        k = infos[int(np.argmin(np.abs(info_stamps - c.stamp)))][1]
        frames.append(Frame(c.ordinal, depths[int(depth_order[d])].ordinal,
                            None if i is None else instances[int(inst_order[i])].ordinal,
                            c.stamp, pose, k))
    total = len(colours)
    why = (f"{no_depth} without depth within {o.depth_tolerance_ms:g} ms, "
           f"{no_pose} without a pose from {o.world!r}")
    if not frames:
        raise EfficientEQAError(f"{name} has no usable frame: {total} colour frames, {why}",
                                fix="record depth and /tf with the colour frames, or widen "
                                    "?depth_tolerance_ms= / ?tf_tolerance_ms= after the path")
    camera = RecordedCamera.of(w, h, frames[0].intrinsics, frames[0].cam_to_world)
    dropped = total - len(frames)
    depth_frame = depths[0].frame_id
    note = (f"{name}: {len(frames)} frames of {total}"
            + (f" ({dropped} dropped: {why})" if dropped else "")
            + ("" if depth_frame == camera_frame else
               f"; depth ({depth_frame}) read as registered to colour ({camera_frame})")
            + ("; with the simulator's labels" if labelled else "")
            + (f"; warning: {shared} colour frames repeat another's stamp, so they get "
               "its pose and depth" if shared else ""))
    return frames, camera, note


def nearest(sorted_stamps: np.ndarray, stamp: int, tolerance: int) -> int | None:
    """Index of the stamp nearest ``stamp`` in a sorted array, if within ``tolerance``."""
    if len(sorted_stamps) == 0:
        return None
    i = int(np.searchsorted(sorted_stamps, stamp))
    best = min((j for j in (i - 1, i) if 0 <= j < len(sorted_stamps)),
               key=lambda j: abs(int(sorted_stamps[j]) - stamp))
    return best if abs(int(sorted_stamps[best]) - stamp) <= tolerance else None
