"""Reading a Sweet Home 3D furniture package (``*.sh3f``): its properties, licence and pieces.

A package is a zip of OBJ+MTL models plus a Java ``PluginFurnitureCatalog.properties`` that
lists each piece's name, size, elevation and model path. This module reads that listing and
chooses the house-worthy pieces and their stable keys; it touches no mesh, so it is apart from
the model conversion (``obj_model.py``) and the cached catalogue (``catalog.py``).
"""

from __future__ import annotations

import re
import zipfile
from pathlib import Path

from efficienteqa.envs.synthetic.vocabulary import (
    EXCLUDED_SOURCE_CATEGORIES,
    SMALL_CATEGORIES,
    SURFACE_CATEGORIES,
    canonical_category,
)

PROPERTIES = "PluginFurnitureCatalog.properties"
_PREFIX = {"BlendSwap-CC-0": "cc0", "BlendSwap-CC-BY": "ccby"}


def parse_properties(text: str) -> tuple[dict[str, str], dict[int, dict[str, str]]]:
    """Java .properties -> (header keys, {N: {key: value}} for ``key#N`` lines)."""
    header: dict[str, str] = {}
    pieces: dict[int, dict[str, str]] = {}
    text = re.sub(r"\\\r?\n[ \t]*", "", text)  # line continuations
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line[0] in "#!":
            continue
        m = re.match(r"([^=:\s]+)\s*[=:\s]\s*(.*)$", line)
        if not m:
            continue
        key, value = m[1], re.sub(r"\\u([0-9a-fA-F]{4})", lambda u: chr(int(u[1], 16)), m[2])
        value = value.replace("\\:", ":").replace("\\=", "=").replace("\\\\", "\\")
        km = re.fullmatch(r"(\w+)#(\d+)", key)
        if km:
            pieces.setdefault(int(km[2]), {})[km[1]] = value
        else:
            header[key] = value
    return header, pieces


def licence_of(header: dict[str, str]) -> str:
    """The SPDX id of a package's licence (from its header keys), or "unknown"."""
    text = header.get("license", "").lower()
    if "public domain" in text or "cc-0" in text or "cc0" in text:
        return "CC0-1.0"
    if "attribution 3.0" in text:
        return "CC-BY-3.0"
    return "unknown"


def _slug(text: str) -> str:
    text = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", text)  # largeFridge -> large_Fridge
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_") or "model"


def key_prefix(zip_path: Path) -> str:
    """The first part of the keys of a package's entries ("cc0", "ccby", else its name)."""
    return _PREFIX.get(zip_path.stem, _slug(zip_path.stem))


def piece_size_m(piece: dict[str, str]) -> tuple[float, float, float]:
    """(width, depth, height) in metres (the properties give centimetres)."""
    width, depth, height = (round(float(piece[k]) / 100, 5) for k in ("width", "depth", "height"))
    return width, depth, height


def entry_fields(category: str, piece: dict[str, str]) -> dict:
    """Per-piece fields that do not need the mesh: top_m, elevation_m."""
    height = float(piece["height"])
    top = None
    drop = piece.get("dropOnTopElevation")
    if category not in SMALL_CATEGORIES:
        if drop not in (None, ""):
            # small or negative values mean "drop inside" (bins, boxes) or "nothing on top"
            if float(drop) >= max(5.0, 0.2 * height):
                top = round(float(drop) / 100, 4)
        elif category in SURFACE_CATEGORIES:
            top = round(height / 100, 4)
    return {"top_m": top, "elevation_m": round(float(piece.get("elevation") or 0) / 100, 4)}


def plan_catalogue(zip_path: Path) -> tuple[str, list[tuple[str, dict, str]]]:
    """(licence, [(key, piece, category)]) for the house-worthy pieces of one catalogue."""
    with zipfile.ZipFile(zip_path) as zf:
        header, pieces = parse_properties(zf.read(PROPERTIES).decode("latin-1"))
    prefix = key_prefix(zip_path)
    plan, seen = [], set()
    for _, piece in sorted(pieces.items()):
        if piece.get("category") in EXCLUDED_SOURCE_CATEGORIES or piece.get("doorOrWindow") \
                == "true" or not piece.get("model") or "name" not in piece:
            continue
        try:
            height_m = float(piece["height"]) / 100
            elev_m = float(piece.get("elevation") or 0) / 100
        except (KeyError, ValueError):
            continue
        category = canonical_category(piece["name"], height_m, elev_m)
        if category is None:
            continue
        # the model's folder name is stable across package versions, unlike the piece number
        model_dir = piece["model"].strip("/").split("/")[-2:][0].removesuffix(".obj")
        base = f"{prefix}/{_slug(model_dir)}"
        key, n = base, 2
        while key in seen:
            key, n = f"{base}_{n}", n + 1
        seen.add(key)
        plan.append((key, piece, category))
    return licence_of(header), plan
