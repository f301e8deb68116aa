"""Vertex-clustering decimation: heavy catalogue models brought under a triangle budget.

Some CC0 models carry 40-60k triangles for a blender or a plant; a house of them costs twice
the render time for detail a 640x480 camera cannot show. Vertices are snapped to a grid cell
(and, for textured parts, a UV cell, so texture seams survive), triangles that collapse are
dropped, and normals are recomputed flat. The cell grows until the model fits the budget.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from efficienteqa.envs.synthetic.mesh import MeshPart

UV_CELL = 1 / 64  # texture coordinates closer than this may merge (at the finest level)


def cluster_part(part: MeshPart, cell_m: float, uv_cell: float = UV_CELL) -> MeshPart:
    """``part`` with vertices merged per ``cell_m`` grid cell (and ``uv_cell`` texture cell);
    degenerate and repeated triangles removed."""
    tri = part.positions[part.faces].reshape(-1, 3)
    keys = np.floor(tri / cell_m).astype(np.int64)
    uv = part.uvs[part.faces].reshape(-1, 2) if part.uvs is not None else None
    if uv is not None:
        keys = np.concatenate([keys, np.floor(uv / uv_cell).astype(np.int64)], axis=1)
    _, cluster = np.unique(keys, axis=0, return_inverse=True)
    cluster = cluster.reshape(-1)
    counts = np.bincount(cluster).astype(np.float64)[:, None]
    centre = np.zeros((len(counts), 3))
    np.add.at(centre, cluster, tri)
    centre /= counts
    faces = cluster.reshape(-1, 3)
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    faces = np.unique(np.sort(faces[keep], axis=1), axis=0, return_index=True)[1]
    faces = cluster.reshape(-1, 3)[keep][np.sort(faces)]  # original winding, duplicates dropped
    positions = centre[faces].reshape(-1, 3).astype(np.float32)
    normals = np.cross(positions[1::3] - positions[0::3], positions[2::3] - positions[0::3])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    uvs = None
    if uv is not None:
        uv_sum = np.zeros((len(counts), 2))
        np.add.at(uv_sum, cluster, uv)
        uvs = (uv_sum / counts)[faces].reshape(-1, 2).astype(np.float32)
    return replace(part, positions=positions, normals=np.repeat(normals, 3, axis=0).astype(np.float32),
                   faces=np.arange(len(positions), dtype=np.uint32).reshape(-1, 3), uvs=uvs)


def decimate(parts: list[MeshPart], max_triangles: int) -> list[MeshPart]:
    """The model under ``max_triangles`` (unchanged when it already is)."""
    total = sum(len(p.faces) for p in parts)
    if total <= max_triangles:
        return parts
    lo = np.min([p.positions.min(axis=0) for p in parts], axis=0)
    hi = np.max([p.positions.max(axis=0) for p in parts], axis=0)
    size = float(np.max(hi - lo))
    for step in range(16):  # the cells grow 1.5x a step; UV cells with them
        out = [cluster_part(p, size / 400 * 1.5**step, UV_CELL * 1.5**step) for p in parts]
        if sum(len(p.faces) for p in out) <= max_triangles:
            break
    return [p for p in out if len(p.faces)]
