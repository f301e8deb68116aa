"""Your agent in our houses: a walker that heads for the open space it sees, then answers with
the run's model from what the project's pixel network read in its frames.

    cd examples && efficienteqa eval --eval.method your_agent:OpenSpaceWalker \\
        --eval.limit 4 --out ../runs/walker

An agent is a class with ``reset(question, info)`` and ``act(observation) -> action``
(``efficienteqa.eval.agents``); the same class steps the Gymnasium environment
(``efficienteqa.gym``). It sees RGB, depth, intrinsics and the camera's pose, never labels.
"""

from __future__ import annotations

import math

import numpy as np

from efficienteqa.envs.episode import answer, as_observation, move
from efficienteqa.models.backends import build_chat_model
from efficienteqa.models.base import Message
from efficienteqa.perception.pixels.backend import PixelPerception
from efficienteqa.stack import parse_vlm


class OpenSpaceWalker:
    name = "open-space-walker"
    steps = 6  # moves before answering
    eyes = PixelPerception.load()  # RGB-D -> a text description (trained on synthetic renders)

    def reset(self, question: str, info: dict) -> None:
        self.question, self.seen = question, []
        self.eyes.reset()  # the objects it fuses across views start empty
        vlm = info.get("vlm", "local:qwen2.5-coder-1.5b")  # eval's --backends.vlm
        self.model = build_chat_model(parse_vlm(vlm, images=False))

    def act(self, obs: dict) -> dict:
        self.seen.append(self.eyes.frame(as_observation(obs)))
        if len(self.seen) > self.steps:
            prompt = "\n".join(["What you saw, frame by frame:", *self.seen,
                                f"Question: {self.question} Answer in a few words."])
            return answer(self.model.chat([Message("user", prompt)], max_tokens=24).text.strip())
        depth, k, pose = obs["depth"], obs["intrinsics"], obs["pose"]
        h, w = depth.shape
        reach = np.median(depth[h // 3: 2 * h // 3], axis=0)  # how far each column sees
        u = int(np.argmax(reach))
        yaw = math.atan2(pose[1, 2], pose[0, 2]) + math.atan2(k[0, 2] - u, k[0, 0])
        if obs["info"].get("blocked"):
            yaw += math.pi / 2  # turn away from what stopped us
        step = float(np.clip(0.6 * reach[u], 0.3, 1.5))
        x, y = pose[0, 3] + step * math.cos(yaw), pose[1, 3] + step * math.sin(yaw)
        return move(x, y, math.remainder(yaw, math.tau))
