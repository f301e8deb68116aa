"""Synthetic houses end to end: generation, upload, rendering in real houses, questions.

Prints one row per house and the medians. Back-ends: synthetic environment, Sweet Home 3D CC0
furniture (or --assets builtin), moderngl on EGL/llvmpipe (CPU).

    python -m benchmarks.scene_bench --seeds 0 1 2 3 4
    python -m benchmarks.scene_bench --rooms 6      # five 6-room houses
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np

from efficienteqa.envs.synthetic.build import build_geometry
from efficienteqa.envs.synthetic.env import SyntheticEnv, catalog_for
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M, generate_house
from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.scenes import synthetic_questions


def bench(seed: int, assets: str, frames: int, camera: CameraSpec) -> dict[str, float]:
    catalog = catalog_for(assets)
    t0 = time.perf_counter()
    house = generate_house(seed, catalog, assets)
    t1 = time.perf_counter()
    geometry = build_geometry(house, catalog)
    triangles = sum(len(p.faces) for p in geometry.parts)
    t2 = time.perf_counter()
    env = SyntheticEnv(house, catalog, camera)
    t3 = time.perf_counter()
    rng = np.random.default_rng(seed)
    cells = np.argwhere(env.grid.navigable(ROBOT_RADIUS_M))
    poses = [Pose2D(*env.grid.spec.cell_to_world(c), rng.uniform(-np.pi, np.pi))
             for c in cells[rng.choice(len(cells), frames)]]
    env.observe(poses[0])  # warm-up
    times = []
    for pose in poses:
        start = time.perf_counter()
        env.observe(pose)
        times.append(time.perf_counter() - start)
    t4 = time.perf_counter()
    questions = synthetic_questions(env)
    t5 = time.perf_counter()
    env.close()
    return {
        "seed": seed, "rooms": len(house.layout.rooms), "objects": len(house.objects),
        "ktris": triangles / 1e3, "generate_s": t1 - t0, "build_s": t2 - t1,
        "upload_s": t3 - t2, "render_ms_med": 1e3 * float(np.median(times)),
        "render_ms_p95": 1e3 * float(np.percentile(times, 95)), "questions": len(questions),
        "questions_s": t5 - t4,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--rooms", type=int, default=None,
                        help="only houses with this many rooms (seeds are searched upwards)")
    parser.add_argument("--assets", default="sh3d", choices=["sh3d", "builtin"])
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--size", default="640x480")
    args = parser.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    camera = CameraSpec().scaled(w, h)
    seeds = args.seeds
    if args.rooms is not None:
        catalog = catalog_for(args.assets)
        seeds = [s for s in range(500)
                 if len(generate_house(s, catalog, args.assets).layout.rooms) == args.rooms]
        seeds = seeds[: len(args.seeds)]
    rows = [bench(s, args.assets, args.frames, camera) for s in seeds]
    keys = list(rows[0])
    print(f"assets={args.assets} size={args.size} frames/house={args.frames}")
    print(" ".join(f"{k:>13}" for k in keys))
    for row in rows:
        print(" ".join(f"{row[k]:>13.2f}" if isinstance(row[k], float) else f"{row[k]:>13}"
                       for k in keys))
    print(" ".join(f"{'median':>13}" if k == "seed" else f"{np.median([r[k] for r in rows]):>13.2f}"
                   for k in keys))
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory of this process: {peak_mib:.0f} MiB")


if __name__ == "__main__":
    main()
