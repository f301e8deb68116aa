"""Times pixel perception per 640x480 frame: network, close reads, instances, description, map.

Usage: .venv/bin/python -m benchmarks.pixels_bench [--house 100] [--frames 30] [--threads 2]
       [--weights PATH] [--close-reads N]

Frames of one house outside the network's training houses, posed as its training frames are.
Each stage is warmed up on 3 frames, then timed over ``--frames`` frames: ``network`` (the
forward pass and the classes), ``close reads`` (with ``--close-reads N``: the second pass on
up to N crops around supports, ``perception.pixels.close``), ``instances`` (regions and
per-frame labels), ``describe`` (the frame text), ``map`` (the frame's regions lifted and added
to an instance map, which a count question fills: ``mapping.instances``). Prints the median,
min and max milliseconds of each stage and of the total; the budget is 120 ms median for
network + close reads + instances + map on 2 cores.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
import torch

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.mapping.instances import InstanceMap, Region
from efficienteqa.perception.pixels.backend import CLOSE_READS, PixelPerception
from efficienteqa.perception.pixels.close import CloseReads, close_read
from efficienteqa.perception.pixels.frames import house_poses
from efficienteqa.perception.pixels.segment import read_frame
from efficienteqa.perception.semantic import describe_frame


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--house", type=int, default=100)
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--weights", default=None)
    parser.add_argument("--close-reads", type=int, default=CLOSE_READS,
                        help="crops read again a frame (0: off)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    perception = PixelPerception.load(args.weights)
    with SyntheticEnv.from_seed(args.house) as env:
        poses = house_poses(env, args.frames + 3, np.random.default_rng([0, args.house]))
        frames = [env.observe(pose) for _, pose in poses]
    close = CloseReads(crops=args.close_reads)
    times: dict[str, list[float]] = {"network": [], "close reads": [], "instances": [],
                                     "describe": [], "map": []}
    instances = InstanceMap()  # the frames in turn, as an episode's count question fills it
    crops = []
    for n, obs in enumerate(frames):
        t0 = time.perf_counter()
        classes = perception.classify(obs.rgb, obs.depth_m)
        t1 = time.perf_counter()
        if close.crops:
            classes, chosen = close_read(perception.classify, classes, obs.rgb, obs.depth_m,
                                         obs.intrinsics, close)
            crops.append(len(chosen))
        t2 = time.perf_counter()
        instance, labels = read_frame(classes, obs.depth_m, obs.intrinsics, obs.cam_to_world)
        t3 = time.perf_counter()
        describe_frame(replace(obs, instance=instance), labels)
        t4 = time.perf_counter()
        instances.add([Region(o.category, o.points, o.confidence, o.colour, o.room, cut=o.cut)
                       for o in labels.objects])
        t5 = time.perf_counter()
        if n >= 3:  # the first three warm up
            times["network"].append(t1 - t0)
            times["close reads"].append(t2 - t1)
            times["instances"].append(t3 - t2)
            times["describe"].append(t4 - t3)
            times["map"].append(t5 - t4)
    total = np.add(np.add(times["network"], times["close reads"]), times["instances"])
    with_map = total + np.array(times["map"])
    print(f"{'stage':>23} {'median ms':>10} {'min ms':>8} {'max ms':>8}")
    for name, values in (*times.items(), ("network + close + inst.", list(total)),
                         ("... + map (counts)", list(with_map))):
        ms = 1000 * np.array(values)
        print(f"{name:>23} {np.median(ms):10.1f} {ms.min():8.1f} {ms.max():8.1f}")
    if crops:
        read = [(t, c) for t, c in zip(times["close reads"], crops[3:]) if c]
        per_crop = [1000 * t / c for t, c in read]
        print(f"crops read a frame: mean {np.mean(crops[3:]):.2f}, at most {max(crops)}; "
              f"{len(read)} frames with crops, median {np.median(per_crop or [0]):.1f} ms a "
              f"crop; network + close + inst. mean {1000 * np.mean(total):.1f} ms")


if __name__ == "__main__":
    main()
