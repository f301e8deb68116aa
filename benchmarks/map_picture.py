"""A before/after picture of one exploration episode: the map, the path and where the evidence
first came into view, for the paper's machinery and for the project's defaults side by side.

Back-ends: synthetic environment (Sweet Home 3D CC0 furniture), depth and instance buffers
rendered on the CPU, no model: both episodes explore frontier-only (no semantic values) by
default, or SFE with the ground-truth oracle values (``--method sfe``). Same house, question,
start pose and explorer seed on both sides.

    python benchmarks/map_picture.py --house 2003 --out docs/images/explore_before_after.png
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from explore_bench import evidence_centre, evidence_distance  # noqa: E402  (the oracle set-up)

from efficienteqa.agent import mapper_for
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.questions import Question, evidence_visible
from efficienteqa.explore.module import REFUSAL_RETRIES, ExploreModule, move
from efficienteqa.explore.oracle import OracleScorer
from efficienteqa.explore.prompting import PROMPT_CONFIGS
from efficienteqa.explore.registry import EXPLORATIONS, make_explorer
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.visualize import map_image, world_to_image
from efficienteqa.scenes import synthetic_questions

# The two sides: the paper's machinery (DESIGN 3.2-3.3 with the paper's stepping) and the defaults.
SIDES = {
    "paper": {"explorer": {**EXPLORATIONS["paper"], "stop_clearance_m": 0.0}, "prompts": "paper",
              "retries": 0},
    "default": {"explorer": EXPLORATIONS["default"], "prompts": "default",
                "retries": REFUSAL_RETRIES},
}
SCALE = 4  # picture pixels per map cell


@dataclass
class Run:
    poses: list[Pose2D] = field(default_factory=list)
    first_seen: int | None = None
    steps: int = 0
    coverage: float = 0.0
    image: np.ndarray | None = None
    evidence_uv: tuple[float, float] = (0.0, 0.0)  # the evidence's centre in the picture


def episode(env: SyntheticEnv, q: Question, side: dict, method: str, seed: int,
            budget: int) -> Run:
    """One episode to the budget; the map picture of its last state."""
    centre = evidence_centre(env, q)
    start = (env.house.start.x, env.house.start.y)
    scorer = None
    if method == "sfe":
        scorer = OracleScorer(evidence_distance(env, q),
                              lambda inst: any(evidence_visible(inst, [e], min_pixels=20)
                                               for e in q.evidence))
    mapper = mapper_for(env, start)
    explorer = make_explorer("sfe" if method == "sfe" else "frontier-only", **side["explorer"])
    module = ExploreModule(mapper, explorer, scorer, seed=seed, prompts=PROMPT_CONFIGS[side["prompts"]])
    xs, ys = mapper.spec.centres()
    i, j = env.grid.spec.world_to_cell(np.stack([xs, ys], axis=-1))
    inside = env.grid.spec.contains((i, j))
    floor = np.zeros(xs.shape, bool)
    floor[inside] = env.grid.free[i[inside], j[inside]]
    run = Run()
    obs, _ = env.reset()
    out = None
    for step in range(1, budget + 1):
        run.steps = step
        run.poses.append(obs.pose)
        if run.first_seen is None and evidence_visible(obs.instance, q.evidence):
            run.first_seen = step
        out = module.step(obs, step, q.question)
        if out.decision.done:
            break
        obs = move(env, module, obs.pose, out.decision, step, side["retries"]).obs
    mapper.update(obs)
    state = mapper.state((obs.pose.x, obs.pose.y))
    run.coverage = state.explored_floor_share(floor)
    run.image = map_image(state, trajectory=run.poses, scale=SCALE)
    u, v = world_to_image(mapper.spec, centre, SCALE)
    run.evidence_uv = (float(u), float(v))
    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     epilog=__doc__.split("\n\n", 1)[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--house", type=int, default=2003, help="house seed (held-out: 2000-2999)")
    parser.add_argument("--question", default=None, help="question id (default: the house's first "
                        "with evidence)")
    parser.add_argument("--method", default="frontier-only", choices=["frontier-only", "sfe"])
    parser.add_argument("--seed", type=int, default=0, help="explorer seed")
    parser.add_argument("--out", default="docs/images/explore_before_after.png")
    args = parser.parse_args()

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with SyntheticEnv.from_seed(args.house, "sh3d") as env:
        questions = [q for q in synthetic_questions(env) if q.evidence]
        q = next(x for x in questions if args.question in (None, x.id))
        budget = int(math.sqrt(env.floor_area_m2) * 3)
        runs = {name: episode(env, q, side, args.method, args.seed, budget)
                for name, side in SIDES.items()}
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.6))
    for ax, (name, run) in zip(axes, runs.items()):
        ax.imshow(run.image)
        ax.plot(*run.evidence_uv, marker="*", markersize=18, color="gold", markeredgecolor="black")
        seen = (f"evidence first in view at step {run.first_seen}" if run.first_seen
                else "evidence never in view")
        label = "paper's machinery" if name == "paper" else "defaults"
        ax.set_title(f"{label}: {seen}\n{run.steps} steps, floor explored {run.coverage:.0%}",
                     fontsize=10)
        ax.axis("off")
    fig.suptitle(f"house {args.house}, {q.id}: \"{q.question}\" ({args.method}, explorer seed "
                 f"{args.seed}, oracle {q.oracle_steps} steps, budget {budget}); star: the evidence",
                 fontsize=10)
    fig.tight_layout()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    for name, run in runs.items():
        print(f"{name}: first seen {run.first_seen}, steps {run.steps}, coverage {run.coverage:.1%}")
    print(f"picture: {out}")


if __name__ == "__main__":
    main()
