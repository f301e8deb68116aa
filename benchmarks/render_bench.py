"""Times the off-screen renderer on synthetic scenes of a given triangle count.

Usage: .venv/bin/python -m benchmarks.render_bench [--triangles 150000 330000]
       [--sizes 640x480 320x240] [--frames 30] [--lights 8]

Each scene is a 12 x 12 m textured floor, walls on a 4 m grid, textured and plain boxes
("furniture", 12 triangles each) and dense icospheres that bring it to the requested count.
The camera (DESIGN 3.1 default: 1.5 m high, 30 deg down, 120 deg FOV) walks a circle inside; each
size is warmed up, then timed over ``--frames`` renders (read-back of RGB, depth and instance
included). Prints median and 95th percentile milliseconds per frame.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import trimesh

from efficienteqa.envs.synthetic.mesh import MeshPart, box_part
from efficienteqa.envs.synthetic.render import Renderer
from efficienteqa.envs.synthetic.scene_geometry import PointLight, SceneGeometry
from efficienteqa.envs.synthetic.textures import FLOOR_KINDS, floor_texture, wall_texture
from efficienteqa.geometry import CameraSpec, Pose2D, camera_to_world

HALF_M = 6.0


def build_scene(n_triangles: int, n_lights: int, seed: int = 0) -> SceneGeometry:
    """About ``n_triangles`` triangles (never fewer) in a 12 x 12 m walled area."""
    rng = np.random.default_rng(seed)
    parts: list[MeshPart] = []
    floor = box_part((2 * HALF_M, 2 * HALF_M, 0.1), (1.0, 1.0, 1.0), (0.0, 0.0, -0.05))
    floor.texture = floor_texture("wood", seed)
    parts.append(floor)
    wall_tex = wall_texture(seed)
    for c in np.arange(-HALF_M, HALF_M + 0.1, 4.0):
        for size, centre in (((0.1, 2 * HALF_M, 2.6), (c, 0.0, 1.3)),
                             ((2 * HALF_M, 0.1, 2.6), (0.0, c, 1.3))):
            wall = box_part(size, (0.9, 0.88, 0.84), centre)
            wall.texture = wall_tex
            parts.append(wall)
    textures = [floor_texture(kind, seed + i) for i, kind in enumerate(FLOOR_KINDS)]
    n_boxes = max(50, n_triangles // 6 // 12)  # about a sixth of the triangles in boxes
    for i in range(n_boxes):
        size = tuple(rng.uniform(0.1, 0.8, 3))
        centre = (*rng.uniform(-HALF_M + 0.5, HALF_M - 0.5, 2), size[2] / 2 + rng.uniform(0, 1))
        box = box_part(size, tuple(rng.uniform(0.2, 1.0, 3)), centre)
        box.instance_id = i + 1
        if i % 3 == 0:
            box.texture = textures[i % len(textures)]
        box.emissive = 1.0 if i % 50 == 0 else 0.0
        parts.append(box)
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.3)  # 5120 triangles
    while sum(len(p.faces) for p in parts) < n_triangles:
        centre = np.array([*rng.uniform(-HALF_M + 0.5, HALF_M - 0.5, 2), rng.uniform(0.3, 2.0)])
        parts.append(MeshPart(
            positions=(sphere.vertices + centre).astype(np.float32),
            normals=np.asarray(sphere.vertex_normals, np.float32),
            faces=sphere.faces.astype(np.uint32),
            colour=tuple(rng.uniform(0.2, 1.0, 3)),
            instance_id=len(parts) + 1,
        ))
    lights = [PointLight((*rng.uniform(-HALF_M, HALF_M, 2), 2.4), radius_m=5.0)
              for _ in range(n_lights)]
    return SceneGeometry(parts, lights)


def time_renders(renderer: Renderer, camera: CameraSpec, frames: int) -> np.ndarray:
    """Milliseconds per frame over ``frames`` poses on a circle (after 3 warm-up frames)."""
    poses = [camera_to_world(Pose2D(2.0 * math.cos(a), 2.0 * math.sin(a), a + 1.0), camera)
             for a in np.linspace(0, 2 * math.pi, frames, endpoint=False)]
    for pose in poses[:3]:
        renderer.render(pose, camera)
    times = []
    for pose in poses:
        start = time.perf_counter()
        renderer.render(pose, camera)
        times.append((time.perf_counter() - start) * 1000)
    return np.array(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", type=int, nargs="+", default=[150_000, 330_000])
    parser.add_argument("--sizes", nargs="+", default=["640x480", "320x240", "160x120"])
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--lights", type=int, default=8)
    args = parser.parse_args()
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes]
    camera = CameraSpec()
    print(f"{'triangles':>10} {'parts':>6} {'upload ms':>10} {'size':>8} "
          f"{'median ms':>10} {'p95 ms':>8}")
    with Renderer(camera) as renderer:
        for n in args.triangles:
            scene = build_scene(n, args.lights)
            n_tri = sum(len(p.faces) for p in scene.parts)
            start = time.perf_counter()
            renderer.set_scene(scene)
            upload_ms = (time.perf_counter() - start) * 1000
            for width, height in sizes:
                ms = time_renders(renderer, camera.scaled(width, height), args.frames)
                print(f"{n_tri:>10} {len(scene.parts):>6} {upload_ms:>10.0f} "
                      f"{f'{width}x{height}':>8} {np.median(ms):>10.1f} "
                      f"{np.percentile(ms, 95):>8.1f}")


if __name__ == "__main__":
    main()
