"""Poses the agent actually takes, for measuring perception on frames posed as its walks
(`efficienteqa perception evaluate --poses FILE`; docs/perception.md).

For each house: the default explorer (target steering, the model-free direction scorer the
offline default explores with) walks from the house's start pose towards the target of one of
the house's generated questions (the first of a kind chosen by the house seed), the early stop
off, to the step budget; every pose it stands at is written. No language model: the question is
read by rules. Back-ends: synthetic houses (sh3d), semantic-sensor perception for the walk (the
perception under test only ever sees the frames).

    python -m experiments.walk_poses --seeds 100-129,2000-2009 --out results/perception/walk-poses.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from efficienteqa.agent import AgentConfig
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.perception.semantic import SemanticPerception
from efficienteqa.records import code_version
from efficienteqa.scenes import synthetic_questions
from efficienteqa.stack import EXPLORE_SCORERS
from efficienteqa.stop.rules import env_step_budget
from experiments.common import explore_episode, seed_set


def walk(house: int) -> tuple[str, list[list[float]]]:
    """The question walked for and the poses of the walk in ``house``."""
    with SyntheticEnv.from_seed(house) as env:
        questions = synthetic_questions(env, per_category=1, oracle=False)
        q = questions[int(np.random.default_rng([house, 11]).integers(len(questions)))]
        scorer = EXPLORE_SCORERS.build("direction-logit",
                                       perception=SemanticPerception(env.scene_labels()))
        config = AgentConfig.of(max_steps=env_step_budget(env), seed=0)
        ep = explore_episode(env, config, q.question, scorer=scorer, to_budget=True)
    return q.question, [[round(p.x, 3), round(p.y, 3), round(p.yaw, 4)] for p in ep.poses]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", default="100-129,2000-2009")
    parser.add_argument("--out", type=Path, default=Path("results/perception/walk-poses.json"))
    args = parser.parse_args()
    houses: dict[str, dict[str, object]] = {}
    for house in seed_set(args.seeds):
        question, poses = walk(house)
        houses[str(house)] = {"question": question, "poses": poses}
        print(f"house {house}: {len(poses)} poses ({question})", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"about": __doc__.split("\n\n")[1].replace("\n", " "),
                                    "command": f"python -m experiments.walk_poses --seeds "
                                               f"{args.seeds} --out {args.out}",
                                    "code_version": code_version(), "houses": houses},
                                   indent=1) + "\n")


if __name__ == "__main__":
    main()
