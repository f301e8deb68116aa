"""The one mesh type exchanged by the furniture catalogue, the house builder and the renderer."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt


@dataclass
class MeshPart:
    """Triangles sharing one material.

    positions, normals: (N, 3) float32 metres in the part's frame (a model's local frame: z up,
    origin at the bottom centre of its bounding box, front facing -y; or the world frame).
    uvs: (N, 2) float32 or None. faces: (F, 3) uint32. colour: diffuse RGB in [0, 1]
    (multiplies the texture when there is one). texture: (h, w, 3|4) uint8 or None.
    emissive: 0 = lit by the scene, 1 = shows its own colour (a lit screen, a bulb).
    instance_id: 0 = structure, > 0 = an object of the house. material: the source name.
    """

    positions: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    colour: tuple[float, float, float] = (0.8, 0.8, 0.8)
    uvs: np.ndarray | None = None
    texture: np.ndarray | None = None
    emissive: float = 0.0
    instance_id: int = 0
    material: str = ""

    def transformed(self, matrix: np.ndarray, instance_id: int | None = None) -> MeshPart:
        """This part moved by a 4x4 rigid transform (normals rotated, not translated)."""
        rot, shift = matrix[:3, :3], matrix[:3, 3]
        return replace(
            self,
            positions=(self.positions @ rot.T + shift).astype(np.float32),
            normals=(self.normals @ rot.T).astype(np.float32),
            instance_id=self.instance_id if instance_id is None else instance_id,
        )

    @property
    def area_m2(self) -> float:
        tri = self.positions[self.faces]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        return float(0.5 * np.linalg.norm(cross, axis=1).sum())


def rgb3(values: Iterable[float]) -> tuple[float, float, float]:
    """Exactly three numbers (a list, an array row, a generator) as an RGB tuple of floats."""
    r, g, b = (float(c) for c in values)
    return r, g, b


def pose_matrix(x: float, y: float, z: float, yaw_rad: float) -> np.ndarray:
    """4x4 transform: rotate by yaw about +z, then translate."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    m[:3, 3] = [x, y, z]
    return m


def box_part(size_m: tuple[float, float, float], colour: tuple[float, float, float],
             centre: tuple[float, float, float] = (0.0, 0.0, 0.0), material: str = "") -> MeshPart:
    """An axis-aligned box with flat normals; ``centre`` is the box centre."""
    half = np.asarray(size_m, dtype=np.float32) / 2
    c = np.asarray(centre, dtype=np.float32)
    positions: list[npt.NDArray[np.float32]] = []
    normals: list[npt.NDArray[np.float32]] = []
    uvs: list[tuple[float, float]] = []
    faces: list[tuple[int, int, int]] = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            normal = np.zeros(3, np.float32)
            normal[axis] = sign
            u_axis, v_axis = (axis + 1) % 3, (axis + 2) % 3  # e_u x e_v = e_axis
            if sign < 0:
                u_axis, v_axis = v_axis, u_axis
            base = len(positions)
            for du, dv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = np.zeros(3, np.float32)
                p[axis] = sign * half[axis]
                p[u_axis] = du * half[u_axis]
                p[v_axis] = dv * half[v_axis]
                positions.append(p + c)
                normals.append(normal)
                uvs.append(((du + 1) / 2 * size_m[u_axis], (dv + 1) / 2 * size_m[v_axis]))
            faces += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return MeshPart(
        positions=np.array(positions, np.float32),
        normals=np.array(normals, np.float32),
        faces=np.array(faces, np.uint32),
        uvs=np.array(uvs, np.float32),
        colour=colour,
        material=material,
    )
