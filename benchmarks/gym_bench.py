"""Times a step of the Gymnasium environment (``efficienteqa.gym``): the move, the render (RGB,
depth, instance ids read back) and the observation dict, as another agent pays for it.

Usage: .venv/bin/python -m benchmarks.gym_bench [--steps 60] [--question 0]

Opens the question's house once (not timed: a few seconds), then walks a fixed loop of small
moves around the start pose, some of them into furniture or walls (refused moves render too).
Prints the median, 95th percentile and mean milliseconds per step; the target is 80 ms on the
2-core development machine (issue: "time per environment step").
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=60)
    parser.add_argument("--question", type=int, default=0, help="index in the split")
    args = parser.parse_args()

    import gymnasium as gym

    import efficienteqa.gym  # noqa: F401  (registers the id)
    from efficienteqa.envs.episode import move

    env = gym.make("EfficientEQA/SyntheticHouse-v1", limit=args.question + 1,
                   max_episode_steps=None)
    obs, info = env.reset(options={"index": args.question})
    x0, y0 = float(obs["pose"][0, 3]), float(obs["pose"][1, 3])
    times = []
    for i in range(args.steps):
        if env.unwrapped._episode.over:  # a budget spent: a new episode, not timed
            obs, info = env.reset(options={"index": args.question})
        angle = i * 2 * math.pi / 12
        radius = 0.5 + 0.5 * (i % 3)
        goal = move(x0 + radius * math.cos(angle), y0 + radius * math.sin(angle), angle)
        start = time.perf_counter()
        env.step(goal)
        times.append(1000 * (time.perf_counter() - start))
    env.close()
    t = np.array(times[3:])  # the first steps warm caches
    print(f"{len(t)} steps: median {np.median(t):.1f} ms, p95 {np.percentile(t, 95):.1f} ms, "
          f"mean {t.mean():.1f} ms per step (render + depth + observation)")


if __name__ == "__main__":
    main()
