"""Relation bench (DESIGN 9, defect 3 of the walks): how right the frame text's "on"/"in" is, by item size.

On random poses of synthetic houses, every relation the text states ("a cup on the brown table",
"a coffee maker in the white bookshelf") is checked against the house's own record of what the
item stands on (``PlacedObject.support_id``, never read by the perception); every true relation
whose two objects the text lists but does not relate is counted as missed. Rows are by the
item's pixel count (at 640x480), so the gate's item-size threshold can be chosen by measurement:
the gate passes what the text says, and the text lists objects from
``perception.visible.REFERENCE_MIN_PIXELS``.

    python -m experiments.relation_bench --seeds training --poses 12

Develop on the training houses (0-20).
"""

from __future__ import annotations

import argparse
import math
from collections import Counter

import numpy as np

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M
from efficienteqa.geometry import Pose2D
from efficienteqa.perception.semantic import describe_frame
from experiments.common import seed_set

LEAST_PIXELS = 60  # below the text's 150 px, to see where relations turn unreliable
BINS = ((0, 100), (100, 150), (150, 250), (250, 400), (400, 10 ** 9))


def size_bin(pixels: int) -> str:
    lo, hi = next(b for b in BINS if b[0] <= pixels < b[1])
    return f"{lo}-{hi if hi < 10 ** 9 else ''}"


def frame_counts(d, house) -> Counter:  # noqa: ANN001 (FrameDescription, House)
    """Stated relations right/wrong and true relations missed, per item size bin."""
    out: Counter = Counter()
    listed = {o.instance_id: o for o in d.objects}
    for o in d.objects:
        truth = house.object(o.instance_id).support_id if o.label.door is None else None
        key = size_bin(o.pixels)
        if o.support_id is not None:
            right = truth == o.support_id
            out[(key, o.relation, "right" if right else "wrong")] += 1
        elif truth is not None and truth in listed:
            out[(key, "-", "missed")] += 1
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", default="training")
    ap.add_argument("--poses", type=int, default=12, help="random poses per house")
    ap.add_argument("--assets", default="sh3d")
    args = ap.parse_args()
    seeds = seed_set(args.seeds)
    if any(s > 20 for s in seeds):
        raise SystemExit("tune on training houses 0-20 only")
    total: Counter = Counter()
    frames = 0
    for seed in seeds:
        rng = np.random.default_rng([seed, 33])
        with SyntheticEnv.from_seed(seed, args.assets) as env:
            cells = np.argwhere(env.grid.navigable(ROBOT_RADIUS_M))
            labels = env.scene_labels()
            for _ in range(args.poses):
                x, y = env.grid.spec.cell_to_world(cells[rng.integers(len(cells))])
                for k in range(4):
                    yaw = float(rng.uniform(-math.pi, math.pi)) + k * math.pi / 2
                    d = describe_frame(env.observe(Pose2D(float(x), float(y), yaw)), labels,
                                       min_pixels=LEAST_PIXELS)
                    total += frame_counts(d, env.house)
                    frames += 1
    print(f"seeds {args.seeds} ({seeds[0]}-{seeds[-1]}), {frames} frames "
          f"({args.poses} random poses x 4 headings per house)")
    print("| item px | on right | on wrong | in right | in wrong | missed |")
    print("|---|---|---|---|---|---|")
    for lo, _ in BINS:
        key = size_bin(lo)
        print(f"| {key} | " + " | ".join(str(total[(key, r, v)]) for r, v in
                                          (("on", "right"), ("on", "wrong"), ("in", "right"),
                                           ("in", "wrong"), ("-", "missed"))) + " |")


if __name__ == "__main__":
    main()
