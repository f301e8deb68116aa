"""A stand-in for ``habitat_sim`` (Habitat-Sim 0.2.x), for tests on machines without it.

It mimics only the API surface the adapter uses, with Habitat's conventions (y up, cameras
looking along their local -z, ``CameraSensorSpec.orientation`` as Euler angles about x, y, z,
rotations as [x, y, z, w] coefficient lists or quaternions) and ray-casts a tiny scene format of
its own, written as JSON into the files where Habitat expects the GLB and the navmesh:

- ``*.basis.glb``: ``{"room": {"min": [x, y, z], "max": [x, y, z]}, "faces": ["floor",
  "ceiling", "walls"], "objects": [{"id": 7, "category": "table", "min": [...], "max":
  [...]}]}`` (an axis-aligned room seen from inside, axis-aligned boxes in it);
- ``*.basis.navmesh``: ``{"rects": [{"x": [x0, x1], "z": [z0, z1], "y": height}]}``
  (navigable rectangles; a path exists within a rectangle only).

Semantic ids are reported only when the simulator is given a ``scene_dataset_config_file``
naming the scene (a JSON ``{"scenes": [stems]}``; any other config names every scene), as in
Habitat-Sim, where HM3D's annotations come through that file and a scene the file does not
name reads 0 everywhere. As in Habitat-Sim, ``initialize_agent`` puts the agent at a random
navigable point with a random yaw once a navmesh is loaded, ``get_state().sensor_states``
holds each sensor's world pose, and ``PathFinder.get_bounds`` is the box of the whole navmesh.
"""

from __future__ import annotations

import enum
import json
import math
from pathlib import Path

import numpy as np

from habitat_sim import agent as agent  # noqa: F401 - habitat_sim.agent.AgentConfiguration
from habitat_sim.agent import Agent, AgentState, matrix, sensor_pose

__all__ = ["AgentState", "CameraSensorSpec", "Configuration", "SensorType", "ShortestPath",
           "Simulator", "SimulatorConfiguration", "agent"]

STANDIN = True  # lets tests tell this module from the real one


class SensorType(enum.Enum):
    COLOR = 1
    DEPTH = 2
    SEMANTIC = 3


class SimulatorConfiguration:
    def __init__(self) -> None:
        self.scene_id = ""
        self.scene_dataset_config_file = "default"
        self.enable_physics = False
        self.gpu_device_id = 0


class CameraSensorSpec:
    def __init__(self) -> None:
        self.uuid = "rgb"
        self.sensor_type = SensorType.COLOR
        self.resolution = [128, 128]
        self.position = [0.0, 1.5, 0.0]
        self.orientation = [0.0, 0.0, 0.0]
        self.hfov = 90.0


class Configuration:
    def __init__(self, sim_cfg: SimulatorConfiguration, agents: list) -> None:
        self.sim_cfg = sim_cfg
        self.agents = agents


class ShortestPath:
    def __init__(self) -> None:
        self.requested_start = np.zeros(3)
        self.requested_end = np.zeros(3)
        self.points: list[np.ndarray] = []
        self.geodesic_distance = math.inf


class PathFinder:
    def __init__(self) -> None:
        self.rects: list[dict] = []
        self._rng = np.random.default_rng(0)

    @property
    def is_loaded(self) -> bool:
        return bool(self.rects)

    def load_nav_mesh(self, path: str) -> bool:
        try:
            self.rects = json.loads(Path(path).read_text())["rects"]
        except (OSError, ValueError, KeyError):
            return False
        return True

    def seed(self, new_seed: int) -> None:
        self._rng = np.random.default_rng(new_seed)

    def _rect_of(self, pt, max_y_delta: float = 0.5) -> int | None:
        x, y, z = (float(v) for v in pt)
        for i, r in enumerate(self.rects):
            if (r["x"][0] <= x <= r["x"][1] and r["z"][0] <= z <= r["z"][1]
                    and abs(y - r["y"]) <= max_y_delta):
                return i
        return None

    def is_navigable(self, pt, max_y_delta: float = 0.5) -> bool:
        return self._rect_of(pt, max_y_delta) is not None

    def snap_point(self, pt) -> np.ndarray:
        x, y, z = (float(v) for v in pt)
        best, best_d = np.full(3, np.nan), math.inf
        for r in self.rects:
            q = np.array([min(max(x, r["x"][0]), r["x"][1]), r["y"], min(max(z, r["z"][0]), r["z"][1])])
            d = float(np.linalg.norm(q - [x, y, z]))
            if d < best_d:
                best, best_d = q, d
        return best

    def find_path(self, path: ShortestPath) -> bool:
        a, b = self._rect_of(path.requested_start), self._rect_of(path.requested_end)
        if a is None or a != b:
            return False
        path.points = [np.asarray(path.requested_start, float), np.asarray(path.requested_end, float)]
        path.geodesic_distance = float(np.linalg.norm(path.points[1] - path.points[0]))
        return True

    def build_navmesh_vertices(self, island_index: int = -1) -> list[np.ndarray]:
        out = []
        for r in self.rects:
            (x0, x1), (z0, z1), y = r["x"], r["z"], r["y"]
            corners = [np.array(c, float) for c in ([x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1])]
            out += [corners[0], corners[1], corners[2], corners[0], corners[2], corners[3]]
        return out

    def get_random_navigable_point(self) -> np.ndarray:
        r = self.rects[0]
        return np.array([self._rng.uniform(*r["x"]), r["y"], self._rng.uniform(*r["z"])])

    def get_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = [min(r["x"][0] for r in self.rects), min(r["y"] for r in self.rects),
              min(r["z"][0] for r in self.rects)]
        hi = [max(r["x"][1] for r in self.rects), max(r["y"] for r in self.rects),
              max(r["z"][1] for r in self.rects)]
        return np.array(lo), np.array(hi)


class _Category:
    def __init__(self, name: str) -> None:
        self._name = name

    def name(self) -> str:
        return self._name


class _SemanticObject:
    def __init__(self, semantic_id: int, category: str) -> None:
        self.semantic_id = semantic_id
        self.id = f"_{semantic_id}"
        self.category = _Category(category)


class _SemanticScene:
    def __init__(self, objects: list) -> None:
        self.objects = objects


class Simulator:
    def __init__(self, config: Configuration) -> None:
        self.config = config
        self.scene = json.loads(Path(config.sim_cfg.scene_id).read_text())
        self.pathfinder = PathFinder()
        self._annotated = _names_scene(config.sim_cfg.scene_dataset_config_file,
                                       config.sim_cfg.scene_id)
        objects = [_SemanticObject(o["id"], o["category"]) for o in self.scene.get("objects", [])]
        self.semantic_scene = _SemanticScene([None, *objects] if self._annotated else [])
        self._agents: list[Agent] = []
        self._random = np.random.default_rng(1)
        self.closed = False

    def initialize_agent(self, agent_id: int, initial_state: AgentState | None = None) -> Agent:
        """As Habitat-Sim's: without ``initial_state``, the agent is put at a random navigable
        point with a random yaw once a navmesh is loaded."""
        while len(self._agents) <= agent_id:
            self._agents.append(Agent(self.config.agents[len(self._agents)]))
        if initial_state is None:
            initial_state = AgentState()
            if self.pathfinder.is_loaded:
                initial_state.position = self.pathfinder.get_random_navigable_point()
                yaw = float(self._random.uniform(0.0, 2 * math.pi))
                initial_state.rotation = [0.0, math.sin(yaw / 2), 0.0, math.cos(yaw / 2)]
        self._agents[agent_id].set_state(initial_state, is_initial=True)
        return self._agents[agent_id]

    def get_agent(self, agent_id: int) -> Agent:
        return self._agents[agent_id]

    def get_sensor_observations(self) -> dict[str, np.ndarray]:
        ag = self._agents[0]
        return {spec.uuid: self._render(ag.state, spec) for spec in ag.config.sensor_specifications}

    def close(self) -> None:
        self.closed = True

    def _render(self, state: AgentState, spec: CameraSensorSpec) -> np.ndarray:
        h, w = spec.resolution
        f = (w / 2) / math.tan(math.radians(spec.hfov) / 2)
        u, v = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
        dirs = np.stack([(u - w / 2) / f, -(v - h / 2) / f, -np.ones_like(u)], axis=-1)  # GL camera
        origin, q = sensor_pose(state, spec)
        t, ids, faces = self._cast(origin, dirs @ matrix(q).T)
        if spec.sensor_type is SensorType.DEPTH:
            return np.where(np.isfinite(t), t, 0.0).astype(np.float32)
        if spec.sensor_type is SensorType.SEMANTIC:
            return (ids if self._annotated else np.zeros_like(ids)).astype(np.uint32)
        palette = np.array([[0, 0, 0], [150, 120, 90], [230, 230, 230], [200, 180, 160], [40, 90, 200]])
        rgba = np.zeros((h, w, 4), np.uint8)
        rgba[..., :3] = palette[faces]
        rgba[..., 3] = 255
        return rgba

    def _cast(self, o: np.ndarray, d: np.ndarray):
        """Hit distance along each ray (per unit of the camera's -z), its semantic id, its face."""
        room = self.scene["room"]
        lo, hi = np.array(room["min"], float), np.array(room["max"], float)
        present = set(self.scene.get("faces", ["floor", "ceiling", "walls"]))
        with np.errstate(divide="ignore", invalid="ignore"):
            exit_t = np.where(d > 0, (hi - o) / d, np.where(d < 0, (lo - o) / d, np.inf))
        axis = np.argmin(exit_t, axis=-1)
        t = np.take_along_axis(exit_t, axis[..., None], -1)[..., 0]
        ceiling = (axis == 1) & (d[..., 1] > 0)
        face = np.where(axis != 1, 3, np.where(ceiling, 2, 1))  # 1 floor, 2 ceiling, 3 walls
        keep = (((face == 1) & ("floor" in present)) | ((face == 2) & ("ceiling" in present))
                | ((face == 3) & ("walls" in present)))
        t = np.where(keep, t, np.inf)
        face = np.where(keep, face, 0)
        ids = np.where(keep, 1, 0)  # structure: a wall/floor annotation with id 1
        for obj in self.scene.get("objects", []):
            blo, bhi = np.array(obj["min"], float), np.array(obj["max"], float)
            with np.errstate(divide="ignore", invalid="ignore"):
                t1, t2 = (blo - o) / d, (bhi - o) / d
            near = np.nanmax(np.minimum(t1, t2), axis=-1)
            far = np.nanmin(np.maximum(t1, t2), axis=-1)
            hit = (near <= far) & (near > 0) & (near < t)
            t = np.where(hit, near, t)
            ids = np.where(hit, obj["id"], ids)
            face = np.where(hit, 4, face)
        return t, ids, face



def _names_scene(dataset_config: str, scene_id: str) -> bool:
    """Whether the dataset config gives the scene its annotations: any config does, unless it
    lists ``"scenes"`` (file stems) without this one. Habitat-Sim only warns when none does."""
    if dataset_config in ("", "default"):
        return False
    names = json.loads(Path(dataset_config).read_text() or "{}").get("scenes")
    return names is None or Path(scene_id).name.split(".")[0] in names
