"""Close reads: a second pass of the pixel network on crops centred on supports (DESIGN 9,
learned perception).

The network reads a 640x480 frame at half size and its heads run at a quarter (160x120), so a
cup of 30x30 pixels on a desk is 8x8 at the heads: missed, or named as the desk or as another
small thing. A close read crops the frame around a support the full pass sees (a table, a desk,
a counter, a shelf: ``SUPPORTS``), from ``rise_m`` above its top (where things standing on it
show) down to its bottom, and runs the same classifier on the crop resized to
``CloseReads.input_hw`` (as if that were a frame): the crop's things are ``zoom`` times larger
in the network's input than in the full pass. The depth channel is divided by the zoom: the
network learned sizes with depths, and a thing ``zoom`` times larger looks like one ``zoom``
times closer. A support too wide for ``min_zoom`` is read in tiles along its top.

Within the support and the rise above it, where the crop pass names a small object
(``SMALL``) with at least ``paste_min`` of confidence, and the full pass said background
(void, wall, floor), the support itself, or anything it was less sure of, the crop's
category, colour, state and confidence replace the full pass's; everything else stays the
full pass's. Regions, thresholds and the describer then read the classes as before. At most
``crops`` crops a frame, of supports within ``within_m`` whose region has ``min_pixels``,
nearest first.

It reads what the full pass reads (RGB, depth, and the camera's focal length to size the
rise) and nothing else. Numpy and scipy; torch only to resize the crop's RGB.

Chosen on validation houses 3900-3909 (``experiments/close_reads.py``; DESIGN 9 and
docs/perception.md give the sweep): small objects within 3 m found 65.3% -> 71.8%, all objects
found and right 72.4/68.6% -> 73.0/68.6%; pasting only over background and the support found
68.1%, a zoom of at least 1.4 about as many (72.3%) with fewer right, one crop 70.4%, three no
more than two.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import torch
import torch.nn.functional as F
from scipy import ndimage

from efficienteqa.envs.synthetic.vocabulary import SMALL_CATEGORIES, SURFACE_CATEGORIES
from efficienteqa.perception.pixels.segment import FLOOR_PREFIX, PixelClasses

SUPPORTS = SURFACE_CATEGORIES  # what small things stand on (the generator's surfaces)
SMALL = SMALL_CATEGORIES
OVER = ("background", "any")  # what a sure small object of a crop may replace (module doc)
Classifier = Callable[[np.ndarray, np.ndarray], PixelClasses]  # (rgb, depth_m) -> classes


@dataclass(frozen=True)
class CloseReads:
    """How close reads are made (module docstring); ``crops`` 0 is off."""

    crops: int = 2
    input_hw: tuple[int, int] = (240, 320)  # a crop's size as the classifier's frame
    within_m: float = 3.5  # supports whose median depth is at most this
    min_pixels: int = 120  # at half size: smaller support regions are not read again
    rise_m: float = 0.5  # the crop reaches this far above the support's top
    min_zoom: float = 2.0  # a wider support is read in tiles of this zoom along its top
    max_zoom: float = 3.0  # a crop that would zoom more takes in more around the support
    paste_min: float = 0.7  # the crop's confidence a small object's pixel needs
    scale_depth: bool = True
    over: str = "any"  # "background": only where the full pass said background or support

    def __post_init__(self) -> None:
        if self.crops < 0:
            raise ValueError(f"close reads need 0 or more crops, not {self.crops}")
        if not 1.0 <= self.min_zoom <= self.max_zoom:
            raise ValueError("close reads need 1 <= min_zoom <= max_zoom")
        if self.over not in OVER:
            raise ValueError(f"close reads paste over one of {OVER}, not {self.over!r}")


@dataclass(frozen=True)
class Crop:
    """A crop of the full frame: rows y0..y0+h, columns x0..x0+w (full-size pixels, even);
    ``box`` (top, bottom, left, right) the support and the rise above it, where pasting
    keeps."""

    y0: int
    x0: int
    h: int
    w: int
    box: tuple[int, int, int, int]

    def zoom(self, input_w: int) -> float:
        """How much larger the crop's things are in the classifier's input than in the full
        pass's (both halve their frame)."""
        return input_w / self.w


def support_crops(classes: PixelClasses, depth_m: np.ndarray, intrinsics: np.ndarray,
                  config: CloseReads) -> list[Crop]:
    """The crops to read again, nearest support first, at most ``config.crops``: one per
    support region in reach, or its tiles (a crop mostly inside one chosen is left out)."""
    if config.crops <= 0:
        return []
    small = classes.category
    sh, sw = small.shape
    h, w = depth_m.shape
    fy, fx = h // sh, w // sw
    depth = depth_m[fy // 2::fy, fx // 2::fx]
    names = list(classes.categories)
    ids = set(_ids(names, SUPPORTS))
    hin, win = config.input_hw
    widest = win / config.min_zoom
    found: list[tuple[float, Crop]] = []
    for k in (k for k in np.unique(small).tolist() if k in ids):
        regions, n = ndimage.label((small == k) & (depth > 0))
        sizes = np.bincount(regions.ravel(), minlength=n + 1)
        for r in np.flatnonzero(sizes >= config.min_pixels):
            if r == 0:
                continue
            rows, cols = np.nonzero(regions == r)
            d = float(np.median(depth[rows, cols]))
            if not 0 < d <= config.within_m:
                continue
            bottom, left, right = (rows.max() + 1) * fy, cols.min() * fx, (cols.max() + 1) * fx
            top = max(0, int(rows.min() * fy - float(intrinsics[1, 1]) * config.rise_m / d))
            tiles = max(1, int(np.ceil((right - left) / widest)))
            for t in range(tiles):
                a = left + (right - left) * t // tiles
                b = left + (right - left) * (t + 1) // tiles
                found.append((d, _fit((top, bottom, a, b), (h, w), (hin, win), config)))
    chosen: list[Crop] = []
    for _, crop in sorted(found, key=lambda dc: dc[0]):  # stable: tiles left to right
        if len(chosen) == config.crops:
            break
        if not any(_covered(crop, c) for c in chosen):
            chosen.append(crop)
    return chosen


def _fit(box: tuple[int, int, int, int], frame_hw: tuple[int, int], input_hw: tuple[int, int],
         config: CloseReads) -> Crop:
    """The crop of the classifier's aspect around ``box`` (top, bottom, left, right; full-size
    pixels): as small as the box within the zoom limits, inside the frame. A box taller than
    the crop keeps its top (where things stand)."""
    top, bottom, left, right = box
    (h, w), (hin, win) = frame_hw, input_hw
    aspect = win / hin
    cw = max(right - left, (bottom - top) * aspect, win / config.max_zoom)
    cw = min(cw, win / config.min_zoom, w, h * aspect)
    cw, ch = 2 * int(round(cw / 2)), 2 * int(round(cw / aspect / 2))
    cy = (top + bottom) / 2 if bottom - top <= ch else top + ch / 2
    x0 = int(np.clip(round((left + right) / 2 - cw / 2), 0, w - cw)) // 2 * 2
    y0 = int(np.clip(round(cy - ch / 2), 0, h - ch)) // 2 * 2
    return Crop(y0, x0, ch, cw, box)


def _covered(a: Crop, b: Crop) -> bool:
    """Most of ``a`` lies inside ``b``."""
    dy = max(0, min(a.y0 + a.h, b.y0 + b.h) - max(a.y0, b.y0))
    dx = max(0, min(a.x0 + a.w, b.x0 + b.w) - max(a.x0, b.x0))
    return dy * dx >= 0.6 * a.h * a.w


def read_crop(classify: Classifier, rgb: np.ndarray, depth_m: np.ndarray, crop: Crop,
              config: CloseReads) -> PixelClasses:
    """The classifier's classes of ``crop`` resized to ``config.input_hw`` (its frame size)."""
    hin, win = config.input_hw
    part = rgb[crop.y0:crop.y0 + crop.h, crop.x0:crop.x0 + crop.w]
    x = torch.from_numpy(np.ascontiguousarray(part)).permute(2, 0, 1)[None].float()
    x = F.interpolate(x, size=(hin, win), mode="bilinear", align_corners=False,
                      antialias=crop.h > hin)
    rgb_in = x[0].permute(1, 2, 0).round().clamp(0, 255).to(torch.uint8).numpy()
    rows = crop.y0 + ((np.arange(hin) + 0.5) * crop.h / hin).astype(np.int64)
    cols = crop.x0 + ((np.arange(win) + 0.5) * crop.w / win).astype(np.int64)
    depth_in = depth_m[np.ix_(rows, cols)]  # the nearest pixel's: no depth between two surfaces
    if config.scale_depth:
        depth_in = depth_in / crop.zoom(win)
    return classify(rgb_in, np.ascontiguousarray(depth_in, dtype=np.float32))


def paste(classes: PixelClasses, crop: Crop, read: PixelClasses, frame_hw: tuple[int, int],
          config: CloseReads) -> PixelClasses:
    """``classes`` (the full pass's) with the small objects ``read`` (the crop's classes)
    names surely pasted in, within the crop's box (module docstring)."""
    sh, sw = classes.category.shape
    fy, fx = frame_hw[0] // sh, frame_hw[1] // sw
    ch, cw = read.category.shape
    r0, r1 = crop.y0 // fy, (crop.y0 + crop.h) // fy
    c0, c1 = crop.x0 // fx, (crop.x0 + crop.w) // fx
    # the crop's class at the centre of each of the full pass's cells it covers
    y = (np.arange(r0, r1) + 0.5) * fy
    x = (np.arange(c0, c1) + 0.5) * fx
    at = np.ix_(np.clip(((y - crop.y0) * ch / crop.h).astype(np.int64), 0, ch - 1),
                np.clip(((x - crop.x0) * cw / crop.w).astype(np.int64), 0, cw - 1))
    names = list(classes.categories)
    category = read.category[at]
    sure = (read.confidence[at] if read.confidence is not None
            else np.ones(category.shape, np.float32))
    here = classes.category[r0:r1, c0:c1]
    top, bottom, left, right = crop.box
    inside = ((y >= top) & (y < bottom))[:, None] & ((x >= left) & (x < right))[None, :]
    under = np.isin(here, _ids(names, SUPPORTS) + [0, names.index("wall")] + [
        k for k, n in enumerate(names) if n.startswith(FLOOR_PREFIX)])
    if config.over == "any" and classes.confidence is not None:
        under |= classes.confidence[r0:r1, c0:c1] < sure
    take = np.isin(category, _ids(names, SMALL)) & (sure >= config.paste_min) & inside & under
    if not take.any():
        return classes
    out = {}
    for name in ("category", "colour", "state"):
        values = getattr(classes, name).copy()
        values[r0:r1, c0:c1][take] = getattr(read, name)[at][take]
        out[name] = values
    confidence = classes.confidence
    if confidence is not None:
        confidence = confidence.copy()
        confidence[r0:r1, c0:c1][take] = sure[take]
    return replace(classes, confidence=confidence, **out)


def _ids(names: Sequence[str], wanted: frozenset[str]) -> list[int]:
    return [k for k, n in enumerate(names) if n in wanted]


def close_read(classify: Classifier, classes: PixelClasses, rgb: np.ndarray,
               depth_m: np.ndarray, intrinsics: np.ndarray, config: CloseReads
               ) -> tuple[PixelClasses, list[Crop]]:
    """The full pass's ``classes`` with the close reads of up to ``config.crops`` crops
    pasted in, and the crops read."""
    crops = support_crops(classes, depth_m, intrinsics, config)
    for crop in crops:
        read = read_crop(classify, rgb, depth_m, crop, config)
        classes = paste(classes, crop, read, depth_m.shape, config)
    return classes, crops
