"""Habitat-Sim + HM3D behind the environment contract of ``envs.base`` (SPEC 4).

``habitat_sim`` is imported when an environment is built, never at import time: it is installed
with conda (it has no usable pip wheel on Linux) and most users never need it. The adapter uses
only Habitat-Sim's documented Python API: ``Simulator``, ``CameraSensorSpec``, ``AgentState``
and the ``PathFinder`` of the scene's navmesh.

Stepping teleports: the agent's target pose is snapped to the navmesh and taken only when the
navmesh has a path to it from where the robot stands; otherwise the robot stays and
``info["blocked"]`` is True. The floor of the start pose is the episode's floor: its height is
canonical z = 0, and its navmesh area is the floor area behind the step budget.
"""

from __future__ import annotations

import logging
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from efficienteqa.envs.habitat import frames
from efficienteqa.envs.habitat.labels import HabitatLabels
from efficienteqa.envs.habitat.scenes import HabitatStart, SceneFiles
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec, Pose2D
from efficienteqa.observation import Observation

log = logging.getLogger(__name__)

INSTALL = "conda install -c conda-forge -c aihabitat-nightly habitat-sim headless (see docs/habitat.md)"
COLOR, DEPTH, SEMANTIC = "color", "depth", "semantic"
FLOOR_BAND_M = 0.5  # navmesh triangles within this height of the start are on its floor
STOREY_M = 3.0  # canonical z extent of one floor: the map ignores the storeys above
WALL_MARGIN_M = 1.0  # walls stand beyond the navmesh edge by about the robot radius
MAX_STEP_DELTA_Y_M = 0.5  # a target may be this far above or below the floor (thresholds, ramps)


def import_habitat_sim() -> ModuleType:
    try:
        import habitat_sim
    except ImportError:
        raise EfficientEQAError("Habitat-Sim is not installed (pip cannot install it on Linux)",
                                fix=INSTALL) from None
    return habitat_sim


class HabitatEnv:
    """A robot in an HM3D scene in Habitat-Sim, in the canonical frame.

    ``start``: the episode's start pose in Habitat's frame (HM-EQA's ``scene_init_poses.csv``);
    None takes a navigable point drawn with ``seed``. ``semantic``: attach the semantic sensor
    (None: where the scene has annotations), which lets semantic-sensor perception run here.
    """

    def __init__(self, files: SceneFiles, start: HabitatStart | None = None,
                 camera: CameraSpec | None = None, *, semantic: bool | None = None,
                 gpu_device_id: int = 0, seed: int = 0) -> None:
        hs = import_habitat_sim()
        self.files = files
        self.camera = camera or CameraSpec()
        self.semantic = files.semantic is not None if semantic is None else semantic
        if self.semantic and files.semantic is None:
            raise EfficientEQAError(f"scene {files.scene} has no semantic annotations",
                                    fix="use --perception rgb, or an HM3D-Semantics scene")
        self.sim = hs.Simulator(self._configuration(hs, gpu_device_id))
        try:
            self.pathfinder = self.sim.pathfinder
            if not self.pathfinder.load_nav_mesh(str(files.navmesh)) or not self.pathfinder.is_loaded:
                raise EfficientEQAError(f"Habitat-Sim cannot load the navmesh {files.navmesh}",
                                        fix="download the scene's .basis.navmesh again")
            if start is None:
                self.pathfinder.seed(seed)
                point = self.pathfinder.get_random_navigable_point()
                start = HabitatStart(tuple(float(v) for v in point), 0.0)  # type: ignore[arg-type]
            self.floor_y = start.position[1]
            self.agent = self.sim.initialize_agent(0)
            self._hs = hs
            floor = self._floor_triangles()
            self._floor_area_m2 = frames.triangle_area_m2(floor)
            self._floor_xy = frames.to_canonical(floor, self.floor_y)[:, :2]
            self.start = frames.pose_to_canonical(np.array(start.position), start.yaw_rad, self.floor_y)
            if not self.is_navigable(self.start.x, self.start.y):
                raise EfficientEQAError(f"the start pose {start} is not on the navmesh of {files.scene}",
                                        fix="check the scene and scene_init_poses.csv belong together")
        except BaseException:
            self.sim.close()
            raise
        self.pose = self.start
        self._position_h = np.array(start.position, dtype=float)
        self.steps = 0
        self._labels: HabitatLabels | None = None

    def _configuration(self, hs: ModuleType, gpu_device_id: int) -> Any:
        sim_cfg = hs.SimulatorConfiguration()
        sim_cfg.scene_id = str(self.files.glb)
        if self.semantic and self.files.dataset_config is not None:
            sim_cfg.scene_dataset_config_file = str(self.files.dataset_config)
        sim_cfg.enable_physics = False
        sim_cfg.gpu_device_id = gpu_device_id
        cam = self.camera
        sensors = []
        kinds = [(COLOR, hs.SensorType.COLOR), (DEPTH, hs.SensorType.DEPTH)]
        if self.semantic:
            kinds.append((SEMANTIC, hs.SensorType.SEMANTIC))
        for uuid, kind in kinds:
            spec = hs.CameraSensorSpec()
            spec.uuid = uuid
            spec.sensor_type = kind
            spec.resolution = [cam.height, cam.width]
            spec.hfov = cam.hfov_deg
            spec.position = [0.0, cam.height_m, 0.0]
            spec.orientation = [float(np.radians(cam.pitch_deg)), 0.0, 0.0]
            sensors.append(spec)
        agent_cfg = hs.agent.AgentConfiguration()
        agent_cfg.sensor_specifications = sensors
        return hs.Configuration(sim_cfg, [agent_cfg])

    def _floor_triangles(self) -> np.ndarray:
        """Navmesh triangles (3N, 3) lying on the start's floor (Habitat frame)."""
        verts = np.array([list(v) for v in self.pathfinder.build_navmesh_vertices()], dtype=float)
        if verts.size == 0:
            raise EfficientEQAError(f"the navmesh of {self.files.scene} is empty",
                                    fix="download the scene's .basis.navmesh again")
        tri = verts.reshape(-1, 3, 3)
        on_floor = np.all(np.abs(tri[:, :, 1] - self.floor_y) < FLOOR_BAND_M, axis=1)
        if not on_floor.any():
            raise EfficientEQAError(f"no navmesh lies at the start height {self.floor_y:.2f} m "
                                    f"in {self.files.scene}", fix="check the start pose")
        return tri[on_floor].reshape(-1, 3)

    # -- the contract --------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Observation, dict[str, Any]]:
        """Back to the start pose (or ``options["start"]``, a canonical Pose2D on this floor).
        ``seed`` is accepted for the contract; the scene does not change with it."""
        start = (options or {}).get("start", self.start)
        target = self._reachable(start, require_path=False)
        if target is None:
            raise ValueError(f"start pose {start} is not navigable")
        self._teleport(start, target)
        self.steps = 0
        return self.observe(), self._info(blocked=False)

    def step(self, action: Pose2D) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        target = self._reachable(action, require_path=True)
        if target is not None:
            self._teleport(action, target)
        self.steps += 1
        return self.observe(), 0.0, False, False, self._info(blocked=target is None)

    def observe(self) -> Observation:
        raw = self.sim.get_sensor_observations()
        rgb = np.ascontiguousarray(np.asarray(raw[COLOR])[..., :3], dtype=np.uint8)
        depth = np.asarray(raw[DEPTH], dtype=np.float32).reshape(rgb.shape[:2])
        depth = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0).astype(np.float32)
        instance = None
        if self.semantic:
            instance = self.scene_labels().instance_buffer(np.asarray(raw[SEMANTIC]))
            instance[depth <= 0] = -1
        theta = frames.yaw_to_habitat(self.pose.yaw)
        return Observation(rgb=rgb, depth_m=depth,
                           cam_to_world=frames.camera_to_world(self._position_h, theta,
                                                               self.floor_y, self.camera),
                           intrinsics=self.camera.intrinsics, pose=self.pose, instance=instance)

    def is_navigable(self, x: float, y: float) -> bool:
        point = frames.to_habitat(np.array([x, y, 0.0]), self.floor_y)
        return bool(self.pathfinder.is_navigable(point, MAX_STEP_DELTA_Y_M))

    @property
    def floor_area_m2(self) -> float:
        """The navigable area of the start's floor (the navmesh, so furniture footprints and a
        robot-radius band along the walls are not counted)."""
        return self._floor_area_m2

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The start floor's navmesh extent plus a wall margin; z from the floor to one storey."""
        lo = self._floor_xy.min(axis=0) - WALL_MARGIN_M
        hi = self._floor_xy.max(axis=0) + WALL_MARGIN_M
        return np.array([lo[0], lo[1], 0.0]), np.array([hi[0], hi[1], STOREY_M])

    def scene_labels(self) -> HabitatLabels:
        """The semantic sensor's labels (for semantic-sensor perception)."""
        if not self.semantic:
            raise EfficientEQAError(f"scene {self.files.scene} is loaded without its semantic sensor",
                                    fix="use --perception rgb with an image VLM, or an "
                                        "HM3D-Semantics scene")
        if self._labels is None:
            self._labels = HabitatLabels(self.sim.semantic_scene)
        return self._labels

    def close(self) -> None:
        self.sim.close()

    def __enter__(self) -> HabitatEnv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- internals -----------------------------------------------------------------------
    def _reachable(self, pose: Pose2D, require_path: bool) -> np.ndarray | None:
        """The Habitat position to stand at for ``pose`` (the navmesh height under it), or
        None when it is off the navmesh or, with ``require_path``, unreachable from here."""
        wanted = frames.to_habitat(np.array([pose.x, pose.y, 0.0]), self.floor_y)
        if not self.pathfinder.is_navigable(wanted, MAX_STEP_DELTA_Y_M):
            return None
        snapped = np.array(list(self.pathfinder.snap_point(wanted)), dtype=float)
        if not np.all(np.isfinite(snapped)):
            return None
        target = np.array([wanted[0], snapped[1], wanted[2]])
        if require_path:
            path = self._hs.ShortestPath()
            path.requested_start = self._position_h
            path.requested_end = target
            if not self.pathfinder.find_path(path):
                return None
        return target

    def _teleport(self, pose: Pose2D, position_h: np.ndarray) -> None:
        state = self._hs.AgentState()
        state.position = position_h
        state.rotation = frames.yaw_quaternion(frames.yaw_to_habitat(pose.yaw))
        self.agent.set_state(state)
        self.pose, self._position_h = pose, position_h

    def _info(self, blocked: bool) -> dict[str, Any]:
        return {"step": self.steps, "pose": self.pose, "blocked": blocked,
                "floor_area_m2": self.floor_area_m2}


def open_habitat_scene(root: Path, scene: str, start: HabitatStart | None = None,
                       camera: CameraSpec | None = None, **options: Any) -> HabitatEnv:
    """``scene`` ("00800-TEEsavR23oF") under the HM3D folder ``root``."""
    from efficienteqa.envs.habitat.scenes import find_scene

    import_habitat_sim()  # the first thing a user without it must hear about
    return HabitatEnv(find_scene(root, scene), start, camera, **options)
