"""Times pixel perception per 640x480 frame: the network, the instances, and the description.

Usage: .venv/bin/python -m benchmarks.pixels_bench [--house 100] [--frames 30] [--threads 2]
       [--weights PATH]

Frames of one house outside the network's training houses, posed as its training frames are.
Each stage is warmed up on 3 frames, then timed over ``--frames`` frames: ``network`` (the
forward pass and the classes), ``instances`` (regions and per-frame labels), ``describe`` (the
frame text), ``map`` (the frame's regions lifted and added to an instance map, which a count
question fills: ``mapping.instances``). Prints the median, min and max milliseconds of each
stage and of the total; the budget is 100 ms median for network + instances on 2 cores, 120 ms
with the map.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
import torch

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.mapping.instances import InstanceMap, Region
from efficienteqa.perception.pixels.backend import PixelPerception
from efficienteqa.perception.pixels.dataset import house_poses
from efficienteqa.perception.pixels.segment import read_frame
from efficienteqa.perception.semantic import describe_frame


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--house", type=int, default=100)
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--weights", default=None)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    perception = PixelPerception.load(args.weights)
    with SyntheticEnv.from_seed(args.house) as env:
        poses = house_poses(env, args.frames + 3, np.random.default_rng([0, args.house]))
        frames = [env.observe(pose) for _, pose in poses]
    times: dict[str, list[float]] = {"network": [], "instances": [], "describe": [], "map": []}
    instances = InstanceMap()  # the frames in turn, as an episode's count question fills it
    for n, obs in enumerate(frames):
        t0 = time.perf_counter()
        classes = perception.classify(obs.rgb, obs.depth_m)
        t1 = time.perf_counter()
        instance, labels = read_frame(classes, obs.depth_m, obs.intrinsics, obs.cam_to_world)
        t2 = time.perf_counter()
        describe_frame(replace(obs, instance=instance), labels)
        t3 = time.perf_counter()
        instances.add([Region(o.category, o.points, o.confidence, o.colour, o.room, cut=o.cut)
                       for o in labels.objects])
        t4 = time.perf_counter()
        if n >= 3:  # the first three warm up
            times["network"].append(t1 - t0)
            times["instances"].append(t2 - t1)
            times["describe"].append(t3 - t2)
            times["map"].append(t4 - t3)
    total = np.add(times["network"], times["instances"])
    with_map = total + np.array(times["map"])
    print(f"{'stage':>22} {'median ms':>10} {'min ms':>8} {'max ms':>8}")
    for name, values in (*times.items(), ("network + instances", list(total)),
                         ("... + map (counts)", list(with_map))):
        ms = 1000 * np.array(values)
        print(f"{name:>22} {np.median(ms):10.1f} {ms.min():8.1f} {ms.max():8.1f}")


if __name__ == "__main__":
    main()
