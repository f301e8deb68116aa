"""The synthetic-house environment: the contract of ``envs.base`` over a generated house."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import ndimage

from efficienteqa.envs.base import move_info
from efficienteqa.envs.synthetic.build import build_geometry
from efficienteqa.envs.synthetic.catalog import Catalog, load_catalog
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M, generate_house, navigation_grid
from efficienteqa.envs.synthetic.house import (
    ALL_CATALOGUES,
    DEFAULT_ASSETS,
    House,
    check_assets,
)
from efficienteqa.envs.synthetic.layout import WALL_HEIGHT_M
from efficienteqa.envs.synthetic.primitives import builtin_catalog
from efficienteqa.envs.synthetic.render import Renderer
from efficienteqa.geometry import CameraSpec, Pose2D, camera_to_world
from efficienteqa.mapping.navgrid import OccupancyGrid
from efficienteqa.observation import Observation

if TYPE_CHECKING:
    from efficienteqa.envs.synthetic.labels import HouseLabels


def catalog_for(assets: str, cc_by: bool = False) -> Catalog:
    """"sh3d": the converted furniture package's CC0 catalogue (plus its CC-BY catalogues
    when ``cc_by``); "sh3d-all": all of them; "builtin": coloured boxes for tests."""
    if assets == "builtin":
        return builtin_catalog()
    check_assets(assets)
    every = cc_by or assets == ALL_CATALOGUES
    return load_catalog(("CC0-1.0", "CC-BY-3.0") if every else ("CC0-1.0",))


def credits(house: House, catalog: Catalog) -> str:
    """Markdown lines crediting the CC-BY models the house uses (empty when all are CC0)."""
    return catalog.attribution(sorted({o.model_key for o in house.objects
                                       if o.category != "door"}))


class SyntheticEnv:
    """A robot in a synthetic house. Actions are target poses; the adapter teleports there.

    A target that is not navigable (inside furniture or walls, or outside the house) leaves the
    robot where it was and reports ``info["blocked"] = True``.
    """

    def __init__(self, house: House, catalog: Catalog, camera: CameraSpec | None = None,
                 renderer: Renderer | None = None) -> None:
        self.house = house
        self.catalog = catalog
        self.camera = camera or CameraSpec()
        self.grid = navigation_grid(house)
        self.renderer = renderer or Renderer(self.camera)
        self.renderer.set_scene(build_geometry(house, catalog))
        self.start = start_clear_of_doors(house, self.grid)
        self.pose = self.start
        self.steps = 0

    @classmethod
    def from_seed(cls, seed: int, assets: str = DEFAULT_ASSETS, camera: CameraSpec | None = None
                  ) -> SyntheticEnv:
        catalog = catalog_for(assets)
        return cls(generate_house(seed, catalog, assets), catalog, camera)

    # -- the contract --------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Observation, dict[str, Any]]:
        """Back to the start pose (``start``: the house's, off any open door's leaf; or
        ``options["start"]``, a Pose2D). The house is fixed by construction; ``seed`` is
        accepted for the contract and does not change it."""
        start = (options or {}).get("start", self.start)
        if not self.is_navigable(start.x, start.y):
            raise ValueError(f"start pose {start} is not navigable")
        self.pose, self.steps = start, 0
        return self.observe(), self._info(blocked=False)

    def step(self, action: Pose2D) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        blocked = not self.is_navigable(action.x, action.y)
        if not blocked:
            self.pose = action
        self.steps += 1
        return self.observe(), 0.0, False, False, {**self._info(blocked=blocked),
                                                   **move_info(action, self.pose, blocked)}

    def observe(self, pose: Pose2D | None = None) -> Observation:
        """The frame at the robot's pose (or at ``pose``, without moving)."""
        pose = pose or self.pose
        cam_to_world = camera_to_world(pose, self.camera)
        frame = self.renderer.render(cam_to_world)
        return Observation(rgb=frame.rgb, depth_m=frame.depth_m, cam_to_world=cam_to_world,
                           intrinsics=self.camera.intrinsics, pose=pose, instance=frame.instance)

    def is_navigable(self, x: float, y: float) -> bool:
        return self.grid.is_navigable(x, y, ROBOT_RADIUS_M)

    @property
    def floor_area_m2(self) -> float:
        return float(sum(r.area_m2 for r in self.house.layout.rooms))

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lay = self.house.layout
        return np.array([0.0, 0.0, 0.0]), np.array([lay.width_m, lay.depth_m, WALL_HEIGHT_M])

    def scene_labels(self) -> HouseLabels:
        """The semantic sensor: object labels and room names (for semantic-sensor perception)."""
        from efficienteqa.envs.synthetic.labels import HouseLabels

        return HouseLabels(self.house)

    def close(self) -> None:
        self.renderer.close()

    def __enter__(self) -> SyntheticEnv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _info(self, blocked: bool) -> dict[str, Any]:
        return {"step": self.steps, "pose": self.pose, "blocked": blocked,
                "floor_area_m2": self.floor_area_m2}


def start_clear_of_doors(house: House, grid: OccupancyGrid) -> Pose2D:
    """The house's start pose; where open doors' leaves (which the navigation grid does not
    hold, but the robot's map does) wall it into a pocket apart from the house's largest
    navigable region (house 129), the navigable cell of that region nearest by path, facing the
    same way. The generated questions keep ``house.start`` (their oracle steps count from it)."""
    start = house.start
    leaves = [o for o in house.objects if o.category == "door"]
    if not leaves:
        return start
    shape = grid.spec.shape
    centres = grid.spec.cell_to_world(np.argwhere(np.ones(shape, bool))).reshape(*shape, 2)
    gap = np.full(shape, np.inf)  # metres from each cell centre to the nearest leaf
    for o in leaves:
        c, s = np.cos(o.yaw), np.sin(o.yaw)
        d = centres - (o.x, o.y)
        u, v = d[..., 0] * c + d[..., 1] * s, -d[..., 0] * s + d[..., 1] * c
        gap = np.minimum(gap, np.hypot(np.maximum(np.abs(u) - o.size_m[0] / 2, 0),
                                       np.maximum(np.abs(v) - o.size_m[1] / 2, 0)))
    open_ = grid.navigable(ROBOT_RADIUS_M) & (gap >= ROBOT_RADIUS_M)
    labels, n = ndimage.label(open_, structure=np.ones((3, 3), bool))
    if n == 0:
        return start
    largest = 1 + int(np.argmax(np.bincount(labels.ravel())[1:]))
    i, j = grid.spec.world_to_cell((start.x, start.y))
    if labels[int(i), int(j)] == largest:
        return start
    path_m = grid.distance_field((start.x, start.y), ROBOT_RADIUS_M)
    ok = (labels == largest) & np.isfinite(path_m)
    if not ok.any():
        return start
    k = np.unravel_index(np.argmin(np.where(ok, path_m, np.inf)), shape)
    return Pose2D(float(centres[k][0]), float(centres[k][1]), start.yaw)
