"""A vision-language model that answers the sighting call from the scene's truth, with errors
injected at set rates: for the tests and ``experiments/sighting_noise.py``, never shipped.

It reads the labels of the frame it is asked about (``LabelsSightings`` tells it which) and
writes the reply a perfect VLM would (the robot's room, the rooms whose floor shows through a
doorway with the box of that floor, each of the target's things in view with its box), then
spoils it: each thing left out with probability ``miss``, the view's room named as another with
probability ``wrong_room``, each box shifted by its own size in a random direction with
probability ``displace``. The reply goes through the real parser and projection
(``perception.sightings``), so this bounds what a real VLM's sightings can give the steering.
"""

from __future__ import annotations

import json
import re
import zlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from efficienteqa.envs.base import SceneLabels
from efficienteqa.geometry import backproject
from efficienteqa.models.base import Capabilities, ChatResponse, Message, Usage
from efficienteqa.observation import Observation
from efficienteqa.perception.base import Perception, Sightings
from efficienteqa.perception.floor import floor_view
from efficienteqa.perception.regions import GLIMPSE_PIXELS
from efficienteqa.perception.sightings import BOX_SCALE, ModelSightings
from efficienteqa.perception.visible import REFERENCE_AREA_PX, scaled_min_pixels, visible_objects
from efficienteqa.question import ROOMS, Target, names


@dataclass(frozen=True)
class Errors:
    miss: float = 0.0
    wrong_room: float = 0.0
    displace: float = 0.0

    @property
    def tag(self) -> str:
        return f"miss{self.miss:g}-room{self.wrong_room:g}-shift{self.displace:g}"


def _box(mask: np.ndarray) -> list[float]:
    h, w = mask.shape
    rows, cols = np.nonzero(mask)
    return [cols.min() * BOX_SCALE / w, rows.min() * BOX_SCALE / h,
            (cols.max() + 1) * BOX_SCALE / w, (rows.max() + 1) * BOX_SCALE / h]


class LabelsVLM:
    """A ``ChatModel`` for the sighting call only (module docstring)."""

    name = "labels-vlm"

    def __init__(self, labels: SceneLabels, errors: Errors = Errors(), seed: int = 0) -> None:
        self.labels, self.errors, self.seed = labels, errors, seed
        self.capabilities = Capabilities(images=True)
        self.usage = Usage()
        self.obs: Observation | None = None

    def look(self, obs: Observation) -> None:
        self.obs = obs

    def truth(self, obs: Observation, wanted: list[str]) -> dict[str, Any]:
        """The reply a perfect VLM writes for ``obs``."""
        h, w = obs.depth_m.shape
        points = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)
        view = floor_view(obs, self.labels, points)
        room = self.labels.room_at(obs.pose.x, obs.pose.y)
        doorways = []
        for n, other in enumerate(view.rooms):
            mask = view.room_index == n
            if other != room and mask.sum() >= scaled_min_pixels(h, w):
                doorways.append({"room": other, "box": _box(mask)})
        things = []
        glimpse = max(1, round(GLIMPSE_PIXELS * h * w / REFERENCE_AREA_PX))
        for o in visible_objects(obs, self.labels, glimpse):
            name = next((t for t in wanted if names(t, o.label.category)), None)
            if name is not None:
                assert obs.instance is not None
                things.append({"name": name, "box": _box(obs.instance == o.instance_id)})
        return {"room": room, "doorways": doorways, "things": things}

    def chat(self, messages: list[Message], *, max_tokens: int = 256, temperature: float = 0.0,
             logprobs: int | None = None, json_schema: dict[str, Any] | None = None,
             seed: int | None = None) -> ChatResponse:
        text = messages[-1].text
        if self.obs is None or "Say what one view shows" not in text:
            raise ValueError("the labels VLM answers the sighting call of a frame it was shown")
        listed = re.search(r"^Things to look for: (.*)$", text, re.MULTILINE)
        data = self.truth(self.obs, re.findall(r'"([^"]+)"', listed.group(1)) if listed else [])
        pose = self.obs.pose
        rng = np.random.default_rng([self.seed, zlib.crc32(f"{pose.x:.3f} {pose.y:.3f} "
                                                           f"{pose.yaw:.3f}".encode())])
        e = self.errors
        if data["room"] is not None and rng.random() < e.wrong_room:
            data["room"] = str(rng.choice([r for r in ROOMS if r != data["room"]]))
        kept = []
        for thing in data["things"]:
            if rng.random() < e.miss:
                continue
            if rng.random() < e.displace:
                x0, y0, x1, y1 = thing["box"]
                angle = rng.uniform(0, 2 * np.pi)
                dx, dy = (x1 - x0) * np.cos(angle), (y1 - y0) * np.sin(angle)
                thing["box"] = [x0 + dx, y0 + dy, x1 + dx, y1 + dy]
            kept.append(thing)
        data["things"] = kept
        reply = json.dumps(data)
        response = ChatResponse(reply, self.name, prompt_tokens=len(text.split()),
                                completion_tokens=len(reply.split()), finish_reason="stop")
        self.usage.add(response)
        return response


class LabelsSightings(ModelSightings):
    """``ModelSightings`` over the image path whose model is a ``LabelsVLM`` of ``labels``."""

    def __init__(self, base: Perception, labels: SceneLabels, errors: Errors = Errors(),
                 seed: int = 0) -> None:
        super().__init__(base, LabelsVLM(labels, errors, seed), images=True)

    def sightings(self, obs: Observation, target: Target) -> Sightings:
        self.model.look(obs)  # type: ignore[attr-defined]
        return super().sightings(obs, target)
