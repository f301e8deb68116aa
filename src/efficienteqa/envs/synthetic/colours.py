"""Colour names of furniture and recolouring for one-clear-answer colour questions."""

from __future__ import annotations

import colorsys
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import numpy.typing as npt

from efficienteqa.envs.synthetic.mesh import MeshPart, rgb3

PALETTE: dict[str, tuple[float, float, float]] = {
    "white": (0.92, 0.92, 0.92), "black": (0.05, 0.05, 0.05), "grey": (0.5, 0.5, 0.5),
    "brown": (0.45, 0.28, 0.14), "beige": (0.87, 0.78, 0.6), "red": (0.8, 0.1, 0.1),
    "orange": (0.95, 0.55, 0.1), "yellow": (0.95, 0.85, 0.15), "green": (0.15, 0.6, 0.2),
    "blue": (0.15, 0.3, 0.8), "purple": (0.5, 0.2, 0.65), "pink": (0.95, 0.6, 0.75),
}


def colour_name(rgb: Sequence[float]) -> str:
    """Name an RGB in [0, 1] with one word of PALETTE (HSV rules, tuned for furniture)."""
    h, s, v = colorsys.rgb_to_hsv(*(float(np.clip(c, 0.0, 1.0)) for c in rgb[:3]))
    hue = h * 360
    if v < 0.2:
        return "black"
    if s < 0.15 or (s < 0.25 and v < 0.45):
        return "white" if v > 0.8 else "grey"
    if 15 <= hue < 50 and s < 0.5 and v >= 0.6:
        return "beige"  # pale warm tones: light wood, cream, sand
    if 10 <= hue < 70 and v < 0.6:
        return "brown"  # dark orange/yellow is what wood and leather look like
    if hue < 15 or hue >= 340:
        return "pink" if s < 0.5 and v > 0.7 else "red"
    if hue < 45:
        return "orange"
    if hue < 70:
        return "yellow"
    if hue < 170:
        return "green"
    if hue < 260:
        return "blue"
    if hue < 300:
        return "purple"
    return "pink" if v > 0.5 else "purple"


def part_mean_rgb(part: MeshPart) -> npt.NDArray[np.float64]:
    rgb = np.asarray(part.colour, np.float64)
    if part.texture is not None:  # Kd multiplies the texture
        rgb = rgb * part.texture[..., :3].reshape(-1, 3).mean(0) / 255.0
    return rgb


def _dominant(parts: Sequence[MeshPart], share: float = 0.6) -> list[int]:
    """Indices of the largest parts that together cover at least ``share`` of the area."""
    areas = np.array([p.area_m2 for p in parts])
    order, total, chosen = np.argsort(-areas), areas.sum(), []
    for i in order:
        chosen.append(int(i))
        if areas[chosen].sum() >= share * total:
            break
    return chosen


def mesh_colour(parts: Sequence[MeshPart]) -> tuple[float, float, float]:
    """Area-weighted mean RGB of the dominant parts (those covering >= 60 % of the surface)."""
    idx = _dominant(parts)
    w = np.array([parts[i].area_m2 for i in idx]) + 1e-12
    rgb = sum(wi * part_mean_rgb(parts[i]) for wi, i in zip(w, idx, strict=True)) / w.sum()
    return rgb3(rgb)


def recoloured(parts: Sequence[MeshPart], rgb: Sequence[float]) -> list[MeshPart]:
    """Copies of ``parts`` with the dominant parts tinted to ``rgb`` (others unchanged)."""
    target = np.clip(np.asarray(rgb[:3], np.float64), 0, 1)
    out = list(parts)
    for i in _dominant(parts):
        p = parts[i]
        if p.texture is None:
            out[i] = replace(p, colour=rgb3(target))
            continue
        # keep the texture's detail as luminance with mean 0.85 (Kd = rgb / 0.85 restores the
        # target); contrast is reduced just enough that no texel clips at 1
        lum = p.texture[..., :3].astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)
        rel = lum / max(float(lum.mean()), 1.0) - 1.0
        k = min(1.0, (1 / 0.85 - 1) / max(float(rel.max()), 1e-6))
        lum = np.clip(0.85 * 255 * (1 + k * rel), 0, 255).astype(np.uint8)
        out[i] = replace(p, texture=np.repeat(lum[..., None], 3, axis=2),
                         colour=rgb3(np.clip(target / 0.85, 0, 1)))
    return out
