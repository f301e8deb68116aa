"""The off-screen renderer against an independent numpy ray caster, plus orientation, intrinsics,
lighting and texture checks. Skipped when no EGL context can be created."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from efficienteqa.envs.synthetic.mesh import MeshPart, box_part
from efficienteqa.envs.synthetic.render import Renderer
from efficienteqa.envs.synthetic.scene_geometry import Frame, PointLight, SceneGeometry
from efficienteqa.envs.synthetic.textures import FLOOR_KINDS, floor_texture, wall_texture
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec, Pose2D, camera_to_world

CAMERA = CameraSpec()
SMALL = CAMERA.scaled(160, 120)


@pytest.fixture(scope="module")
def renderer() -> Iterator[Renderer]:
    try:
        r = Renderer(SMALL)
    except EfficientEQAError as exc:
        pytest.skip(f"no off-screen OpenGL (EGL) context on this machine: {exc}")
    with r:
        yield r


def _box(size, colour, centre, instance_id: int) -> MeshPart:
    part = box_part(size, colour, centre)
    part.instance_id = instance_id
    return part


def _room() -> list[MeshPart]:
    """A 6 x 6 m floor slab, three 2.5 m walls (structure, id 0) and three boxes (ids 1-3)."""
    return [
        _box((6.0, 6.0, 0.1), (0.6, 0.5, 0.4), (1.0, 0.0, -0.05), 0),
        _box((0.1, 6.0, 2.5), (0.9, 0.9, 0.9), (4.0, 0.0, 1.25), 0),
        _box((6.0, 0.1, 2.5), (0.8, 0.9, 0.8), (1.0, 3.0, 1.25), 0),
        _box((6.0, 0.1, 2.5), (0.8, 0.8, 0.9), (1.0, -3.0, 1.25), 0),
        _box((0.8, 0.8, 0.8), (1.0, 0.0, 0.0), (2.2, 0.9, 0.4), 1),
        _box((0.6, 1.0, 1.2), (0.0, 1.0, 0.0), (2.6, -1.0, 0.6), 2),
        _box((0.4, 0.4, 1.8), (0.0, 0.0, 1.0), (3.4, 0.1, 0.9), 3),
    ]


def _ray_cast(parts: list[MeshPart], origin: np.ndarray, dirs: np.ndarray):
    """Moller-Trumbore against every triangle: (t of the nearest hit or inf, its instance id)."""
    tris = np.concatenate([p.positions[p.faces].astype(np.float64) for p in parts])
    ids = np.concatenate([np.full(len(p.faces), p.instance_id) for p in parts])
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    pvec = np.cross(dirs[:, None, :], e2[None])  # (R, T, 3)
    det = np.einsum("tk,rtk->rt", e1, pvec)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        tvec = origin - v0  # (T, 3)
        u = np.einsum("tk,rtk->rt", tvec, pvec) * inv
        qvec = np.cross(tvec, e1)  # (T, 3)
        v = np.einsum("rk,tk->rt", dirs, qvec) * inv
        t = np.einsum("tk,tk->t", e2, qvec)[None] * inv
    hit = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6)
    t = np.where(hit, t, np.inf)
    nearest = np.argmin(t, axis=1)
    t_min = t[np.arange(len(dirs)), nearest]
    return t_min, np.where(np.isfinite(t_min), ids[nearest], -1)


def _pixel_rays(camera: CameraSpec, cam_to_world: np.ndarray, us: np.ndarray, vs: np.ndarray):
    """World ray directions through pixel centres, scaled so that camera z = 1 (t = depth)."""
    k = camera.intrinsics
    d_cam = np.stack([(us + 0.5 - k[0, 2]) / k[0, 0], (vs + 0.5 - k[1, 2]) / k[1, 1],
                      np.ones_like(us, dtype=np.float64)], axis=1)
    return d_cam @ cam_to_world[:3, :3].T


def _interior(instance: np.ndarray) -> np.ndarray:
    """Pixels whose 3x3 neighbourhood shows a single instance (away from silhouettes)."""
    pad = np.pad(instance, 1, mode="edge")
    h, w = instance.shape
    same = np.ones_like(instance, dtype=bool)
    for dy in range(3):
        for dx in range(3):
            same &= pad[dy:dy + h, dx:dx + w] == instance
    return same


@pytest.fixture(scope="module")
def room_frame(renderer: Renderer):
    parts = _room()
    renderer.set_scene(SceneGeometry(parts))
    pose = camera_to_world(Pose2D(-0.5, 0.2, math.radians(-8.0)), SMALL)
    frame = renderer.render(pose, SMALL)
    rng = np.random.default_rng(0)
    vs, us = rng.integers(0, SMALL.height, 600), rng.integers(0, SMALL.width, 600)
    t, ids = _ray_cast(parts, pose[:3, 3], _pixel_rays(SMALL, pose, us, vs))
    keep = _interior(frame.instance)[vs, us]
    return frame, us[keep], vs[keep], t[keep], ids[keep]


def test_frame_layout(room_frame) -> None:
    frame: Frame = room_frame[0]
    assert frame.rgb.shape == (120, 160, 3) and frame.rgb.dtype == np.uint8
    assert frame.depth_m.shape == (120, 160) and frame.depth_m.dtype == np.float32
    assert frame.instance.shape == (120, 160) and frame.instance.dtype == np.int32


def test_depth_matches_ray_cast(room_frame) -> None:
    frame, us, vs, t, _ = room_frame
    assert len(us) > 300
    hit = np.isfinite(t)
    assert hit.sum() > 200 and (~hit).sum() > 5  # the scene shows sky above the walls
    err = np.abs(frame.depth_m[vs[hit], us[hit]] - t[hit])
    assert err.max() < 0.01, f"max depth error {err.max():.4f} m"
    assert np.all(frame.depth_m[vs[~hit], us[~hit]] == 0.0)


def test_instance_ids_match_ray_cast(room_frame) -> None:
    frame, us, vs, _, ids = room_frame
    rendered = frame.instance[vs, us]
    assert np.mean(rendered == ids) >= 0.99
    for box in (1, 2, 3):
        assert np.any(ids == box), f"box {box} not sampled"
    assert np.all(rendered[ids == -1] == -1)


def test_orientation_left_is_plus_y(renderer: Renderer) -> None:
    floor = _box((10.0, 10.0, 0.1), (0.5, 0.5, 0.5), (0.0, 0.0, -0.05), 0)
    left = _box((0.5, 0.5, 0.5), (1.0, 0.0, 0.0), (3.0, 1.0, 0.25), 7)
    renderer.set_scene(SceneGeometry([floor, left]))
    frame = renderer.render(camera_to_world(Pose2D(0.0, 0.0, 0.0), SMALL), SMALL)
    cols = np.nonzero(frame.instance == 7)[1]
    assert len(cols) > 0 and cols.max() < SMALL.width / 2
    # The floor fills the bottom rows, close by; the top row looks at the sky.
    assert np.all(frame.instance[-5:] == 0)
    assert frame.depth_m[-1].mean() < frame.depth_m[SMALL.height // 2].mean()
    assert np.all(frame.instance[0] == -1)


def test_emissive_ignores_lights(renderer: Renderer) -> None:
    colour = (0.2, 0.8, 0.4)
    glow = _box((0.5, 0.5, 0.5), colour, (2.0, 0.5, 1.2), 1)
    glow.emissive = 1.0
    matte = _box((0.5, 0.5, 0.5), colour, (2.0, -0.5, 1.2), 2)
    pose = camera_to_world(Pose2D(0.0, 0.0, 0.0), SMALL)
    dark = SceneGeometry([glow, matte], lights=[], ambient=0.1, sun_intensity=0.0)
    renderer.set_scene(dark)
    frame = renderer.render(pose, SMALL)
    glow_px = frame.rgb[_interior(frame.instance) & (frame.instance == 1)].astype(int)
    matte_px = frame.rgb[_interior(frame.instance) & (frame.instance == 2)].astype(int)
    assert len(glow_px) > 10 and len(matte_px) > 10
    assert np.abs(glow_px - np.round(np.array(colour) * 255)).max() <= 2
    assert matte_px.sum(axis=1).mean() < 0.6 * glow_px.sum(axis=1).mean()
    # A point light brightens the matte box but leaves the emissive one unchanged.
    renderer.set_scene(SceneGeometry([glow, matte], lights=[PointLight((1.0, -0.5, 1.2))],
                                     ambient=0.1, sun_intensity=0.0))
    lit = renderer.render(pose, SMALL)
    assert lit.rgb[frame.instance == 2].mean() > frame.rgb[frame.instance == 2].mean() + 10
    assert np.array_equal(lit.rgb[frame.instance == 1], frame.rgb[frame.instance == 1])


def test_texture_colours_appear(renderer: Renderer) -> None:
    checker = np.zeros((64, 64, 3), np.uint8)
    checker[...] = (220, 20, 20)
    checker[(np.arange(64)[:, None] // 16 + np.arange(64)[None] // 16) % 2 == 1] = (20, 20, 220)
    panel = _box((0.05, 2.0, 2.0), (1.0, 1.0, 1.0), (2.0, 0.0, 1.0), 4)
    panel.texture = checker
    cutout = _box((0.05, 1.0, 1.0), (1.0, 1.0, 1.0), (1.5, 0.0, 0.4), 5)
    cutout.texture = np.zeros((8, 8, 4), np.uint8)  # fully transparent: alpha-tested away
    renderer.set_scene(SceneGeometry([panel, cutout], ambient=0.9, sun_intensity=0.0))
    frame = renderer.render(camera_to_world(Pose2D(0.0, 0.0, 0.0), SMALL), SMALL)
    px = frame.rgb[frame.instance == 4].astype(int)
    assert np.any((px[:, 0] > 150) & (px[:, 2] < 60))
    assert np.any((px[:, 2] > 150) & (px[:, 0] < 60))
    assert not np.any(frame.instance == 5)


def test_intrinsics_and_projection(renderer: Renderer) -> None:
    assert CAMERA.fx == pytest.approx(184.75, abs=0.01)
    assert SMALL.fx == pytest.approx(CAMERA.fx / 4)
    point = np.array([2.5, 0.7, 0.6])
    marker = _box((0.04, 0.04, 0.04), (1.0, 1.0, 1.0), tuple(point), 9)
    renderer.set_scene(SceneGeometry([marker]))
    pose = camera_to_world(Pose2D(0.3, -0.2, math.radians(10.0)), CAMERA)
    p_cam = np.linalg.inv(pose) @ np.append(point, 1.0)
    u, v, _ = CAMERA.intrinsics @ (p_cam[:3] / p_cam[2])
    frame = renderer.render(pose, CAMERA)
    rows, cols = np.nonzero(frame.instance == 9)
    assert len(rows) > 4
    # Pixel (c, r) covers [c, c + 1) x [r, r + 1): its centre is (c + 0.5, r + 0.5).
    assert cols.mean() + 0.5 == pytest.approx(u, abs=0.5)
    assert rows.mean() + 0.5 == pytest.approx(v, abs=0.5)
    assert frame.depth_m[rows, cols].min() == pytest.approx(p_cam[2] - 0.04, abs=0.03)


def test_topdown_clips_above_cut(renderer: Renderer) -> None:
    floor = _box((4.0, 4.0, 0.1), (0.5, 0.5, 0.5), (0.0, 0.0, -0.05), 0)
    ceiling = _box((4.0, 4.0, 0.1), (0.0, 0.0, 0.0), (0.0, 0.0, 2.55), 0)
    red = _box((0.5, 0.5, 0.5), (1.0, 0.0, 0.0), (1.0, 1.0, 0.25), 1)
    renderer.set_scene(SceneGeometry([floor, ceiling, red], ambient=0.8, sun_intensity=0.2))
    img = renderer.render_topdown((-2.0, -2.0), (2.0, 2.0), 20.0, cut_z=2.0)
    assert img.shape == (80, 80, 3)
    redness = (img[..., 0].astype(int) - img[..., 2]) > 100
    rows, cols = np.nonzero(redness)
    # x = 1 m -> column 60, y = 1 m -> row 20 (row 0 is max y).
    assert cols.mean() == pytest.approx(59.5, abs=1.0)
    assert rows.mean() == pytest.approx(19.5, abs=1.0)
    assert img[40, 20].mean() > 60  # the grey floor, not the black ceiling


def test_textures_deterministic_tileable_and_distinct() -> None:
    textures = []
    for kind in FLOOR_KINDS:
        tex = floor_texture(kind, 3)
        assert tex.shape == (256, 256, 3) and tex.dtype == np.uint8
        assert np.array_equal(tex, floor_texture(kind, 3))
        # Seamless: the wrap-around step is no larger than the steps inside the image.
        for img in (tex, tex.transpose(1, 0, 2)):
            steps = np.abs(np.diff(img.astype(int), axis=1)).mean(axis=(0, 2))
            wrap = np.abs(img[:, 0].astype(int) - img[:, -1]).mean()
            assert wrap <= steps.max() + 1.0, kind
        textures.append(tex.astype(int))
    for i in range(len(textures)):
        for j in range(i):
            assert np.abs(textures[i] - textures[j]).mean() > 20
    assert not np.array_equal(floor_texture("wood", 1), floor_texture("wood", 2))
    wall = wall_texture(0)
    assert wall.shape == (256, 256, 3) and wall.min() > 150  # light, low contrast
    with pytest.raises(ValueError):
        floor_texture("lava", 0)


def test_close_is_idempotent() -> None:
    try:
        r = Renderer(CameraSpec(32, 24))
    except EfficientEQAError as exc:
        pytest.skip(f"no off-screen OpenGL (EGL) context on this machine: {exc}")
    r.close()
    r.close()


def test_two_renderers_side_by_side(renderer: Renderer) -> None:
    """Each renderer makes its own context current; creating or closing another is harmless."""
    box = _box((0.5, 0.5, 0.5), (1.0, 0.0, 0.0), (2.0, 0.0, 1.0), 3)
    pose = camera_to_world(Pose2D(0.0, 0.0, 0.0), SMALL)
    renderer.set_scene(SceneGeometry([box]))
    with Renderer(CameraSpec(32, 24)) as other:
        other.set_scene(SceneGeometry([box]))
        assert np.any(other.render(pose).instance == 3)
        # A one-off camera does not change the default one.
        assert other.render(pose, SMALL).rgb.shape == (120, 160, 3)
        assert other.render(pose).rgb.shape == (24, 32, 3)
        assert np.any(renderer.render(pose, SMALL).instance == 3)
    assert np.any(renderer.render(pose, SMALL).instance == 3)


def test_depth_prepass_and_culling_change_nothing(renderer: Renderer) -> None:
    parts = _room() + [_box((0.3, 0.3, 0.3), (1.0, 1.0, 0.0), (-7.0, 5.0, 0.15), 8)]
    renderer.set_scene(SceneGeometry(parts, lights=[PointLight((1.0, 0.0, 2.0))]))
    pose = camera_to_world(Pose2D(-0.5, 0.2, math.radians(-8.0)), SMALL)
    frames = []
    for prepass in (False, True):
        renderer.depth_prepass = prepass
        frames.append(renderer.render(pose, SMALL))
    renderer.depth_prepass = None
    assert np.array_equal(frames[0].instance, frames[1].instance)
    assert np.array_equal(frames[0].depth_m, frames[1].depth_m)
    assert np.abs(frames[0].rgb.astype(int) - frames[1].rgb).max() <= 1
    # The far box behind the camera is culled; turning round brings it into view.
    back = camera_to_world(Pose2D(-0.5, 0.2, math.atan2(4.8, -6.5)), SMALL)
    assert np.any(renderer.render(back, SMALL).instance == 8)
