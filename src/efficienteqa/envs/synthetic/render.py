"""Off-screen OpenGL renderer for synthetic houses (moderngl, EGL, Mesa llvmpipe on CPU).

One pass writes three targets: colour (RGBA8), linear depth (R32F, metres along the optical
axis) and instance id (R32I, stored as id + 1 so that a cleared 0 means "nothing hit").

Frames: parts and lights are in the world frame (z up, metres). ``cam_to_world`` uses OpenCV
camera axes (x right, y down, z forward). The projection maps camera +y (down) to window rows
that increase, so the first row glReadPixels returns (window row 0) is the top of the image:
frames read back are already in OpenCV order (row 0 = top, column 0 = left). That y flip
mirrors the winding of every triangle, which does not matter: nothing is culled.

The shaders, context and vertex layout are in ``render_gl.py``; the scene and frame types in
``scene_geometry.py``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Concatenate, ParamSpec, TypeVar

import moderngl
import numpy as np

from efficienteqa.envs.synthetic.mesh import MeshPart
from efficienteqa.envs.synthetic.render_gl import (
    ATTRIBUTES,
    FAR_M,
    MAX_LIGHTS,
    VERTEX_DTYPE,
    compile_programs,
    create_context,
    part_vertices,
    projection_matrix,
    texture_key,
    uniform,
)
from efficienteqa.envs.synthetic.scene_geometry import Frame, SceneGeometry
from efficienteqa.geometry import CameraSpec

CELL_M = 3.0  # floor grid (metres) for frustum culling
PREPASS_MIN_PIXELS = 320 * 240  # above this, a depth pre-pass pays for itself on llvmpipe

@dataclass
class _Batch:
    vao: moderngl.VertexArray
    depth_vao: moderngl.VertexArray | None  # position only, for the depth pre-pass
    buffers: list[moderngl.Buffer]
    texture: moderngl.Texture | None
    cutout: bool
    cells: slice  # this batch's rows of Renderer._cell_* (index ranges in floor-grid cells)


_P = ParamSpec("_P")
_R = TypeVar("_R")


def _current(method: Callable[Concatenate[Renderer, _P], _R]
             ) -> Callable[Concatenate[Renderer, _P], _R]:
    """Make the renderer's GL context current for the call: several renderers (contexts) may
    live in one thread, and creating or releasing one changes which context is current."""

    @functools.wraps(method)
    def wrapper(self: Renderer, *args: _P.args, **kwargs: _P.kwargs) -> _R:
        if self._ctx is None:
            raise RuntimeError("the renderer is closed")
        with self._ctx:
            return method(self, *args, **kwargs)

    return wrapper


class Renderer:
    """Renders a ``SceneGeometry`` through a ``CameraSpec`` (one GL context per renderer).

    Use as a context manager, or call ``close()``. ``set_scene`` uploads once; parts sharing a
    texture (or having none) are merged into one vertex/index buffer, ordered by 3 m floor cell
    so that cells outside the view frustum are skipped (one draw call per run of visible
    cells). ``depth_prepass``: draw opaque depth first so each pixel is shaded once; None =
    only above 320x240 pixels, where it pays for itself.
    """

    def __init__(self, camera: CameraSpec, depth_prepass: bool | None = None) -> None:
        self.camera = camera
        self._ctx = create_context()
        self._programs, self._depth_program = compile_programs(self._ctx)
        self.depth_prepass = depth_prepass
        self._batches: list[_Batch] = []
        self._scene: SceneGeometry | None = None
        # Render targets per (width, height), kept so that alternating sizes costs nothing.
        self._targets: dict[tuple[int, int], dict[str, moderngl.Framebuffer]] = {}

    # -- resources -------------------------------------------------------------------------
    def _make_targets(self, width: int, height: int) -> dict[str, moderngl.Framebuffer]:
        ctx = self._ctx
        colour = ctx.renderbuffer((width, height), 4)
        depth = ctx.renderbuffer((width, height), 1, dtype="f4")
        inst = ctx.renderbuffer((width, height), 1, dtype="i4")
        zbuf = ctx.depth_renderbuffer((width, height))
        return {
            "all": ctx.framebuffer([colour, depth, inst], zbuf),
            "depth": ctx.framebuffer(depth_attachment=zbuf),
            "colour": ctx.framebuffer([colour]),
        }

    def _release_targets(self, targets: dict[str, moderngl.Framebuffer]) -> None:
        for fbo in targets.values():
            for attachment in (*fbo.color_attachments, fbo.depth_attachment):
                if attachment is not None:
                    attachment.release()
            fbo.release()

    def _release_scene(self) -> None:
        for batch in self._batches:
            batch.vao.release()
            if batch.depth_vao is not None:
                batch.depth_vao.release()
            for buf in batch.buffers:
                buf.release()
            if batch.texture is not None:
                batch.texture.release()
        self._batches = []

    def close(self) -> None:
        """Release every GL object and the context (idempotent)."""
        if self._ctx is None:
            return
        with self._ctx:
            self._release_scene()
            for targets in self._targets.values():
                self._release_targets(targets)
            for prog in (*self._programs.values(), self._depth_program):
                prog.release()
        self._ctx.release()
        # None marks the renderer closed (checked by @_current); typed as always open so that
        # the methods it guards need no narrowing
        self._ctx = None  # type: ignore[assignment]

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- scene -----------------------------------------------------------------------------
    @_current
    def set_scene(self, geometry: SceneGeometry) -> None:
        """Upload the scene's meshes and textures (replacing any previous scene)."""
        self._release_scene()
        self._scene = geometry
        groups: dict[str | None, list[tuple[MeshPart, np.ndarray]]] = {}
        textures: dict[str, np.ndarray] = {}
        for part in geometry.parts:
            if len(part.faces) == 0:
                continue
            colour = np.asarray(part.colour, np.float32)
            key = None
            if part.texture is not None and part.uvs is not None:
                key = texture_key(part.texture)
                textures[key] = part.texture
            elif part.texture is not None:  # a texture without uvs: use its mean colour
                colour = colour * part.texture[..., :3].reshape(-1, 3).mean(0) / 255.0
            groups.setdefault(key, []).append((part, colour))
        firsts: list[int] = []
        counts: list[int] = []
        boxes: list[np.ndarray] = []
        for key, members in groups.items():
            # Order parts by floor cell so each cell is one contiguous index range that can be
            # frustum-culled on its own (llvmpipe transforms vertices on one thread).
            cell_of = [tuple(np.floor(p.positions.mean(0)[:2] / CELL_M).astype(int))
                       for p, _ in members]
            order = sorted(range(len(members)), key=lambda i: cell_of[i])
            verts, faces, offset, start = [], [], 0, len(firsts)
            index, prev_cell = 0, None
            for i in order:
                part, colour = members[i]
                verts.append(part_vertices(part, colour))
                faces.append(part.faces.astype(np.uint32) + offset)
                offset += len(part.positions)
                box = np.stack([part.positions.min(0), part.positions.max(0)])
                if cell_of[i] == prev_cell:
                    counts[-1] += 3 * len(part.faces)
                    boxes[-1] = np.stack([np.minimum(boxes[-1][0], box[0]),
                                          np.maximum(boxes[-1][1], box[1])])
                else:
                    firsts.append(index)
                    counts.append(3 * len(part.faces))
                    boxes.append(box)
                index += 3 * len(part.faces)
                prev_cell = cell_of[i]
            texture, cutout = None, False
            if key is not None:
                texture, cutout = self._upload_texture(textures[key])
            self._batches.append(self._make_batch(
                np.concatenate(verts), np.concatenate(faces), texture, cutout,
                slice(start, len(firsts))))
        self._cell_first = np.array(firsts, np.int64)
        self._cell_count = np.array(counts, np.int64)
        self._cell_box = np.array(boxes, np.float64).reshape(-1, 2, 3)

    def _upload_texture(self, image: np.ndarray) -> tuple[moderngl.Texture, bool]:
        image = np.ascontiguousarray(image, dtype=np.uint8)
        if image.ndim == 2:
            image = np.repeat(image[..., None], 3, axis=2)
        comps = image.shape[2]
        cutout = comps == 4 and bool((image[..., 3] < 128).any())
        # Texture row 0 is the image top; OpenGL's v = 0 is the first row uploaded, so flip
        # to make v = 0 the bottom of the image (the OBJ/MTL convention).
        tex = self._ctx.texture((image.shape[1], image.shape[0]), comps,
                                np.ascontiguousarray(image[::-1]).tobytes(), alignment=1)
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = True
        return tex, cutout

    def _make_batch(self, verts: np.ndarray, faces: np.ndarray,
                    texture: moderngl.Texture | None, cutout: bool, cells: slice) -> _Batch:
        vbo = self._ctx.buffer(verts.tobytes())
        ibo = self._ctx.buffer(faces.astype(np.uint32).tobytes())
        vao = self._ctx.vertex_array(
            self._programs[cutout], [(vbo, "3f 3f 2f 3f 1f 1i", *ATTRIBUTES)],
            index_buffer=ibo, index_element_size=4,
        )
        depth_vao = None if cutout else self._ctx.vertex_array(
            self._depth_program, [(vbo, f"3f {VERTEX_DTYPE.itemsize - 12}x", "in_pos")],
            index_buffer=ibo, index_element_size=4,
        )
        return _Batch(vao, depth_vao, [vbo, ibo], texture, cutout, cells)

    # -- drawing ---------------------------------------------------------------------------
    def _set_uniforms(self, view: np.ndarray, view_proj: np.ndarray, eye: np.ndarray,
                      ortho: bool) -> None:
        scene = self._scene
        assert scene is not None
        sun = -np.asarray(scene.sun_direction, np.float64)
        sun /= max(float(np.linalg.norm(sun)), 1e-9)
        lights = scene.lights[:MAX_LIGHTS]
        pos = np.zeros((MAX_LIGHTS, 3), np.float32)
        col = np.zeros((MAX_LIGHTS, 3), np.float32)
        inv_r2 = np.ones(MAX_LIGHTS, np.float32)
        for i, light in enumerate(lights):
            pos[i] = light.position
            col[i] = np.asarray(light.colour, np.float32) * light.intensity
            inv_r2[i] = 1.0 / max(light.radius_m, 1e-3) ** 2
        values = {
            "u_view_proj": view_proj.T.astype("f4").tobytes(),
            "u_view": view.T.astype("f4").tobytes(),
            "u_eye": tuple(map(float, eye)), "u_ortho": ortho,
            "u_ambient": float(scene.ambient), "u_sun_dir": tuple(map(float, sun)),
            "u_sun": float(scene.sun_intensity), "u_n_lights": len(lights),
            "u_light_pos": pos.tobytes(), "u_light_col": col.tobytes(),
            "u_light_inv_r2": inv_r2.tobytes(), "u_tex": 0,
        }
        uniform(self._depth_program, "u_view_proj").write(values["u_view_proj"])
        for prog in self._programs.values():
            for name, value in values.items():
                if name not in prog:
                    continue
                if isinstance(value, bytes):
                    uniform(prog, name).write(value)
                else:
                    uniform(prog, name).value = value

    def _visible_ranges(self, view_proj: np.ndarray) -> list[list[tuple[int, int]]]:
        """Per batch, the (first index, index count) runs of cells that touch the frustum."""
        lo, hi = self._cell_box[:, 0], self._cell_box[:, 1]
        corners = np.stack([np.where(np.array(bits, bool), hi, lo)
                            for bits in np.ndindex(2, 2, 2)], axis=1)  # (M, 8, 3)
        clip = corners @ view_proj[:3, :3].T + view_proj[:3, 3]
        w = corners @ view_proj[3, :3] + view_proj[3, 3]
        outside = np.zeros(len(lo), bool)
        for axis in range(3):  # all eight corners beyond one clip plane -> culled
            outside |= np.all(clip[..., axis] < -w, axis=1) | np.all(clip[..., axis] > w, axis=1)
        runs: list[list[tuple[int, int]]] = []
        for batch in self._batches:
            batch_runs: list[tuple[int, int]] = []
            for cell in range(batch.cells.start, batch.cells.stop):
                if outside[cell]:
                    continue
                first, count = int(self._cell_first[cell]), int(self._cell_count[cell])
                if batch_runs and sum(batch_runs[-1]) == first:
                    batch_runs[-1] = (batch_runs[-1][0], batch_runs[-1][1] + count)
                else:
                    batch_runs.append((first, count))
            runs.append(batch_runs)
        return runs

    def _draw(self, targets: dict[str, moderngl.Framebuffer], view_proj: np.ndarray,
              prepass: bool) -> None:
        assert self._scene is not None, "call set_scene() first"
        runs = self._visible_ranges(view_proj)
        ctx = self._ctx
        targets["all"].use()
        targets["all"].clear(0.0, 0.0, 0.0, 0.0, depth=1.0)  # depth 0 m, instance 0 (= -1)
        targets["colour"].clear(*self._scene.sky_colour, 1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        ctx.depth_func = "<"
        if prepass:
            # Opaque depth first (cheap), then shade each pixel once: llvmpipe is fragment-bound.
            targets["depth"].use()
            for batch, batch_runs in zip(self._batches, runs, strict=True):
                if batch.depth_vao is None:  # cutout batches: alpha decides, not depth alone
                    continue
                for first, count in batch_runs:
                    batch.depth_vao.render(moderngl.TRIANGLES, vertices=count, first=first)
            ctx.depth_func = "<="
        targets["all"].use()
        order = sorted(range(len(self._batches)), key=lambda i: self._batches[i].cutout)
        for batch, batch_runs in ((self._batches[i], runs[i]) for i in order):  # opaque first
            if not batch_runs:
                continue
            prog = self._programs[batch.cutout]
            uniform(prog, "u_textured").value = batch.texture is not None
            if batch.texture is not None:
                batch.texture.use(0)
            for first, count in batch_runs:
                batch.vao.render(moderngl.TRIANGLES, vertices=count, first=first)

    def _read(self, fbo: moderngl.Framebuffer, width: int, height: int) -> Frame:
        rgb = np.frombuffer(fbo.read(components=3, attachment=0, alignment=1), np.uint8)
        depth = np.frombuffer(fbo.read(components=1, attachment=1, dtype="f4"), np.float32)
        inst = np.frombuffer(fbo.read(components=1, attachment=2, dtype="i4"), np.int32)
        return Frame(rgb=rgb.reshape(height, width, 3).copy(),
                     depth_m=depth.reshape(height, width).copy(),
                     instance=inst.reshape(height, width) - 1)

    @_current
    def render(self, cam_to_world: np.ndarray, camera: CameraSpec | None = None) -> Frame:
        """Render from ``cam_to_world`` (4x4, OpenCV camera axes, metres).

        ``camera`` (default: always the renderer's own ``self.camera``) may differ in
        resolution, e.g. ``camera.scaled(160, 120)`` for cheap visibility checks; targets are
        allocated once per size.
        """
        camera = camera or self.camera
        size = (camera.width, camera.height)
        if size not in self._targets:
            self._targets[size] = self._make_targets(*size)
        targets = self._targets[size]
        cam_to_world = np.asarray(cam_to_world, np.float64)
        view = np.linalg.inv(cam_to_world)
        view_proj = projection_matrix(camera) @ view
        self._set_uniforms(view, view_proj, cam_to_world[:3, 3], ortho=False)
        prepass = self.depth_prepass
        if prepass is None:
            prepass = camera.width * camera.height > PREPASS_MIN_PIXELS
        self._draw(targets, view_proj, prepass)
        return self._read(targets["all"], camera.width, camera.height)

    @_current
    def render_topdown(self, bounds_min_xy: tuple[float, float] | np.ndarray,
                       bounds_max_xy: tuple[float, float] | np.ndarray, px_per_m: float,
                       cut_z: float) -> np.ndarray:
        """Orthographic RGB view from above of the given xy rectangle (metres, world).

        Geometry above ``cut_z`` (metres) is clipped by the near plane, so ceilings vanish. Returns
        (H, W, 3) uint8 with H = ceil(dy * px_per_m), W = ceil(dx * px_per_m); column 0 is
        min x, row 0 is max y (north up, like a map).
        """
        lo = np.asarray(bounds_min_xy, np.float64)
        hi = np.asarray(bounds_max_xy, np.float64)
        width = max(1, math.ceil((hi[0] - lo[0]) * px_per_m))
        height = max(1, math.ceil((hi[1] - lo[1]) * px_per_m))
        hi = lo + np.array([width, height]) / px_per_m
        top, bottom = cut_z, -FAR_M  # the near plane sits at cut_z
        # World -> camera looking down -z, camera x = world x, camera y (down) = -world y.
        view = np.array([[1.0, 0, 0, 0], [0, -1.0, 0, 0], [0, 0, -1.0, top], [0, 0, 0, 1]])
        ortho = np.array([
            [2 / (hi[0] - lo[0]), 0, 0, -(hi[0] + lo[0]) / (hi[0] - lo[0])],
            [0, 2 / (hi[1] - lo[1]), 0, (hi[1] + lo[1]) / (hi[1] - lo[1])],
            [0, 0, 2 / (top - bottom), -1.0],
            [0, 0, 0, 1],
        ])
        targets = self._make_targets(width, height)
        try:
            self._set_uniforms(view, ortho @ view, np.array([0.0, 0.0, top]), ortho=True)
            self._draw(targets, ortho @ view, prepass=True)
            return self._read(targets["all"], width, height).rgb
        finally:
            self._release_targets(targets)
