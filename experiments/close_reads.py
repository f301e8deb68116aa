"""Choose the pixel perception's close reads (perception/pixels/close.py) on validation houses:
small objects within 3 m found, small objects right, all objects found and right.

Frames: validation houses 3900-3909, posed as the training frames are (24 a house, view seeds
0 and 1) and on the agent's own walks (16 a walk; experiments/walk_poses.py writes them to
--poses when the file is missing). Each frame is scored as ``perception evaluate`` scores it.
The full pass is run once a frame and shared by every setting. Back-ends: synthetic houses
(sh3d), the committed pixel network and its recorded thresholds, no language model.

    python -m experiments.close_reads --poses out/walks-validation.json
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from efficienteqa.envs.synthetic.vocabulary import SMALL_CATEGORIES
from efficienteqa.perception.pixels.backend import PixelPerception
from efficienteqa.perception.pixels.close import CloseReads
from efficienteqa.perception.pixels.evaluate import Scores, heldout_frames, read_poses, score_frame
from efficienteqa.perception.pixels.segment import PixelClasses
from experiments.common import seed_set
from experiments.walk_poses import walk

CHOSEN = CloseReads()
SETTINGS = {
    "off": CloseReads(crops=0),
    "chosen: 2 crops, zoom >= 2 in tiles, over anything less sure, 0.7": CHOSEN,
    "1 crop": replace(CHOSEN, crops=1),
    "3 crops": replace(CHOSEN, crops=3),
    "over background and the support only": replace(CHOSEN, over="background"),
    "over background and the support only, 0.5": replace(CHOSEN, over="background",
                                                           paste_min=0.5),
    "paste from 0.5": replace(CHOSEN, paste_min=0.5),
    "paste from 0.8": replace(CHOSEN, paste_min=0.8),
    "zoom >= 1.4, no tiles": replace(CHOSEN, min_zoom=1.4),
    "depth not scaled": replace(CHOSEN, scale_depth=False),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--houses", default="3900-3909")
    parser.add_argument("--poses", type=Path, default=Path("out/walks-validation.json"))
    parser.add_argument("--frames", type=int, default=24, help="training-style views a house")
    parser.add_argument("--walk-frames", type=int, default=16, help="views a walk")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    houses = seed_set(args.houses)
    if not args.poses.is_file():
        walks = {str(h): dict(zip(("question", "poses"), walk(h))) for h in houses}
        args.poses.parent.mkdir(parents=True, exist_ok=True)
        args.poses.write_text(json.dumps({"houses": walks}) + "\n")
    net = PixelPerception.load(close_reads=0)
    held = frozenset(net.record.get("data", {}).get("heldout_model_keys", []))
    sets = {"views, seed 0": list(heldout_frames(houses, args.frames, 0, None, held)),
            "views, seed 1": list(heldout_frames(houses, args.frames, 1, None, held)),
            "walks": list(heldout_frames(houses, args.walk_frames, 0, read_poses(args.poses),
                                         held))}
    full: dict[int, PixelClasses] = {}

    def classify(rgb: np.ndarray, depth: np.ndarray) -> PixelClasses:
        """The network; a whole frame's classes once (every setting shares them)."""
        if rgb.shape[:2] != (480, 640):
            return net.classify(rgb, depth)
        if id(rgb) not in full:
            full[id(rgb)] = net.classify(rgb, depth)
        return full[id(rgb)]

    print(f"houses {args.houses}: " + ", ".join(f"{k} {len(v)} frames" for k, v in sets.items()))
    for name, setting in SETTINGS.items():
        perception = PixelPerception(classify, record=net.record, close_reads=setting)
        total, parts = Scores(), []
        for frames in sets.values():
            scores = Scores()
            for obs, truth, tags in frames:
                score_frame(obs, truth, perception, SMALL_CATEGORIES, scores, tags)
            for key, tally in scores.tallies.items():
                total.tallies[key].add(tally)
            parts.append(_share(scores, "small within 3 m", "recall"))
        print(f"{name}: small within 3 m found {_share(total, 'small within 3 m', 'recall')} "
              f"({' / '.join(parts)}), small right {_share(total, 'size:small', 'precision')}, "
              f"all found {_share(total, 'all', 'recall')}, right "
              f"{_share(total, 'all', 'precision')}", flush=True)


def _share(scores: Scores, key: str, figure: str) -> str:
    f = scores.tallies[key].figures()
    n = f["objects"] if figure == "recall" else f["predicted"]
    return f"{100 * f[figure]:.1f}% of {n}"


if __name__ == "__main__":
    main()
