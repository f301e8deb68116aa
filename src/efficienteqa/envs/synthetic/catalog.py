"""Furniture catalogue: Sweet Home 3D models converted once to metre-scaled meshes.

Source: Debian ``sweethome3d-furniture`` (``*.sh3f`` zips of OBJ+MTL models with a Java
``PluginFurnitureCatalog.properties``). Each model is converted to the canonical local frame
(metres, z up, origin at the bottom centre of its bounding box, front facing -y) and cached under
``cache_dir("furniture", CACHE_VERSION)/<catalogue>/``: an ``index.json`` plus one ``.npz`` per
model holding ``colours`` (P, 3), ``materials`` (P,) and per part i ``p{i}_positions``,
``p{i}_normals`` (float32), ``p{i}_faces`` (uint32), optional ``p{i}_uvs`` (OBJ convention:
v = 0 at the image bottom) and ``p{i}_texture`` ((h, w, 3) uint8, top row first, <= 256 px).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import time
import warnings
import zipfile
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from io import BytesIO
from pathlib import Path

import numpy as np
import numpy.typing as npt

from efficienteqa.cache import cache_dir
from efficienteqa.envs.synthetic.colours import colour_name, mesh_colour, part_mean_rgb
from efficienteqa.envs.synthetic.decimate import decimate
from efficienteqa.envs.synthetic.mesh import MeshPart, rgb3
from efficienteqa.envs.synthetic.vocabulary import (
    EXCLUDED_SOURCE_CATEGORIES,
    LAMP_CATEGORIES,
    SMALL_CATEGORIES,
    SURFACE_CATEGORIES,
    canonical_category,
)
from efficienteqa.errors import EfficientEQAError

CACHE_VERSION = "v2"  # bump when the npz/index format or the conversion changes
MAX_TRIANGLES = 8000  # per model: a 640x480 frame shows no more detail (see decimate.py)
DEFAULT_SOURCE = "/usr/share/sweethome3d/furniture"
TEXTURE_MAX_PX = 256


_TV_MATERIAL = re.compile(r"screen|display|monitor|lcd", re.I)
# ("lamp" itself is too loose: Scopia names every material "..._multilamps")
_LAMP_MATERIAL = re.compile(r"bulb|glass|shade|light|emi[st]|paper|pantalla|cristal|frosted", re.I)


@dataclass(frozen=True)
class CatalogEntry:
    """One model. size_m = (width x, depth y, height z) in metres in the canonical local frame.

    top_m: height (m, above the model's base) of the surface small objects stand on, or None.
    elevation_m: suggested height of the model's base above the floor (wall/ceiling mounted > 0).
    """

    key: str
    name: str
    category: str
    size_m: tuple[float, float, float]
    licence: str
    creator: str
    catalogue: str
    colour: str = "grey"
    state_kind: str | None = None
    state_materials: tuple[str, ...] = ()
    top_m: float | None = None
    elevation_m: float = 0.0


# --- properties and OBJ/MTL parsing ----------------------------------------------------------
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


def _licence(header: dict[str, str]) -> str:
    text = header.get("license", "").lower()
    if "public domain" in text or "cc-0" in text or "cc0" in text:
        return "CC0-1.0"
    if "attribution 3.0" in text:
        return "CC-BY-3.0"
    return "unknown"


def _parse_mtl(text: str) -> dict[str, dict]:
    mats: dict[str, dict] = {}
    cur: dict = {}
    for line in text.splitlines():
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "newmtl":
            cur = mats.setdefault(" ".join(tok[1:]), {"Kd": (0.8, 0.8, 0.8), "map": None})
        elif tok[0] == "Kd" and len(tok) >= 4:
            cur["Kd"] = tuple(float(x) for x in tok[1:4])
        elif tok[0] == "map_Kd" and len(tok) >= 2:
            cur["map"] = tok[-1]  # options (-s, -o ...) come first; the file name is last
    return mats


def _read_texture(zf: zipfile.ZipFile, folder: str, name: str) -> np.ndarray | None:
    """The texture as (h, w, 3) uint8 <= TEXTURE_MAX_PX, or None if missing/unreadable."""
    from PIL import Image

    wanted = (folder + name.replace("\\", "/")).lower()
    match = next((n for n in zf.namelist() if n.lower() == wanted), None)
    if match is None:
        return None
    try:
        img = Image.open(BytesIO(zf.read(match))).convert("RGB")
    except Exception:  # odd formats (tif variants...): the part keeps its Kd colour
        return None
    img.thumbnail((TEXTURE_MAX_PX, TEXTURE_MAX_PX))
    return np.asarray(img, np.uint8).copy()


_Floats = npt.NDArray[np.float64]


def _parse_obj(text: str) -> tuple[_Floats, _Floats, _Floats, dict[str, npt.NDArray[np.int64]],
                                   list[str]]:
    """-> positions (V, 3), uvs (T, 2), normals (N, 3), {material: [corner rows]}, mtllibs.

    Corner rows are (face, v, vt, vn) with 0-based indices and -1 where absent; polygons are
    fan-triangulated so every 3 consecutive rows form a triangle.
    """
    vs: list[list[str]] = []
    vts: list[list[str]] = []
    vns: list[list[str]] = []
    libs: list[str] = []
    groups: dict[str, list[tuple[int, ...]]] = {}
    rows = groups.setdefault("", [])
    nface = 0
    for line in text.splitlines():
        if line.startswith("v "):
            vs.append(line.split()[1:4])
        elif line.startswith("vt"):
            vts.append((line.split()[1:3] + ["0"])[:2])
        elif line.startswith("vn"):
            vns.append(line.split()[1:4])
        elif line.startswith("f "):
            corners: list[list[int]] = []
            now = (len(vs), len(vts), len(vns))
            for token in line.split()[1:]:
                idx = [int(x) if x else 0 for x in (token.split("/") + ["", ""])[:3]]
                corners.append([x + n + 1 if x < 0 else x for x, n in zip(idx, now, strict=True)])
            for k in range(1, len(corners) - 1):  # fan
                for corner in (corners[0], corners[k], corners[k + 1]):
                    rows.append((nface, *corner))
                nface += 1
        elif line.startswith("usemtl"):
            rows = groups.setdefault(line[6:].strip(), [])
        elif line.startswith("mtllib"):
            libs.append(line[6:].strip())
    arrays = [np.array(a, np.float64).reshape(-1, w) for a, w in ((vs, 3), (vts, 2), (vns, 3))]
    counts = [len(a) for a in arrays]
    out: dict[str, npt.NDArray[np.int64]] = {}
    for mat, r in groups.items():
        if not r:
            continue
        a = np.array(r, np.int64)
        a[:, 1:] -= 1  # OBJ indices are 1-based; 0 (absent) becomes -1
        if (a[:, 1:] >= np.array(counts)).any() or (a[:, 1] < 0).any():
            raise ValueError(f"face index out of range in material {mat!r}")
        out[mat] = a
    return arrays[0], arrays[1], arrays[2], out, libs


# --- one model -> canonical mesh parts -------------------------------------------------------
_OBJ_TO_LOCAL = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], np.float64)  # (x, y, z) -> (x, -z, y)


def _slug(text: str) -> str:
    text = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", text)  # largeFridge -> large_Fridge
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_") or "model"


def _size_m(piece: dict[str, str]) -> tuple[float, float, float]:
    width, depth, height = (round(float(piece[k]) / 100, 5) for k in ("width", "depth", "height"))
    return width, depth, height


def convert_model(zf: zipfile.ZipFile, piece: dict[str, str]) -> list[MeshPart]:
    """One catalogue piece as MeshParts in the canonical local frame (see module docstring).

    The model's bounding box (after modelRotation) is scaled to exactly width x height x depth
    (OBJ x, y, z), put on z = 0 and centred in x and y. Raises on unreadable input.
    """
    model = piece["model"].lstrip("/")
    folder = model.rsplit("/", 1)[0] + "/" if "/" in model else ""
    pos, uv, nrm, groups, libs = _parse_obj(zf.read(model).decode("utf-8", "replace"))
    mats: dict[str, dict] = {}
    for lib in libs:
        with contextlib.suppress(KeyError):  # a missing .mtl leaves every part default grey
            mats.update(_parse_mtl(zf.read(folder + lib).decode("utf-8", "replace")))
    if not groups:
        raise ValueError("model has no faces")
    rot = np.eye(3)
    if piece.get("modelRotation"):
        rot = np.array([float(x) for x in piece["modelRotation"].split()]).reshape(3, 3)
    used = np.unique(np.concatenate([a[:, 1] for a in groups.values()]))
    p = pos @ rot.T
    lo, hi = p[used].min(0), p[used].max(0)
    w, d, h = _size_m(piece)
    scale = np.array([w, h, d]) / np.maximum(hi - lo, 1e-9)  # bbox -> catalogue size (OBJ axes)
    origin = np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])
    local = ((p - origin) * scale) @ _OBJ_TO_LOCAL.T
    normal_matrix = _OBJ_TO_LOCAL @ np.diag(1 / scale) @ np.linalg.inv(rot).T
    local_n = nrm @ normal_matrix.T if len(nrm) else nrm
    textures: dict[str, np.ndarray | None] = {}
    parts = []
    for name, rows in groups.items():
        mat = mats.get(name, {"Kd": (0.8, 0.8, 0.8), "map": None})
        face = rows[:, 0]
        # one vertex per distinct (v, vt, vn); corners without a normal get a per-face key
        keys = rows[:, 1:].copy()
        keys[:, 2] = np.where(keys[:, 2] >= 0, keys[:, 2], -2 - face)
        uniq, inv = np.unique(keys, axis=0, return_inverse=True)
        faces = inv.reshape(-1, 3).astype(np.uint32)
        verts = local[uniq[:, 0]]
        tri = verts[faces]
        fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        vn = np.zeros_like(verts)
        flat = uniq[:, 2] < 0
        vn[faces.ravel()] = np.repeat(fn, 3, axis=0)  # flat normals where OBJ has none
        if (~flat).any():
            vn[~flat] = local_n[uniq[~flat, 2]]
        length = np.linalg.norm(vn, axis=1, keepdims=True)
        vn = np.where(length > 1e-12, vn / np.maximum(length, 1e-12), [0.0, 0.0, 1.0])
        tex, uvs = None, None
        if mat["map"] and (uniq[:, 1] >= 0).any():
            if mat["map"] not in textures:
                textures[mat["map"]] = _read_texture(zf, folder, mat["map"])
            tex = textures[mat["map"]]
            if tex is not None:
                uvs = np.where(uniq[:, 1:2] >= 0, uv[np.maximum(uniq[:, 1], 0)], 0.0)
        part = MeshPart(positions=verts.astype(np.float32), normals=vn.astype(np.float32),
                        faces=faces, colour=rgb3(mat["Kd"]),
                        uvs=None if uvs is None else uvs.astype(np.float32), texture=tex,
                        material=name)
        if part.area_m2 > 0:
            parts.append(part)
    if not parts:
        raise ValueError("model has no visible triangles")
    return parts


def _state_materials(category: str, parts: list[MeshPart]) -> tuple[str, ...]:
    """Materials that light up when the object is on: a TV's screen; a lamp's bulbs/shades."""
    if category == "tv":
        return tuple(p.material for p in parts if _TV_MATERIAL.search(p.material))
    if category not in LAMP_CATEGORIES:
        return ()
    names = {p.material for p in parts if _LAMP_MATERIAL.search(p.material)}
    if not names and len(parts) > 1:
        # no telling name: the shade/bulb is usually the lightest material (checked on the CC0
        # lamps; the catalogue's light-source points sit inside metal bodies as often as not)
        lum = [float(part_mean_rgb(p) @ [0.299, 0.587, 0.114]) for p in parts]
        names = {parts[int(np.argmax(lum))].material}
    return tuple(sorted(names))


def _entry_fields(category: str, piece: dict[str, str]) -> dict:
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


def _save_parts(path: Path, parts: list[MeshPart]) -> None:
    arrays: dict[str, np.ndarray] = {
        "colours": np.array([p.colour for p in parts], np.float32),
        "materials": np.array([p.material for p in parts], dtype=str),
    }
    for i, p in enumerate(parts):
        arrays.update({f"p{i}_positions": p.positions, f"p{i}_normals": p.normals,
                       f"p{i}_faces": p.faces})
        if p.uvs is not None and p.texture is not None:
            arrays.update({f"p{i}_uvs": p.uvs, f"p{i}_texture": p.texture})
    np.savez_compressed(path, allow_pickle=False, **arrays)


def _load_parts(path: Path) -> list[MeshPart]:
    with np.load(path, allow_pickle=False) as z:
        parts = []
        for i, (colour, mat) in enumerate(zip(z["colours"], z["materials"], strict=True)):
            has_tex = f"p{i}_texture" in z.files
            parts.append(MeshPart(
                positions=z[f"p{i}_positions"], normals=z[f"p{i}_normals"],
                faces=z[f"p{i}_faces"], colour=rgb3(colour),
                uvs=z[f"p{i}_uvs"] if has_tex else None,
                texture=z[f"p{i}_texture"] if has_tex else None, material=str(mat)))
    return parts


def _convert_job(job: tuple[str, str, dict, str, str, str]) -> dict:
    """Worker: convert one piece, write its npz; return its entry fields or an error."""
    zip_path, key, piece, category, licence, out = job
    try:
        with zipfile.ZipFile(zip_path) as zf:
            parts = decimate(convert_model(zf, piece), MAX_TRIANGLES)
        _save_parts(Path(out), parts)
        kind = "tv" if category == "tv" else "lamp" if category in LAMP_CATEGORIES else None
        state = _state_materials(category, parts)
        entry = CatalogEntry(
            key=key, name=piece["name"], category=category, size_m=_size_m(piece),
            licence=licence, creator=piece.get("creator", "unknown"),
            catalogue=Path(zip_path).stem, colour=colour_name(mesh_colour(parts)),
            state_kind=kind if state else None, state_materials=state,
            **_entry_fields(category, piece))
        return {"entry": asdict(entry)}
    except Exception as exc:  # one broken model must never stop the conversion
        return {"skipped": [key, f"{type(exc).__name__}: {exc}"]}


# --- the catalogue ---------------------------------------------------------------------------
class Catalog:
    """Entries plus lazily loaded, memoised meshes (from npz files or given in memory)."""

    def __init__(self, entries: Iterable[CatalogEntry], meshes: dict[str, list[MeshPart]] | None
                 = None, files: dict[str, Path] | None = None,
                 skipped: Sequence[tuple[str, str]] = ()) -> None:
        self.entries: list[CatalogEntry] = list(entries)
        self._by_key = {e.key: e for e in self.entries}
        self._files = dict(files or {})
        self._meshes: dict[str, list[MeshPart]] = {}
        for key, parts in (meshes or {}).items():
            self._meshes[key] = [_frozen(p) for p in parts]
        self.skipped: list[tuple[str, str]] = list(skipped)

    def categories(self) -> list[str]:
        return sorted({e.category for e in self.entries})

    def without(self, keys: Iterable[str]) -> Catalog:
        """The catalogue less the entries ``keys`` (held-out meshes); meshes stay shared."""
        drop = set(keys)
        out = Catalog([e for e in self.entries if e.key not in drop],
                      files={k: f for k, f in self._files.items() if k not in drop},
                      skipped=self.skipped)
        out._meshes = {k: m for k, m in self._meshes.items() if k not in drop}
        return out

    def by_category(self, category: str) -> list[CatalogEntry]:
        return [e for e in self.entries if e.category == category]

    def entry(self, key: str) -> CatalogEntry:
        if key not in self._by_key:
            raise KeyError(f"no catalogue entry {key!r}")
        return self._by_key[key]

    def mesh(self, key: str) -> list[MeshPart]:
        """The model's parts in its local frame (instance_id 0). Arrays are read-only; the
        MeshPart objects are fresh, so ``dataclasses.replace`` / ``recoloured`` are safe."""
        if key not in self._meshes:
            self.entry(key)
            self._meshes[key] = [_frozen(p) for p in _load_parts(self._files[key])]
        return [replace(p) for p in self._meshes[key]]

    def attribution(self, keys: Iterable[str]) -> str:
        """Markdown lines crediting the CC-BY models among ``keys`` (empty for CC0 only)."""
        lines = []
        for key in dict.fromkeys(keys):
            e = self.entry(key)
            if e.licence != "CC0-1.0":
                lines.append(f"- {e.name} by {e.creator}, {e.licence}, {e.catalogue}")
        return "\n".join(lines)


def _frozen(part: MeshPart) -> MeshPart:
    for arr in (part.positions, part.normals, part.faces, part.uvs, part.texture):
        if arr is not None:
            arr.setflags(write=False)
    return part


PROPERTIES = "PluginFurnitureCatalog.properties"
_PREFIX = {"BlendSwap-CC-0": "cc0", "BlendSwap-CC-BY": "ccby"}


def _signature(path: Path) -> dict:
    st = path.stat()
    return {"file": path.name, "size": st.st_size, "mtime": int(st.st_mtime)}


def _plan(zip_path: Path) -> tuple[str, list[tuple[str, dict, str]]]:
    """(licence, [(key, piece, category)]) for the house-worthy pieces of one catalogue."""
    with zipfile.ZipFile(zip_path) as zf:
        header, pieces = parse_properties(zf.read(PROPERTIES).decode("latin-1"))
    prefix = _PREFIX.get(zip_path.stem, _slug(zip_path.stem))
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
    return _licence(header), plan


def _convert_catalogue(zip_path: Path, dest: Path, keys: set[str] | None, progress: bool,
                       workers: int) -> dict:
    """Convert one .sh3f into ``dest`` (built in a temp folder, then renamed into place)."""
    licence, plan = _plan(zip_path)
    if keys is not None:
        plan = [p for p in plan if p[0] in keys]
    tmp = dest.with_name(f"{dest.name}.tmp{os.getpid()}")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    jobs = [(str(zip_path), key, piece, cat, licence, str(tmp / f"{key.split('/')[-1]}.npz"))
            for key, piece, cat in plan]
    results = []
    from rich.progress import Progress

    with Progress(disable=not progress, transient=False) as bar:
        task = bar.add_task(f"furniture: {zip_path.stem}", total=len(jobs))
        if workers > 1 and len(jobs) > 4:
            with ProcessPoolExecutor(workers) as pool:
                for res in pool.map(_convert_job, jobs, chunksize=2):
                    results.append(res)
                    bar.advance(task)
        else:
            for job in jobs:
                results.append(_convert_job(job))
                bar.advance(task)
    index = {"source": _signature(zip_path), "licence": licence,
             "keys": None if keys is None else sorted(keys),
             "entries": [r["entry"] for r in results if "entry" in r],
             "skipped": [r["skipped"] for r in results if "skipped" in r]}
    (tmp / "index.json").write_text(json.dumps(index, indent=1))
    trash = dest.with_name(f"{dest.name}.old{os.getpid()}")
    if dest.exists():
        dest.rename(trash)
    tmp.rename(dest)  # the folder appears complete or not at all
    shutil.rmtree(trash, ignore_errors=True)
    return index


def _entry_from_json(d: dict) -> CatalogEntry:
    return CatalogEntry(**{**d, "size_m": tuple(d["size_m"]),
                           "state_materials": tuple(d["state_materials"])})


def load_catalog(licences: Sequence[str] = ("CC0-1.0",), source_dir: str | Path | None = None,
                 cache: str | Path | None = None, progress: bool = True,
                 keys: Iterable[str] | None = None, workers: int | None = None) -> Catalog:
    """The furniture catalogue for the given licences, converting (once) what is not cached.

    source_dir: folder of ``*.sh3f`` (default $EFFICIENTEQA_FURNITURE_DIR or the Debian path).
    keys: convert/load only these entries (tests); None = every house-worthy model.
    """
    src = Path(source_dir or os.environ.get("EFFICIENTEQA_FURNITURE_DIR") or DEFAULT_SOURCE)
    zips = sorted(src.glob("*.sh3f")) if src.is_dir() else []
    if not zips:
        raise EfficientEQAError(f"furniture catalogue not found at {src}",
                                fix="sudo apt-get install sweethome3d-furniture")
    root = Path(cache) if cache is not None else cache_dir("furniture", CACHE_VERSION)
    wanted = None if keys is None else set(keys)
    workers = workers or min(4, os.cpu_count() or 1)
    entries, files, skipped = [], {}, []
    for zip_path in zips:
        dest = root / zip_path.stem
        prefix = _PREFIX.get(zip_path.stem, _slug(zip_path.stem))
        here = None if wanted is None else {k for k in wanted if k.startswith(prefix + "/")}
        if here is not None and not here:
            continue
        index = None
        if (dest / "index.json").exists():
            index = json.loads((dest / "index.json").read_text())
            fresh = index.get("source") == _signature(zip_path)
            covers = index.get("keys") is None or (here is not None and here <= set(index["keys"]))
            if not (fresh and covers):
                index = None
        if index is None:
            with zipfile.ZipFile(zip_path) as zf:
                licence = _licence(parse_properties(zf.read(PROPERTIES).decode("latin-1"))[0])
            if licence not in licences:
                continue
            start = time.perf_counter()
            index = _convert_catalogue(zip_path, dest, here, progress, workers)
            if progress:
                print(f"converted {len(index['entries'])} models from {zip_path.name} in "
                      f"{time.perf_counter() - start:.1f} s")
        if index["licence"] not in licences:
            continue
        for d in index["entries"]:
            if wanted is None or d["key"] in wanted:
                entries.append(_entry_from_json(d))
                files[d["key"]] = dest / f"{d['key'].split('/')[-1]}.npz"
        skipped += [tuple(s) for s in index["skipped"]]
    if skipped:
        warnings.warn(f"{len(skipped)} furniture models skipped: "
                      + "; ".join(f"{k} ({why})" for k, why in skipped), stacklevel=2)
    return Catalog(entries, files=files, skipped=skipped)
