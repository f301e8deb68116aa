"""A before/after picture of one exploration episode: the map, the path and where the evidence
first came into view, for the paper's machinery and for the project's defaults side by side.

Back-ends: synthetic environment (Sweet Home 3D CC0 furniture), depth and instance buffers
rendered on the CPU, no model: both episodes explore frontier-only (no semantic values) by
default, or SFE with the ground-truth oracle values (``--method sfe``). Same house, question,
start pose and explorer seed on both sides.

    python -m experiments.map_picture --house 2003 --out docs/images/explore_before_after.png
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from efficienteqa.agent import PAPER_CONFIG, AgentConfig
from efficienteqa.config.knobs import with_leaves
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.questions import Question, evidence_visible
from efficienteqa.explore.oracle import OracleScorer
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.visualize import map_image, world_to_image
from efficienteqa.scenes import synthetic_questions
from efficienteqa.stop.rules import env_step_budget
from experiments.common import evidence_centre, evidence_distance, explore_episode, truth_floor

# The two sides: the paper's machinery (DESIGN 3.2-3.3 with the paper's stepping) and the defaults,
# as the agent configures them (without the target steering: the picture is of the explorer).
SIDES = {
    "paper": with_leaves(AgentConfig(), exploration=PAPER_CONFIG.explore.exploration,
                     prompts=PAPER_CONFIG.explore.prompts,
                     stop_clearance_m=PAPER_CONFIG.explore.stop_clearance_m,
                     refusal_retries=PAPER_CONFIG.explore.refusal_retries, steering="none"),
    "default": AgentConfig.of(steering="none"),
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


def episode(env: SyntheticEnv, q: Question, side: AgentConfig, method: str, seed: int,
            budget: int) -> Run:
    """One episode to the budget (the agent's loop); the map picture of its last state."""
    scorer = None
    if method == "sfe":
        scorer = OracleScorer(evidence_distance(env, q),
                              lambda inst: any(evidence_visible(inst, [e], min_pixels=20)
                                               for e in q.evidence))
    config = with_leaves(side, explorer="sfe" if method == "sfe" else "frontier-only", seed=seed,
                     max_steps=budget)
    ep = explore_episode(env, config, q.question, scorer=scorer, to_budget=True,
                         seen=lambda instance: evidence_visible(instance, q.evidence))
    assert ep.state is not None  # an episode run to the budget ends with its map
    run = Run(poses=ep.poses, first_seen=ep.first_seen, steps=ep.steps)
    run.coverage = ep.state.explored_floor_share(truth_floor(env))
    run.image = map_image(ep.state, trajectory=run.poses, scale=SCALE)
    u, v = world_to_image(ep.state.spec, evidence_centre(env, q), SCALE)
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
        budget = env_step_budget(env)
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
