"""The synthetic-house environment: the contract of ``envs.base`` over a generated house."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from efficienteqa.envs.synthetic.build import build_geometry
from efficienteqa.envs.synthetic.catalog import Catalog, load_catalog
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M, generate_house, navigation_grid
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS, House
from efficienteqa.envs.synthetic.layout import WALL_HEIGHT_M
from efficienteqa.envs.synthetic.primitives import builtin_catalog
from efficienteqa.envs.synthetic.render import Renderer
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec, Pose2D, camera_to_world
from efficienteqa.observation import Observation

if TYPE_CHECKING:
    from efficienteqa.envs.synthetic.labels import HouseLabels


def catalog_for(assets: str, cc_by: bool = False) -> Catalog:
    """"sh3d": the converted furniture package (CC0, plus CC-BY catalogues when ``cc_by``);
    "builtin": coloured boxes for tests."""
    if assets == "builtin":
        return builtin_catalog()
    if assets == DEFAULT_ASSETS:
        return load_catalog(("CC0-1.0", "CC-BY-3.0") if cc_by else ("CC0-1.0",))
    raise EfficientEQAError(f"unknown assets {assets!r}", fix="use 'sh3d' or 'builtin'")


class SyntheticEnv:
    """A robot in a synthetic house. Actions are target poses; the adapter teleports there.

    A target that is not navigable (inside furniture or walls, or outside the house) leaves the
    robot where it was and reports ``info["blocked"] = True``.
    """

    def __init__(self, house: House, catalog: Catalog, camera: CameraSpec | None = None,
                 renderer: Renderer | None = None) -> None:
        self.house = house
        self.camera = camera or CameraSpec()
        self.grid = navigation_grid(house)
        self.renderer = renderer or Renderer(self.camera)
        self.renderer.set_scene(build_geometry(house, catalog))
        self.pose = house.start
        self.steps = 0

    @classmethod
    def from_seed(cls, seed: int, assets: str = DEFAULT_ASSETS, camera: CameraSpec | None = None
                  ) -> SyntheticEnv:
        catalog = catalog_for(assets)
        return cls(generate_house(seed, catalog, assets), catalog, camera)

    # -- the contract --------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[Observation, dict[str, Any]]:
        """Back to the start pose (or ``options["start"]``, a Pose2D). The house is fixed by
        construction; ``seed`` is accepted for the contract and does not change it."""
        start = (options or {}).get("start", self.house.start)
        if not self.is_navigable(start.x, start.y):
            raise ValueError(f"start pose {start} is not navigable")
        self.pose, self.steps = start, 0
        return self.observe(), self._info(blocked=False)

    def step(self, action: Pose2D) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        blocked = not self.is_navigable(action.x, action.y)
        if not blocked:
            self.pose = action
        self.steps += 1
        return self.observe(), 0.0, False, False, self._info(blocked=blocked)

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
