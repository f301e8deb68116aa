"""Habitat-Sim + HM3D behind the environment contract of ``envs.base`` (DESIGN 4).

``habitat_sim`` is imported when an environment is built, never at import time: it is installed
with conda (it has no usable pip wheel on Linux) and most users never need it. The adapter uses
only Habitat-Sim's documented Python API: ``Simulator``, ``CameraSensorSpec``, ``AgentState``
and the ``PathFinder`` of the scene's navmesh.

Three options choose between ExploreEQA's set-up (Stanford-ILIAD/explore-eqa, the defaults:
what ``--preset paper`` runs) and the project's earlier one (docs/habitat.md, "Fidelity to
ExploreEQA"):

- ``camera_mount``: "body-tilt" (ExploreEQA: the agent's body is tilted by the camera's pitch
  and the sensor sits ``height_m`` up the tilted body, so the camera is about 1.30 m high and
  0.75 m ahead of the agent) or "sensor-pitch" (the body upright, the camera ``height_m``
  straight above the agent and pitched). Either way an observation's ``cam_to_world`` is the
  sensor pose Habitat-Sim reports (``AgentState.sensor_states``), the pose it rendered from.
- ``moves``: "unchecked" (ExploreEQA: the agent is set at the planned pose, at the start's
  floor height, with no navmesh check) or "checked" (the target is snapped to the navmesh and
  taken only when the navmesh has a path to it; otherwise the robot stays and
  ``info["blocked"]`` is True).
- ``budget_area``: the area behind the step budget ``int(sqrt(area) * 3)``: "navmesh-bbox"
  (ExploreEQA: the x-z bounding box of the whole navmesh, every floor) or "floor" (the
  navigable area of the start's floor).

The floor of the start pose is the episode's floor: its height is canonical z = 0.
"""

from __future__ import annotations

import logging
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from efficienteqa.envs.base import move_info
from efficienteqa.envs.habitat import frames
from efficienteqa.envs.habitat.labels import HabitatLabels
from efficienteqa.envs.habitat.scenes import DATASET_CONFIG, HabitatStart, SceneFiles
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
CAMERA_MOUNTS = ("body-tilt", "sensor-pitch")
MOVES = ("unchecked", "checked")
BUDGET_AREAS = ("navmesh-bbox", "floor")


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
    (None: where the scene has annotations and their dataset config), which lets
    semantic-sensor perception run here. ``camera_mount``, ``moves``, ``budget_area``: see the
    module's docstring.
    """

    scanned = True  # textured from photographs: frames that look real (``envs.base.looks_real``)

    def __init__(self, files: SceneFiles, start: HabitatStart | None = None,
                 camera: CameraSpec | None = None, *, semantic: bool | None = None,
                 camera_mount: str = "body-tilt", moves: str = "unchecked",
                 budget_area: str = "navmesh-bbox", gpu_device_id: int = 0, seed: int = 0) -> None:
        for name, value, allowed in (("camera_mount", camera_mount, CAMERA_MOUNTS),
                                     ("moves", moves, MOVES), ("budget_area", budget_area, BUDGET_AREAS)):
            if value not in allowed:
                raise EfficientEQAError(f"unknown Habitat {name} {value!r}",
                                        fix=f"use one of {', '.join(allowed)}")
        hs = import_habitat_sim()
        self.files = files
        self.camera = camera or CameraSpec()
        self.camera_mount, self.moves, self.budget_area = camera_mount, moves, budget_area
        self._unlabelled = _unloadable_annotations(files)
        if semantic is None:
            semantic = files.semantic is not None and self._unlabelled is None
            if self._unlabelled is not None:
                log.warning("%s; the semantic sensor is left off", self._unlabelled.args[0])
        self.semantic = semantic
        if self.semantic and self._unlabelled is not None:
            raise self._unlabelled
        if self.semantic and files.semantic is None:
            raise EfficientEQAError(f"scene {files.scene} has no semantic annotations",
                                    fix="use --backends.perception rgb, or an HM3D-Semantics scene")
        self.sim = hs.Simulator(self._configuration(hs, gpu_device_id))
        try:
            self.pathfinder = self.sim.pathfinder
            if not self.pathfinder.load_nav_mesh(str(files.navmesh)) or not self.pathfinder.is_loaded:
                raise EfficientEQAError(f"Habitat-Sim cannot load the navmesh {files.navmesh}",
                                        fix="download the scene's .basis.navmesh again")
            if self.semantic:
                self._check_annotations_loaded()
            if start is None:
                self.pathfinder.seed(seed)
                point = self.pathfinder.get_random_navigable_point()
                start = HabitatStart(tuple(float(v) for v in point), 0.0)  # type: ignore[arg-type]
            self.floor_y = start.position[1]
            self.agent = self.sim.initialize_agent(0)  # at a random pose: _teleport below
            self._hs = hs
            floor = self._floor_triangles()
            self._floor_area_m2 = frames.triangle_area_m2(floor)
            self._floor_xy = frames.to_canonical(floor, self.floor_y)[:, :2]
            lo, hi = (np.asarray(list(b), dtype=float) for b in self.pathfinder.get_bounds())
            self._navmesh_bbox_area_m2 = float(abs((hi[0] - lo[0]) * (hi[2] - lo[2])))
            self.start = frames.pose_to_canonical(np.array(start.position), start.yaw_rad, self.floor_y)
            at = self._reachable(self.start, require_path=False)
            if at is None:
                raise EfficientEQAError(f"the start pose {start} is not on the navmesh of {files.scene}",
                                        fix="check the scene and scene_init_poses.csv belong together")
            self._teleport(self.start, at)  # observe() before reset() sees the start
        except BaseException:
            self.sim.close()
            raise
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
        pitch = 0.0 if self.camera_mount == "body-tilt" else float(np.radians(cam.pitch_deg))
        for uuid, kind in kinds:
            spec = hs.CameraSensorSpec()
            spec.uuid = uuid
            spec.sensor_type = kind
            spec.resolution = [cam.height, cam.width]
            spec.hfov = cam.hfov_deg
            spec.position = [0.0, cam.height_m, 0.0]  # in the body frame (tilted with body-tilt)
            spec.orientation = [pitch, 0.0, 0.0]
            sensors.append(spec)
        agent_cfg = hs.agent.AgentConfiguration()
        agent_cfg.sensor_specifications = sensors
        return hs.Configuration(sim_cfg, [agent_cfg])

    def _check_annotations_loaded(self) -> None:
        """Habitat-Sim only warns when it finds no annotations for the scene in its dataset
        config, and its semantic sensor then reads 0 everywhere: refuse that here."""
        objects = getattr(self.sim.semantic_scene, "objects", None) or []
        if not any(obj is not None for obj in objects):
            raise EfficientEQAError(
                f"Habitat-Sim loaded {self.files.scene} without its semantic annotations "
                f"({self.files.dataset_config} names none for it)",
                fix=f"use the {DATASET_CONFIG} of the same HM3D-Semantics download as the "
                    "scene, or --backends.perception rgb")

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
        if self.moves == "unchecked":  # ExploreEQA: set the planned pose, on the start's floor
            target: np.ndarray | None = frames.to_habitat(np.array([action.x, action.y, 0.0]),
                                                          self.floor_y)
        else:
            target = self._reachable(action, require_path=True)
        if target is not None:
            self._teleport(action, target)
        self.steps += 1
        return self.observe(), 0.0, False, False, {
            **self._info(blocked=target is None), **move_info(action, self.pose, target is None)}

    def observe(self) -> Observation:
        raw = self.sim.get_sensor_observations()
        rgb = np.ascontiguousarray(np.asarray(raw[COLOR])[..., :3], dtype=np.uint8)
        depth = np.asarray(raw[DEPTH], dtype=np.float32).reshape(rgb.shape[:2])
        depth = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0).astype(np.float32)
        instance = None
        if self.semantic:
            instance = self.scene_labels().instance_buffer(np.asarray(raw[SEMANTIC]))
            instance[depth <= 0] = -1
        return Observation(rgb=rgb, depth_m=depth, cam_to_world=self.camera_pose(),
                           intrinsics=self.camera.intrinsics, pose=self.pose, instance=instance)

    def camera_pose(self) -> np.ndarray:
        """The canonical cam_to_world of the depth sensor as Habitat-Sim reports it (the pose
        it renders from, so maps and back-projection use what the simulator did)."""
        sensor = self.agent.get_state().sensor_states[DEPTH]
        return frames.sensor_to_world(np.asarray(sensor.position, dtype=float), sensor.rotation,
                                      self.floor_y)

    def is_navigable(self, x: float, y: float) -> bool:
        point = frames.to_habitat(np.array([x, y, 0.0]), self.floor_y)
        return bool(self.pathfinder.is_navigable(point, MAX_STEP_DELTA_Y_M))

    @property
    def floor_area_m2(self) -> float:
        """The navigable area of the start's floor (the navmesh, so furniture footprints and a
        robot-radius band along the walls are not counted)."""
        return self._floor_area_m2

    @property
    def navmesh_bbox_area_m2(self) -> float:
        """The area of the x-z bounding box of the whole navmesh, every floor (ExploreEQA's
        ``scene_size``, from ``PathFinder.get_bounds``)."""
        return self._navmesh_bbox_area_m2

    @property
    def budget_area_m2(self) -> float:
        """The area behind the step budget (``stop.env_step_budget``), as ``budget_area`` says."""
        return self.navmesh_bbox_area_m2 if self.budget_area == "navmesh-bbox" else self.floor_area_m2

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The start floor's navmesh extent plus a wall margin; z from the floor to one storey."""
        lo = self._floor_xy.min(axis=0) - WALL_MARGIN_M
        hi = self._floor_xy.max(axis=0) + WALL_MARGIN_M
        return np.array([lo[0], lo[1], 0.0]), np.array([hi[0], hi[1], STOREY_M])

    def scene_labels(self) -> HabitatLabels:
        """The semantic sensor's labels (for semantic-sensor perception)."""
        if not self.semantic and self._unlabelled is not None:
            raise self._unlabelled
        if not self.semantic:
            raise EfficientEQAError(f"scene {self.files.scene} is loaded without its semantic sensor",
                                    fix="use --backends.perception rgb with an image VLM, or an "
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
        tilt = float(np.radians(self.camera.pitch_deg)) if self.camera_mount == "body-tilt" else 0.0
        state = self._hs.AgentState()
        state.position = position_h
        state.rotation = frames.body_quaternion(frames.yaw_to_habitat(pose.yaw), tilt)
        self.agent.set_state(state)
        self.pose, self._position_h = pose, position_h

    def _info(self, blocked: bool) -> dict[str, Any]:
        return {"step": self.steps, "pose": self.pose, "blocked": blocked,
                "floor_area_m2": self.floor_area_m2, "budget_area_m2": self.budget_area_m2}


def _unloadable_annotations(files: SceneFiles) -> EfficientEQAError | None:
    """Why Habitat-Sim would load the scene's semantic annotations as all zeros (it only
    warns): the ``.semantic.*`` files are there but no dataset config names them."""
    if files.semantic is None or files.dataset_config is not None:
        return None
    return EfficientEQAError(
        f"scene {files.scene} has HM3D-Semantics files but no {DATASET_CONFIG} was found, so "
        "Habitat-Sim would read every object id as 0",
        fix=f"put {DATASET_CONFIG} (from the HM3D semantics download) in "
            f"{files.semantic.parent.parent}, or use --backends.perception rgb")


def open_habitat_scene(root: Path, scene: str, start: HabitatStart | None = None,
                       camera: CameraSpec | None = None, **options: Any) -> HabitatEnv:
    """``scene`` ("00800-TEEsavR23oF") under the HM3D folder ``root``."""
    from efficienteqa.envs.habitat.scenes import find_scene

    import_habitat_sim()  # the first thing a user without it must hear about
    return HabitatEnv(find_scene(root, scene), start, camera, **options)
