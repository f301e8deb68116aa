"""A tiny built-in furniture set of coloured boxes and cylinders, for fast tests.

Same ``Catalog`` interface as the converted Sweet Home 3D models, no cache or Debian package
needed. Every model is in the canonical local frame: metres, z up, origin at the bottom centre of
its bounding box, front facing -y. Sizes are plausible real ones.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from efficienteqa.envs.synthetic.catalog import Catalog, CatalogEntry
from efficienteqa.envs.synthetic.colours import colour_name, mesh_colour
from efficienteqa.envs.synthetic.mesh import MeshPart, box_part

RGB = tuple[float, float, float]
WOOD: RGB = (0.45, 0.28, 0.14)
WHITE: RGB = (0.92, 0.92, 0.92)
BLACK: RGB = (0.05, 0.05, 0.05)
GREY: RGB = (0.5, 0.5, 0.5)


def cylinder_part(radius: float, height: float, colour: RGB,
                  bottom: tuple[float, float, float] = (0.0, 0.0, 0.0), segments: int = 16,
                  material: str = "") -> MeshPart:
    """A closed z-aligned cylinder (smooth sides, flat caps) standing on ``bottom`` (metres).

    ``segments`` should be a multiple of 4 so the bounding box is exactly 2r x 2r x height.
    """
    ang = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=1)
    b = np.asarray(bottom, np.float64)
    lo, hi = b + radius * ring, b + radius * ring + [0, 0, height]
    idx = np.arange(segments)
    nxt = (idx + 1) % segments
    # side: vertices [lo..., hi...] with outward radial normals; counter-clockwise from outside
    side_f = np.concatenate([np.stack([idx, nxt, segments + nxt], 1),
                             np.stack([idx, segments + nxt, segments + idx], 1)])
    positions = [lo, hi]
    normals = [ring, ring]
    faces = [side_f]
    for z_cap, sign in ((b[2], -1.0), (b[2] + height, 1.0)):  # caps as triangle fans
        base = sum(len(p) for p in positions)
        centre = np.array([[b[0], b[1], z_cap]])
        rim = (lo if sign < 0 else hi)
        positions += [centre, rim]
        normals += [np.tile([0.0, 0.0, sign], (segments + 1, 1))]
        fan = np.stack([np.zeros(segments, int), 1 + idx, 1 + nxt], 1) + base
        faces.append(fan if sign > 0 else fan[:, [0, 2, 1]])
    return MeshPart(positions=np.concatenate(positions).astype(np.float32),
                    normals=np.concatenate(normals).astype(np.float32),
                    faces=np.concatenate(faces).astype(np.uint32), colour=colour,
                    material=material)


def _box(w: float, d: float, h: float, colour: RGB, x: float = 0.0, y: float = 0.0,
         z: float = 0.0, material: str = "") -> MeshPart:
    """A box of size w x d x h whose bottom centre is at (x, y, z)."""
    return box_part((w, d, h), colour, (x, y, z + h / 2), material)


def _table(w: float, d: float, h: float, colour: RGB, top: float = 0.04) -> list[MeshPart]:
    leg, parts = 0.05, [_box(w, d, top, colour, z=h - top, material="top")]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(_box(leg, leg, h - top, colour, sx * (w - leg) / 2, sy * (d - leg) / 2,
                              material="legs"))
    return parts


def _seat(w: float, d: float, h: float, colour: RGB, seat: float, arms: bool) -> list[MeshPart]:
    """Sofa/armchair: base, back (at +y, the rear) and optional arms."""
    back, arm = 0.2, 0.15 if arms else 0.0
    parts = [_box(w, d, seat, colour, material="fabric"),
             _box(w, back, h, colour, y=(d - back) / 2, material="fabric")]
    if arms:
        for sx in (-1, 1):
            parts.append(_box(arm, d, seat + 0.2, colour, sx * (w - arm) / 2, material="fabric"))
    return parts


def _chair() -> list[MeshPart]:
    w, d, seat, h = 0.45, 0.5, 0.45, 0.9
    return _table(w, d, seat, WOOD, top=0.05) + [_box(w, 0.05, h - seat, WOOD, 0, (d - 0.05) / 2,
                                                      seat, material="back")]


def _tv() -> list[MeshPart]:
    w, d, h = 1.0, 0.1, 0.65
    return [_box(0.3, d, 0.03, BLACK, material="stand"),
            _box(0.06, 0.04, 0.05, BLACK, z=0.03, material="stand"),
            _box(w, 0.05, h - 0.08, BLACK, y=0.0, z=0.08, material="frame"),
            _box(w - 0.06, 0.005, h - 0.14, (0.1, 0.1, 0.12), y=-0.0275, z=0.11,
                 material="screen")]


def _floor_lamp() -> list[MeshPart]:
    return [cylinder_part(0.15, 0.03, BLACK, material="base"),
            cylinder_part(0.015, 1.3, BLACK, (0, 0, 0.03), material="pole"),
            cylinder_part(0.04, 0.08, (1.0, 0.95, 0.8), (0, 0, 1.33), material="bulb"),
            cylinder_part(0.2, 0.27, (0.87, 0.78, 0.6), (0, 0, 1.33), material="shade")]


def _toilet() -> list[MeshPart]:
    return [cylinder_part(0.19, 0.42, WHITE, (0, -0.12, 0), material="bowl"),
            _box(0.4, 0.2, 0.4, WHITE, y=0.22, z=0.4, material="tank"),
            _box(0.3, 0.3, 0.4, WHITE, y=0.05, material="base")]


def _plant() -> list[MeshPart]:
    return [cylinder_part(0.15, 0.3, (0.6, 0.3, 0.15), material="pot"),
            cylinder_part(0.2, 0.7, (0.15, 0.5, 0.15), (0, 0, 0.3), material="leaves")]


def _stove() -> list[MeshPart]:
    parts = [_box(0.6, 0.6, 0.88, WHITE, material="body")]
    for sx in (-1, 1):
        for sy in (-1, 1):
            parts.append(cylinder_part(0.09, 0.02, BLACK, (sx * 0.14, sy * 0.14, 0.88),
                                       material="burner"))
    return parts


def _shelves(w: float, d: float, h: float, colour: RGB, n: int) -> list[MeshPart]:
    t = 0.03
    parts = [_box(t, d, h, colour, sx * (w - t) / 2, material="side") for sx in (-1, 1)]
    parts.append(_box(w - 2 * t, t, h, colour, y=(d - t) / 2, material="back"))
    for i in range(n + 1):
        parts.append(_box(w - 2 * t, d - t, t, colour, y=-t / 2, z=i * (h - t) / n,
                          material="shelf"))
    return parts


# key -> (category, name, top_m, state_kind, builder)
_MODELS: dict[str, tuple[str, str, float | None, str | None, Callable[[], list[MeshPart]]]] = {
    "sofa": ("sofa", "Sofa", 0.45, None,
             lambda: _seat(2.0, 0.9, 0.85, (0.15, 0.3, 0.8), 0.45, True)),
    "armchair": ("armchair", "Armchair", 0.45, None,
                 lambda: _seat(0.9, 0.85, 0.85, (0.15, 0.6, 0.2), 0.45, True)),
    "chair": ("chair", "Chair", 0.45, None, _chair),
    "table": ("table", "Dining table", 0.75, None, lambda: _table(1.6, 0.9, 0.75, WOOD)),
    "coffee_table": ("coffee table", "Coffee table", 0.45, None,
                     lambda: _table(1.1, 0.6, 0.45, BLACK)),
    "bed": ("bed", "Bed", 0.55, None, lambda: [
        _box(1.6, 2.1, 0.35, WOOD, material="frame"),
        _box(1.55, 2.0, 0.2, WHITE, y=-0.05, z=0.35, material="mattress"),
        _box(1.6, 0.08, 0.9, WOOD, y=1.01, material="headboard")]),
    "nightstand": ("nightstand", "Nightstand", 0.55, None,
                   lambda: [_box(0.5, 0.45, 0.55, WOOD, material="body")]),
    "tv": ("tv", "TV", None, "tv", _tv),
    "tv_stand": ("tv stand", "TV stand", 0.5, None,
                 lambda: [_box(1.4, 0.45, 0.5, BLACK, material="body")]),
    "floor_lamp": ("floor lamp", "Floor lamp", None, "lamp", _floor_lamp),
    "refrigerator": ("refrigerator", "Refrigerator", None, None, lambda: [
        _box(0.7, 0.7, 1.8, WHITE, material="body"),
        _box(0.03, 0.03, 0.5, GREY, x=0.28, y=-0.365, z=1.1, material="handle")]),
    "stove": ("stove", "Stove", 0.9, None, _stove),
    "sink": ("sink", "Washbasin", 0.85, None, lambda: [
        cylinder_part(0.1, 0.7, WHITE, material="pedestal"),
        _box(0.6, 0.45, 0.15, WHITE, z=0.7, material="basin")]),
    "toilet": ("toilet", "Toilet", None, None, _toilet),
    "bathtub": ("bathtub", "Bathtub", None, None, lambda: [
        _box(1.7, 0.75, 0.6, WHITE, material="tub")]),
    "desk": ("desk", "Desk", 0.75, None, lambda: _table(1.4, 0.7, 0.75, (0.87, 0.78, 0.6))),
    "bookshelf": ("bookshelf", "Bookshelf", 0.9, None, lambda: _shelves(0.9, 0.35, 1.8, WOOD, 4)),
    "wardrobe": ("wardrobe", "Wardrobe", None, None, lambda: [
        _box(1.2, 0.6, 2.0, WHITE, material="body"),
        _box(0.02, 0.02, 0.3, GREY, x=0.05, y=-0.31, z=1.0, material="handle")]),
    "plant": ("plant", "Plant", None, None, _plant),
    "cup": ("cup", "Cup", None, None, lambda: [cylinder_part(0.04, 0.1, WHITE, material="cup")]),
    "book": ("book", "Book", None, None,
             lambda: [_box(0.15, 0.22, 0.03, (0.8, 0.1, 0.1), material="cover")]),
    "vase": ("vase", "Vase", None, None,
             lambda: [cylinder_part(0.075, 0.3, (0.15, 0.3, 0.8), material="vase")]),
}


def builtin_catalog() -> Catalog:
    """The built-in primitive furniture (keys "builtin/<name>", licence CC0-1.0)."""
    entries, meshes = [], {}
    for slug, (category, name, top, kind, build) in _MODELS.items():
        parts = build()
        pts = np.concatenate([p.positions for p in parts])
        lo, hi = pts.min(0), pts.max(0)
        # handles and tanks stick out: re-centre so the origin is the bbox's bottom centre
        shift = np.eye(4)
        shift[:3, 3] = [-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]]
        parts = [p.transformed(shift) for p in parts]
        size = tuple(round(float(v), 4) for v in hi - lo)
        state = {"tv": ("screen",), "lamp": ("bulb", "shade")}.get(kind or "", ())
        key = f"builtin/{slug}"
        entries.append(CatalogEntry(
            key=key, name=name, category=category, size_m=size,  # type: ignore[arg-type]
            licence="CC0-1.0", creator="efficienteqa", catalogue="builtin",
            colour=colour_name(mesh_colour(parts)), state_kind=kind, state_materials=state,
            top_m=top))
        meshes[key] = parts
    return Catalog(entries, meshes=meshes)
