"""Per-step cost of the map: TSDF fusion and the 2-D maps, over a scripted 40-step trajectory.

Renders every frame first (rendering is not timed), warms numba up, then replays the frames
into a fresh ``Mapper``. Prints median / p95 ms per step for each part and the cost at steps
1-10 against 31-40 (it should stay flat as the episode grows), and the last 10 frames replayed
into an empty map: equal costs mean the cost follows the view, not the history.

    python -m benchmarks.mapping_bench                 # first 6-room house, sh3d furniture
    python -m benchmarks.mapping_bench --seed 3 --assets builtin
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from efficienteqa.envs.synthetic.env import SyntheticEnv, catalog_for
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M, generate_house
from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.mapping.maps2d import Mapper
from efficienteqa.mapping.navgrid import truncate_path
from efficienteqa.mapping.tsdf import VolumeSpec


def room_tour(env: SyntheticEnv, steps: int, step_m: float = 3.0) -> list[Pose2D]:
    """Poses visiting the room centres in turn (nearest first, then cycling), at most step_m
    apart along ground-truth shortest paths, each facing the way the path goes on."""
    grid, pose = env.grid, env.house.start
    rooms = sorted(env.house.layout.rooms, key=lambda r: math.dist(r.centre, (pose.x, pose.y)))
    poses, k = [pose], 0
    while len(poses) < steps and k < 10 * steps:
        goal, k = rooms[k % len(rooms)].centre, k + 1
        path = grid.shortest_path((pose.x, pose.y), goal, ROBOT_RADIUS_M, snap_m=2.0)
        while path is not None and len(poses) < steps and math.dist(path[0], path[-1]) > 0.3:
            x, y = (float(v) for v in truncate_path(path, step_m))
            path = grid.shortest_path((x, y), goal, ROBOT_RADIUS_M, snap_m=2.0)
            dx, dy = x - pose.x, y - pose.y
            if path is not None and len(path) > 1:
                dx, dy = path[1] - path[0]
            pose = Pose2D(x, y, math.atan2(dy, dx))
            poses.append(pose)
    return poses


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=None,
                        help="house seed (default: the first seed with --rooms rooms)")
    parser.add_argument("--rooms", type=int, default=6)
    parser.add_argument("--assets", default="sh3d", choices=["sh3d", "builtin"])
    parser.add_argument("--steps", type=int, default=40)
    parser.add_argument("--size", default="640x480")
    args = parser.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    seed = args.seed
    if seed is None:
        catalog = catalog_for(args.assets)
        seed = next(s for s in range(500)
                    if len(generate_house(s, catalog, args.assets).layout.rooms) == args.rooms)
    with SyntheticEnv.from_seed(seed, args.assets, CameraSpec().scaled(w, h)) as env:
        poses = room_tour(env, args.steps)
        frames = [env.observe(p) for p in poses]
        lo, hi = env.bounds
        rooms = len(env.house.layout.rooms)
    spec = VolumeSpec.around(lo[:2], hi[:2], floor_z=0.0)
    warm = Mapper(spec, 0.0, (poses[0].x, poses[0].y))  # numba compile / cache load
    warm.update(frames[0])

    mapper = Mapper(spec, 0.0, (poses[0].x, poses[0].y))
    fuse_ms, maps_ms = [], []
    for obs in frames:
        t0 = time.perf_counter()
        mapper.integrate(obs)
        t1 = time.perf_counter()
        state = mapper.state((obs.pose.x, obs.pose.y))
        t2 = time.perf_counter()
        fuse_ms.append(1e3 * (t1 - t0))
        maps_ms.append(1e3 * (t2 - t1))
    fuse, maps = np.array(fuse_ms), np.array(maps_ms)
    print(f"seed={seed} rooms={rooms} assets={args.assets} size={args.size} steps={len(frames)} "
          f"volume={spec.shape} ({np.prod(spec.shape) / 1e6:.2f} M voxels)")
    last = f"steps{len(frames) - 9}-{len(frames)}"
    print(f"{'part':>10} {'median_ms':>10} {'p95_ms':>10} {'steps1-10':>10} {last:>11}")
    for name, t in (("integrate", fuse), ("maps2d", maps), ("total", fuse + maps)):
        print(f"{name:>10} {np.median(t):>10.2f} {np.percentile(t, 95):>10.2f} "
              f"{np.median(t[:10]):>10.2f} {np.median(t[-10:]):>11.2f}")
    fresh = Mapper(spec, 0.0, (poses[0].x, poses[0].y))
    fresh_ms = []
    for obs in frames[-10:]:  # the same views without the history: what the cost depends on
        t0 = time.perf_counter()
        fresh.update(obs)
        fresh_ms.append(1e3 * (time.perf_counter() - t0))
    print(f"{'fresh map':>10} {'':>10} {'':>10} {'':>10} {np.median(fresh_ms):>11.2f}"
          f"   (last 10 frames replayed into an empty map)")
    print(f"final: free {state.free.sum()} cells, island {state.island.sum()}, explored "
          f"{state.explored.sum()} of {state.free.size}")


if __name__ == "__main__":
    main()
