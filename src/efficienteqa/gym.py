"""The synthetic houses as a Gymnasium environment, registered on import::

    import gymnasium as gym
    import efficienteqa.gym  # registers EfficientEQA/SyntheticHouse-v1
    env = gym.make("EfficientEQA/SyntheticHouse-v1")

Each episode is one question of a frozen split (default ``synthetic``, the main table's), in
its house, from its start pose. ``reset(seed=..., options={"index": i})`` picks question ``i``
(default: one drawn with the seed). The observation is ``envs.episode``'s dict: RGB, depth,
intrinsics, camera-to-world pose and the question. The action is a dict too: ``kind`` 0 moves
to ``goal`` (x, y, yaw: a floor pose in the world frame), ``kind`` 1 answers with ``answer``
and ends the episode (``envs.episode.move`` and ``answer`` build them).

A move follows the shortest free path to its goal, 3 m of it at most (``envs.synthetic.moves``:
the step the oracle counts); ``info`` after it holds what a robot would know of it:
``blocked``, ``short``, ``reached`` (``envs.base.move_info``), the steps made (the start view
is step 1, as for the oracle) and the budget (the benchmark's ``int(sqrt(floor area) * 3)``).
Nothing of the simulator's truth appears while the episode runs. At its end (an answer:
terminated; the budget spent: truncated) ``info["grade"]`` gives the rule judge's verdict, the
reference answer, the steps and the oracle's fewest steps to a view of the evidence, and the
reward is 1 for a right answer, else 0. ``noise="robot"`` (or another of ``efficienteqa eval``'s
``--scene.noise`` profiles) gives the robot depth noise, odometry drift and moves that fall
short (``envs.synthetic.noise``; the pose observed is then the drifted one the robot believes).
Needs ``pip install 'efficienteqa[gym]'``.
"""

from __future__ import annotations

import string
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from efficienteqa.datasets import load_dataset
from efficienteqa.datasets.base import EvalQuestion
from efficienteqa.envs.episode import MAX_ANSWER_CHARS, QuestionEpisode
from efficienteqa.envs.synthetic.moves import path_moves
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec, Pose2D

ENV_ID = "EfficientEQA/SyntheticHouse-v1"
CHARSET = string.printable  # what a question or an answer may hold
MAX_QUESTION_CHARS = 256
GOAL_M = 100.0  # a goal's x and y bounds, metres (the houses are a few tens of metres across)


class SyntheticHouseEnv(gymnasium.Env[dict[str, Any], dict[str, Any]]):
    """One question per episode in the synthetic houses (the module docstring)."""

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"]}

    def __init__(self, split: str = "synthetic", limit: int | None = None,
                 render_mode: str | None = None, noise: str = "none") -> None:
        from efficienteqa.envs.synthetic.noise import profile

        profile(noise)  # an unknown profile fails here, in one line, before any house opens
        self.noise = noise
        self.questions: list[EvalQuestion] = load_dataset(split, limit=limit)
        if not self.questions:
            raise EfficientEQAError(f"split {split!r} has no questions", fix="give another split")
        self.camera = CameraSpec()
        h, w = self.camera.height, self.camera.width
        self.observation_space = spaces.Dict({
            "rgb": spaces.Box(0, 255, (h, w, 3), np.uint8),
            "depth": spaces.Box(0.0, np.inf, (h, w), np.float32),
            "intrinsics": spaces.Box(-np.inf, np.inf, (3, 3), np.float32),
            "pose": spaces.Box(-np.inf, np.inf, (4, 4), np.float32),
            "question": spaces.Text(MAX_QUESTION_CHARS, charset=CHARSET),
        })
        self.action_space = spaces.Dict({
            "kind": spaces.Discrete(2),
            "goal": spaces.Box(np.array([-GOAL_M, -GOAL_M, -np.pi], np.float32),
                               np.array([GOAL_M, GOAL_M, np.pi], np.float32)),
            "answer": spaces.Text(MAX_ANSWER_CHARS, min_length=0, charset=CHARSET),
        })
        self.render_mode = render_mode
        self._scene: Any = None  # the open house, kept while questions stay in it
        self._spec: str | None = None  # its scene spec ("synthetic:SEED")
        self._moves: Any = None  # its environment, moving as a mobile base does
        self._episode: QuestionEpisode | None = None
        self._question: EvalQuestion | None = None
        self._last: dict[str, Any] | None = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, Any], dict[str, Any]]:
        super().reset(seed=seed)
        index = (options or {}).get("index")
        if index is None:
            index = int(self.np_random.integers(len(self.questions)))
        if not 0 <= int(index) < len(self.questions):
            raise EfficientEQAError(f"question index {index} is outside 0-{len(self.questions) - 1}",
                                    fix="give options={'index': i} within the split")
        q = self._question = self.questions[int(index)]
        env = self._open(q.scene)
        from efficienteqa.stop.rules import env_step_budget

        start = Pose2D(*q.start) if q.start is not None else None
        budget = env_step_budget(self._scene.env) or 1  # the house's own, not the wrapper's
        self._episode = QuestionEpisode(env, q.question, budget, start)
        obs, info = self._episode.reset()
        self._last = obs
        return obs, {**info, "question_id": q.id}

    def step(self, action: dict[str, Any]
             ) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        if self._episode is None or self._question is None or self._last is None:
            raise EfficientEQAError("step before reset", fix="call reset() first")
        obs, info = self._episode.step(action)
        self._last = obs if obs is not None else {k: np.copy(v) if isinstance(v, np.ndarray)
                                                  else v for k, v in self._last.items()}
        terminated = self._episode.reply is not None
        truncated = not terminated and self._episode.over
        reward = 0.0
        if terminated or truncated:
            info["grade"] = self._grade()
            reward = float(info["grade"]["correct"])
        return self._last, reward, terminated, truncated, info

    def render(self) -> np.ndarray | None:
        return None if self._last is None else np.asarray(self._last["rgb"])

    def close(self) -> None:
        if self._scene is not None:
            self._scene.env.close()
            self._scene = self._spec = None

    def _open(self, name: str) -> Any:
        if self._scene is None or self._spec != name:
            from efficienteqa.scenes import open_scene

            self.close()
            self._scene = open_scene(name, oracle=False, noise=self.noise)
            self._spec = name
            self._moves = path_moves(self._scene.env)  # along free paths, 3 m a step at most
        return self._moves

    def _grade(self) -> dict[str, Any]:
        """The end of an episode, graded by the rule judge (exact on these questions)."""
        from efficienteqa.eval.synthetic_judge import rule_judgement

        q, episode = self._question, self._episode
        assert q is not None and episode is not None
        verdict = rule_judgement(q.question, q.category, q.accepted, episode.reply)
        return {"question_id": q.id, "answer": episode.reply or "", "reference": q.answer,
                "correct": verdict.score == 5, "category": q.category, "steps": episode.steps,
                "oracle_steps": q.oracle_steps, "budget": episode.budget}


def register() -> None:
    """Register ``ENV_ID`` (again, harmlessly, on a second import)."""
    if ENV_ID not in gymnasium.registry:
        gymnasium.register(id=ENV_ID, entry_point=f"{__name__}:SyntheticHouseEnv")


register()
