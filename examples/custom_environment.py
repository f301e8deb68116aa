"""Bring your own environment: a simulator (or a robot's driver) behind ``Environment``.

    python examples/custom_environment.py --vlm openai:gpt-4o
    python examples/custom_environment.py --vlm openai:MODEL@http://127.0.0.1:8000/v1

The agent reads observations (RGB, metric depth along the optical axis, intrinsics, a
camera-to-world pose in OpenCV axes: x right, y down, z forward) and what each move did
(``envs.base.move_info``: blocked, short, where it ended), and asks for poses. A robot's driver
needs nothing else; ``is_navigable``, ``floor_area_m2`` and ``bounds`` below are a simulator's
truth, which the evaluation reads (a start pose's check, the benchmark's step budget) and the
agent never does. This file
is a whole environment in plain numpy: one room, 6 m by 4 m with walls 2.5 m high, and a red box
on the floor, ray-cast at every step. It has no object labels, so a vision-language model reads
its frames (``--perception rgb``); relevancy is the VLM's own yes/no (``vlm-match``).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.ask import ask
from efficienteqa.config.presets import run_config
from efficienteqa.envs.base import move_info
from efficienteqa.geometry import CameraSpec, Pose2D, camera_to_world
from efficienteqa.observation import Observation
from efficienteqa.scenes import Scene

ROOM = (6.0, 4.0, 2.5)  # x, y, height in metres
BOX = ((4.2, 1.2, 0.0), (5.0, 2.0, 0.6))  # min and max corners
COLOURS = {"floor": (150, 120, 90), "wall": (225, 225, 215), "ceiling": (245, 245, 245),
           "box": (200, 30, 30)}


class BoxRoom:
    """``Environment`` for one room and a box (see ``envs.base.Environment``)."""

    def __init__(self, camera: CameraSpec = CameraSpec(width=320, height=240)) -> None:
        self.camera = camera
        self.pose = Pose2D(1.0, 2.0, 0.0)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Observation, dict[str, Any]]:
        start = (options or {}).get("start")
        self.pose = start if start is not None else Pose2D(1.0, 2.0, 0.0)
        return self.observe(), {}

    def step(self, action: Pose2D) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        blocked = not self.is_navigable(action.x, action.y)
        if not blocked:
            self.pose = action
        return self.observe(), 0.0, False, False, move_info(action, self.pose, blocked)

    def is_navigable(self, x: float, y: float) -> bool:
        margin = 0.25  # the robot's radius
        inside = margin <= x <= ROOM[0] - margin and margin <= y <= ROOM[1] - margin
        (x0, y0, _), (x1, y1, _) = BOX
        return inside and not (x0 - margin <= x <= x1 + margin and y0 - margin <= y <= y1 + margin)

    @property
    def floor_area_m2(self) -> float:
        return ROOM[0] * ROOM[1]

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(3), np.array(ROOM)

    def close(self) -> None:
        pass

    def observe(self) -> Observation:
        cam = self.camera
        pose = camera_to_world(self.pose, cam)
        k = np.array([[cam.fx, 0, cam.width / 2], [0, cam.fy, cam.height / 2], [0, 0, 1.0]])
        u, v = np.meshgrid(np.arange(cam.width) + 0.5, np.arange(cam.height) + 0.5)
        rays = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones_like(u)], -1)
        d = rays @ pose[:3, :3].T  # world direction per pixel, with camera-z 1: t is the depth
        o = pose[:3, 3]
        depth = np.full(u.shape, np.inf)
        rgb = np.zeros((*u.shape, 3), np.uint8)
        planes = [(2, 0.0, "floor"), (2, ROOM[2], "ceiling"), (0, 0.0, "wall"),
                  (0, ROOM[0], "wall"), (1, 0.0, "wall"), (1, ROOM[1], "wall")]
        for axis, at, name in planes:
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (at - o[axis]) / d[..., axis]
            hit = (t > 0) & (t < depth)
            depth[hit], rgb[hit] = t[hit], COLOURS[name]
        lo, hi = np.array(BOX[0]), np.array(BOX[1])
        with np.errstate(divide="ignore", invalid="ignore"):  # slab test for the box
            t0, t1 = (lo - o) / d, (hi - o) / d
        near = np.minimum(t0, t1).max(-1)
        far = np.maximum(t0, t1).min(-1)
        hit = (near <= far) & (near > 0) & (near < depth)
        depth[hit], rgb[hit] = near[hit], COLOURS["box"]
        shade = np.clip(1.0 - 0.06 * depth, 0.5, 1.0)[..., None]  # farther is darker
        rgb = (rgb * shade).astype(np.uint8)
        depth = np.where(np.isfinite(depth), depth, 0.0).astype(np.float32)
        return Observation(rgb, depth, pose, k, self.pose)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("question", nargs="?", default="What colour is the box?")
    parser.add_argument("--vlm", required=True, help="an image VLM, e.g. openai:gpt-4o")
    parser.add_argument("--max-steps", type=int, default=6)
    parser.add_argument("--out", type=Path, default=Path("out/box-room"))
    args = parser.parse_args(argv)

    run = run_config(None, {"backends.vlm": args.vlm, "backends.perception": "rgb",
                            "backends.relevancy": "vlm-match",
                            "explore.max_steps": args.max_steps})
    scene = Scene(BoxRoom(), "box-room")
    done = ask(args.question, scene, args.out, run=run)
    print(f"answer: {done.result.answer} after {done.result.steps} steps "
          f"({done.result.stop_reason}); report: {done.report_html}")


if __name__ == "__main__":
    main()
