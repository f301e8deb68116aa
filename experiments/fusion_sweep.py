"""Choose FUSED_MIN (perception/pixels/fusion.py) on validation walks: objects found and right
per frame, with the per-category thresholds alone and with evidence fused over each walk.

Frames are the agent's own walks (experiments/walk_poses.py) in validation houses 3900-3909,
every frame of each walk in order (fusion needs the sequence). Back-ends: synthetic houses
(sh3d), the committed pixel network and its recorded thresholds, no language model.

    python -m experiments.fusion_sweep --houses 3900-3909 --poses out/walks-validation.json
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from efficienteqa.perception.pixels.backend import PixelPerception
from efficienteqa.perception.pixels.evaluate import heldout_frames, read_poses
from efficienteqa.perception.pixels.thresholds import collect, overall
from experiments.common import seed_set
from experiments.walk_poses import walk

GRID = (0.8, 1.0, 1.2, 1.5, 2.0, 2.5, 3.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--houses", default="3900-3909")
    parser.add_argument("--poses", type=Path, default=Path("out/walks-validation.json"))
    parser.add_argument("--frames", type=int, default=1000, help="at most this many per walk")
    args = parser.parse_args()
    houses = seed_set(args.houses)
    if not args.poses.is_file():
        walks = {str(h): dict(zip(("question", "poses"), walk(h))) for h in houses}
        args.poses.parent.mkdir(parents=True, exist_ok=True)
        args.poses.write_text(json.dumps({"houses": walks}) + "\n")
    poses = read_poses(args.poses)
    perception = PixelPerception.load()
    thresholds = perception.record.get("region_thresholds", {})
    first = {tuple(poses[h][0]) for h in houses}
    frames = heldout_frames(houses, args.frames, poses=poses)
    candidates = collect(frames, perception.classify,
                         episodes=lambda obs: (obs.pose.x, obs.pose.y, obs.pose.yaw) in first)
    n = sum(len(v) for v in candidates.objects.values())
    print(f"{len(houses)} walks, {n} objects in view (houses {args.houses})")
    for fused_min in (math.inf, *GRID):
        found, right = overall(candidates, thresholds, fused_min)
        print(f"FUSED_MIN {fused_min}: found {found:.1%}, right {right:.1%}")
    categories = set(candidates.objects) | set(candidates.regions)
    for level in (0.4, 0.5, 0.6, 0.7, 0.8):  # one threshold for every category, no fusion
        found, right = overall(candidates, dict.fromkeys(categories, level))
        print(f"MIN_CONFIDENCE {level}: found {found:.1%}, right {right:.1%}")


if __name__ == "__main__":
    main()
