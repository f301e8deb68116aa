import numpy as np

from efficienteqa.envs.synthetic.decimate import cluster_part, decimate
from efficienteqa.envs.synthetic.mesh import MeshPart, box_part


def _sphere(n: int = 60) -> MeshPart:
    """A finely tessellated UV sphere of radius 0.5 m (about 2 n^2 triangles)."""
    th, ph = np.meshgrid(np.linspace(0, np.pi, n), np.linspace(0, 2 * np.pi, n), indexing="ij")
    pts = 0.5 * np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    uv = np.stack([ph / (2 * np.pi), th / np.pi], -1)
    idx = np.arange(n * n).reshape(n, n)
    quads = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1).reshape(-1, 4)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]).astype(np.uint32)
    pts = pts.reshape(-1, 3).astype(np.float32)
    return MeshPart(pts, pts * 2, faces, uvs=uv.reshape(-1, 2).astype(np.float32))


def test_budget_is_met_and_shape_kept():
    sphere = _sphere()
    out = decimate([sphere], 1500)
    assert sum(len(p.faces) for p in out) <= 1500
    radius = np.linalg.norm(out[0].positions, axis=1)
    assert np.all(np.abs(radius - 0.5) < 0.03)  # still a sphere
    assert out[0].uvs is not None and out[0].uvs.shape == (len(out[0].positions), 2)
    unit = np.linalg.norm(out[0].normals, axis=1)
    assert np.allclose(unit, 1, atol=1e-4)


def test_small_models_are_untouched_and_boxes_survive_clustering():
    box = box_part((1.0, 0.5, 0.8), (1, 0, 0))
    assert decimate([box], 100)[0] is box
    clustered = cluster_part(box, 0.01)
    assert len(clustered.faces) == 12
    assert np.allclose(np.sort(clustered.positions, axis=0)[[0, -1]],
                       np.sort(box.positions, axis=0)[[0, -1]], atol=0.01)


def test_textured_parts_meet_tight_budgets():
    for budget in (50, 200, 1000):
        kept = sum(len(p.faces) for p in decimate([_sphere(80)], budget))
        assert budget / 4 < kept <= budget
