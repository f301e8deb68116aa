"""Procedural floor and wall textures: numpy only, deterministic by seed, seamlessly tileable.

Every texture is (SIZE, SIZE, 3) uint8 RGB (sRGB-ish). Noise is made by low-pass filtering white
noise in the Fourier domain, which makes it periodic over the image, and every pattern (planks,
tiles, slabs) has a period that divides SIZE, so the images tile without seams. The house
builder maps them with UVs in metres; one tile is meant to cover about 1-2 m.
"""

from __future__ import annotations

import numpy as np

SIZE = 256
FLOOR_KINDS = ("wood", "tiles", "carpet", "stone")


def _noise(rng: np.random.Generator, scale_px: tuple[float, float]) -> np.ndarray:
    """Periodic Gaussian-filtered noise, (SIZE, SIZE) float in [0, 1].

    scale_px: (along rows = y, along columns = x) feature size in pixels; unequal values
    stretch the noise (wood grain).
    """
    freq = np.fft.fftfreq(SIZE)
    fy, fx = np.meshgrid(freq, freq, indexing="ij")
    sy, sx = (2 * np.pi * s for s in scale_px)
    gain = np.exp(-0.5 * ((fy * sy) ** 2 + (fx * sx) ** 2))
    field = np.real(np.fft.ifft2(np.fft.fft2(rng.standard_normal((SIZE, SIZE))) * gain))
    field -= field.min()
    return field / max(float(field.max()), 1e-9)


def _to_uint8(rgb: np.ndarray) -> np.ndarray:
    return np.clip(np.round(rgb * 255.0), 0, 255).astype(np.uint8)


def _shade(base: tuple[float, float, float], value: np.ndarray) -> np.ndarray:
    """Multiply a base RGB colour (0-1) by a per-pixel brightness (H, W)."""
    return value[..., None] * np.asarray(base, np.float64)


def _wood(rng: np.random.Generator) -> np.ndarray:
    palettes = [(0.62, 0.42, 0.25), (0.72, 0.55, 0.36), (0.48, 0.31, 0.19), (0.80, 0.66, 0.47)]
    base = palettes[rng.integers(len(palettes))]
    rows = 8  # plank width SIZE / rows px; planks run along x
    plank_h = SIZE // rows
    y = np.arange(SIZE)[:, None]
    x = np.arange(SIZE)[None, :]
    row = np.broadcast_to(y // plank_h, (SIZE, SIZE))
    # Two planks per row with a staggered joint; the column index wraps, so the tile repeats.
    offsets = rng.integers(0, SIZE, rows)
    shifted = (x + offsets[row]) % SIZE
    plank = row * 2 + shifted // (SIZE // 2)
    tone = 0.8 + 0.35 * rng.random(rows * 2)
    grain = _noise(rng, (1.5, 40.0))
    rings = 0.5 + 0.5 * np.sin(2 * np.pi * (y / 9.0 + 3.0 * _noise(rng, (6.0, 60.0))))
    value = tone[plank] * (0.78 + 0.14 * grain + 0.10 * rings)
    gap = (y % plank_h == 0) | (shifted % (SIZE // 2) == 0)
    value = np.where(gap, value * 0.45, value)
    return _to_uint8(_shade(base, value))


def _tiles(rng: np.random.Generator) -> np.ndarray:
    palettes = [(0.92, 0.92, 0.90), (0.86, 0.80, 0.70), (0.70, 0.76, 0.82), (0.80, 0.80, 0.80)]
    base = palettes[rng.integers(len(palettes))]
    n = 4  # tiles per side
    size = SIZE // n
    y, x = np.mgrid[0:SIZE, 0:SIZE]
    tile = (y // size) * n + x // size
    tone = 0.93 + 0.07 * rng.random(n * n)
    value = tone[tile] * (0.94 + 0.06 * _noise(rng, (2.0, 2.0)))
    # A soft highlight gradient per tile reads as a glazed surface.
    value *= 1.0 - 0.05 * ((x % size) / size + (y % size) / size)
    grout = ((x % size) < 3) | ((y % size) < 3)
    rgb = _shade(base, value)
    rgb[grout] = np.asarray((0.45, 0.43, 0.40)) * (0.9 + 0.1 * rng.random())
    return _to_uint8(rgb)


def _carpet(rng: np.random.Generator) -> np.ndarray:
    palettes = [(0.55, 0.20, 0.20), (0.30, 0.38, 0.55), (0.62, 0.58, 0.50), (0.35, 0.45, 0.33)]
    base = palettes[rng.integers(len(palettes))]
    fibre = rng.random((SIZE, SIZE))
    value = 0.75 + 0.12 * _noise(rng, (12.0, 12.0)) + 0.08 * _noise(rng, (1.0, 1.0)) + 0.05 * fibre
    return _to_uint8(_shade(base, value))


def _stone(rng: np.random.Generator) -> np.ndarray:
    palettes = [(0.72, 0.70, 0.66), (0.58, 0.56, 0.55), (0.78, 0.72, 0.62), (0.45, 0.47, 0.50)]
    base = palettes[rng.integers(len(palettes))]
    size = SIZE // 2  # 2 x 2 large slabs, rows offset by half a slab
    y, x = np.mgrid[0:SIZE, 0:SIZE]
    row = y // size
    sx = (x + row * (size // 2)) % SIZE
    slab = row * 2 + sx // size
    tone = 0.85 + 0.2 * rng.random(4)
    mottle = _noise(rng, (10.0, 10.0))
    veins = np.abs(np.sin(2 * np.pi * (x + y) / SIZE * 2 + 8.0 * _noise(rng, (18.0, 18.0))))
    value = tone[slab] * (0.82 + 0.13 * mottle + 0.08 * veins ** 8)
    joint = ((sx % size) < 2) | ((y % size) < 2)
    value = np.where(joint, 0.5, value)
    return _to_uint8(_shade(base, value))


_FLOORS = {"wood": _wood, "tiles": _tiles, "carpet": _carpet, "stone": _stone}


def floor_texture(kind: str, seed: int) -> np.ndarray:
    """A tileable (256, 256, 3) uint8 floor texture of ``kind`` (one of ``FLOOR_KINDS``).

    wood: 8 planks per tile with staggered joints, grain and per-plank tone; tiles: 4 x 4
    ceramic tiles with grout; carpet: soft fibrous noise; stone: 2 x 2 large slabs with veins.
    The palette and pattern depend only on ``seed``.
    """
    if kind not in _FLOORS:
        raise ValueError(f"unknown floor kind {kind!r}; choose one of {FLOOR_KINDS}")
    return _FLOORS[kind](np.random.default_rng(seed))


def wall_texture(seed: int) -> np.ndarray:
    """A tileable (256, 256, 3) uint8 plaster texture: near white, subtle low-contrast noise.

    Meant to be multiplied by the wall's ``colour``.
    """
    rng = np.random.default_rng(seed)
    value = 0.88 + 0.06 * _noise(rng, (20.0, 20.0)) + 0.04 * _noise(rng, (1.2, 1.2))
    return _to_uint8(np.repeat(value[..., None], 3, axis=2))
