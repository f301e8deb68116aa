"""A top-down picture of the map state: drawing only, no logic beyond coordinate transforms.

North up: image row 0 is the grid's top row (largest y); each cell is ``scale`` x ``scale``
pixels. Image coordinates are continuous with pixel k spanning [k, k+1).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.state import MapState

if TYPE_CHECKING:
    from efficienteqa.observation import PromptPoint



class FrontierMark(Protocol):
    """What a frontier needs to be drawn (``explore.base.Frontier`` has it; mapping sits below
    explore and does not import it): its point and outward normal (m) and its size (cells)."""

    @property
    def xy(self) -> tuple[float, float]: ...

    @property
    def normal(self) -> tuple[float, float]: ...

    @property
    def size(self) -> int: ...


UNOBSERVED = (64, 64, 64)
FREE = (235, 235, 235)
EXPLORED = (200, 235, 200)
OCCUPIED = (0, 0, 0)
FRONTIER = (0, 110, 255)
TRAJECTORY = (255, 140, 0)
ROBOT = (220, 0, 0)
TARGET = (200, 0, 200)
PROMPT = (220, 220, 220)


def world_to_image(spec: GridSpec, xy: np.ndarray | Sequence[float], scale: int) -> np.ndarray:
    """Continuous image (u, v) (..., 2) of world points xy (..., 2) metres, north up."""
    p = np.asarray(xy, dtype=float)
    u = (p[..., 0] - spec.origin_xy[0]) / spec.resolution_m * scale
    v = (spec.shape[0] - (p[..., 1] - spec.origin_xy[1]) / spec.resolution_m) * scale
    return np.stack([u, v], axis=-1)


def _cell_colours(state: MapState, values: np.ndarray | None) -> np.ndarray:
    img = np.empty((*state.spec.shape, 3), dtype=float)
    img[:] = UNOBSERVED
    img[state.free] = FREE
    img[state.free & state.explored] = EXPLORED
    if values is not None:
        v = np.clip(np.asarray(values, dtype=float), 0.0, None)
        t = v / max(float(v.max()), 1e-12)
        heat = np.stack([np.full_like(t, 255.0), 255.0 * (1.0 - t), np.zeros_like(t)], axis=-1)
        alpha = (0.7 * t)[..., None]
        img = np.where(v[..., None] > 0, (1 - alpha) * img + alpha * heat, img)
    img[state.occupied] = OCCUPIED
    return img.round().astype(np.uint8)


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    try:
        return ImageFont.load_default(size=size)  # Pillow >= 10.1
    except TypeError:
        return ImageFont.load_default()


def _disk(draw: ImageDraw.ImageDraw, uv: np.ndarray, r: float, **kw: object) -> None:
    cu, cv = uv[0] - 0.5, uv[1] - 0.5  # Pillow puts pixel centres on integers
    draw.ellipse((cu - r, cv - r, cu + r, cv + r), **kw)  # type: ignore[arg-type]


def map_image(state: MapState, values: np.ndarray | None = None,
              frontiers: Sequence[FrontierMark] = (), trajectory: Sequence[Pose2D] = (),
              target_xy: Sequence[float] | None = None, prompts: Sequence[PromptPoint] = (),
              scale: int = 4, crop_m: float | None = 1.0) -> np.ndarray:
    """(rows*scale, cols*scale, 3) uint8 top-down picture of ``state`` (north up), cut to what
    the map knows plus ``crop_m`` metres (None: the whole grid).

    Cells: unobserved dark grey, free light grey, explored free light green, occupied black;
    ``values`` (same shape as the grid) as a yellow-to-red heat overlay whose opacity grows with
    the value. Frontiers: blue dots sized by member count with a tick along the outward normal;
    trajectory: orange polyline ending in a red arrow (the last pose); target: magenta ring;
    prompt points: light grey lettered dots.
    """
    spec = state.spec
    cells = _cell_colours(state, values)[::-1]
    image = Image.fromarray(np.repeat(np.repeat(cells, scale, axis=0), scale, axis=1))
    draw = ImageDraw.Draw(image)
    px_per_m = scale / spec.resolution_m
    line_w = max(1, scale // 2)

    def at(xy: np.ndarray | Sequence[float]) -> np.ndarray:
        return world_to_image(spec, xy, scale)

    for f in frontiers:
        uv = at(f.xy)
        tip = at(np.asarray(f.xy) + 0.6 * np.asarray(f.normal))
        draw.line([tuple(uv - 0.5), tuple(tip - 0.5)], fill=FRONTIER, width=line_w)
        _disk(draw, uv, max(2.0, scale * (0.75 + 0.25 * math.sqrt(max(f.size, 1)))), fill=FRONTIER)
    if len(trajectory) > 1:
        pts = at(np.array([[p.x, p.y] for p in trajectory])) - 0.5
        draw.line([tuple(p) for p in pts], fill=TRAJECTORY, width=line_w, joint="curve")
    if trajectory:
        p = trajectory[-1]
        ahead, side = np.array([math.cos(p.yaw), math.sin(p.yaw)]), np.array(
            [-math.sin(p.yaw), math.cos(p.yaw)])
        corners = [p.xy + 0.4 * ahead, p.xy - 0.2 * ahead + 0.2 * side,
                   p.xy - 0.2 * ahead - 0.2 * side]
        draw.polygon([tuple(at(c) - 0.5) for c in corners], fill=ROBOT, outline=(0, 0, 0))
    if target_xy is not None:
        _disk(draw, at(target_xy), max(4.0, 0.4 * px_per_m), outline=TARGET, width=line_w + 1)
    radius = max(6.0, 0.3 * px_per_m)
    font = _font(int(radius * 1.4))
    for q in prompts:
        uv = at(q.xy)
        _disk(draw, uv, radius, fill=PROMPT, outline=(0, 0, 0), width=1)
        x0, y0, x1, y1 = draw.textbbox((0, 0), q.letter, font=font)
        draw.text((uv[0] - 0.5 - (x0 + x1) / 2, uv[1] - 0.5 - (y0 + y1) / 2), q.letter,
                  fill=(0, 0, 0), font=font)
    picture = np.asarray(image)
    if crop_m is not None:
        picture = picture[_known_window(state, trajectory, crop_m, scale)]
    return picture.copy()


def _known_window(state: MapState, trajectory: Sequence[Pose2D], margin_m: float,
                  scale: int) -> tuple[slice, slice]:
    """The image rows and columns of what the map knows (and the trajectory), plus
    ``margin_m``: the agent's map is a square around the start far larger than a house."""
    spec = state.spec
    rows, cols = np.nonzero(state.explored | state.free | state.occupied)
    if trajectory:
        i, j = spec.world_to_cell(np.array([[p.x, p.y] for p in trajectory]))
        rows, cols = np.concatenate([rows, np.ravel(i)]), np.concatenate([cols, np.ravel(j)])
    if rows.size == 0:
        return slice(None), slice(None)
    pad = math.ceil(margin_m / spec.resolution_m)
    n_rows, n_cols = spec.shape
    top = max(0, n_rows - 1 - int(rows.max()) - pad)  # the picture is north up: rows flipped
    bottom = min(n_rows, n_rows - int(rows.min()) + pad)
    left, right = max(0, int(cols.min()) - pad), min(n_cols, int(cols.max()) + 1 + pad)
    return slice(top * scale, bottom * scale), slice(left * scale, right * scale)
