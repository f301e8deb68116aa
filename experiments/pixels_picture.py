"""A picture of what pixel perception sees: for a few held-out frames, the RGB frame, the
network's classes and the truth side by side, each with the text it gives.

Usage: .venv/bin/python -m experiments.pixels_picture [--houses 100 101 102] [--out
       results/perception/frames.png] [--weights PATH]

Each row is one frame of a house the network never trained on (the first surface view of the
house, posed as the training views are). Classes are drawn in one fixed colour each: walls grey,
each room type's floor its own pale colour, doors brown, objects by category. The texts under
the row are pixel perception's and the semantic sensor's descriptions of that frame.
"""

from __future__ import annotations

import argparse
import textwrap
import zlib
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.perception.pixels.backend import PixelPerception
from efficienteqa.perception.pixels.frames import build_vocabulary, frame_labels, house_poses
from efficienteqa.perception.pixels.net import IGNORE
from efficienteqa.perception.semantic import SemanticPerception

W, H = 320, 240  # each panel: the network's own resolution
TEXT_ROWS = 7


def palette(categories: tuple[str, ...]) -> np.ndarray:
    """One RGB per category: nothing black, walls grey, floors pale, the rest from its name."""
    colours = np.zeros((256, 3), np.uint8)
    for i, name in enumerate(categories):
        if name == "wall":
            colours[i] = (120, 120, 120)
        elif name.startswith("floor:"):
            h = zlib.crc32(name.encode())
            colours[i] = (180 + h % 60, 180 + (h >> 8) % 60, 180 + (h >> 16) % 60)
        elif name == "door":
            colours[i] = (140, 90, 40)
        elif name != "void":
            h = zlib.crc32(name.encode())
            colours[i] = (40 + h % 200, 40 + (h >> 8) % 200, 40 + (h >> 16) % 200)
    colours[IGNORE] = (255, 0, 255)
    return colours


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--houses", type=int, nargs="+", default=[100, 101, 102])
    parser.add_argument("--out", type=Path, default=Path("results/perception/frames.png"))
    parser.add_argument("--weights", type=Path, default=None)
    args = parser.parse_args()
    pixels = PixelPerception.load(args.weights)
    vocab = build_vocabulary()
    colours = palette(vocab.categories)
    rows = []
    for house in args.houses:
        with SyntheticEnv.from_seed(house) as env:
            poses = house_poses(env, 4, np.random.default_rng([0, house]))
            pose = next(p for kind, p in poses if kind == "surface")
            obs = env.observe(pose)
            truth = frame_labels(obs, env.house, vocab)["category"]
            seen = pixels.classify(obs.rgb, obs.depth_m).category
            said = pixels.frame(obs)
            known = SemanticPerception(env.scene_labels()).frame(obs)
        panels = [Image.fromarray(obs.rgb).resize((W, H)), Image.fromarray(colours[seen]),
                  Image.fromarray(colours[truth])]
        text = ["pixels: " + said, "labels: " + known]
        lines = [ln for t in text for ln in textwrap.wrap(t, 150)][:TEXT_ROWS * 2]
        row = Image.new("RGB", (3 * W, H + 12 * len(lines) + 8), "white")
        for k, panel in enumerate(panels):
            row.paste(panel, (k * W, 0))
        draw = ImageDraw.Draw(row)
        for n, line in enumerate(lines):
            draw.text((4, H + 4 + 12 * n), line, fill="black")
        rows.append(row)
    header = Image.new("RGB", (3 * W, 16), "white")
    draw = ImageDraw.Draw(header)
    for k, title in enumerate(("RGB (held-out house)", "network's classes", "truth")):
        draw.text((k * W + 4, 2), title, fill="black")
    sheet = Image.new("RGB", (3 * W, 16 + sum(r.height for r in rows)), "white")
    sheet.paste(header, (0, 0))
    y = 16
    for row in rows:
        sheet.paste(row, (0, y))
        y += row.height
    args.out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(args.out)
    print(f"{len(rows)} frames -> {args.out}")


if __name__ == "__main__":
    main()
