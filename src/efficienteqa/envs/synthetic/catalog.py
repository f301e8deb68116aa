"""Furniture catalogue: Sweet Home 3D models converted once to metre-scaled meshes.

Source: Debian ``sweethome3d-furniture`` (``*.sh3f`` zips of OBJ+MTL models with a Java
``PluginFurnitureCatalog.properties``). Each model is converted to the canonical local frame
(metres, z up, origin at the bottom centre of its bounding box, front facing -y) and cached under
``cache_dir("furniture", CACHE_VERSION)/<catalogue>/``: an ``index.json`` plus one ``.npz`` per
model holding ``colours`` (P, 3), ``materials`` (P,) and per part i ``p{i}_positions``,
``p{i}_normals`` (float32), ``p{i}_faces`` (uint32), optional ``p{i}_uvs`` (OBJ convention:
v = 0 at the image bottom) and ``p{i}_texture`` ((h, w, 3) uint8, top row first, <= 256 px).

Reading a package's listing is in ``sh3f.py``; converting one model in ``obj_model.py``.
"""

from __future__ import annotations

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
from pathlib import Path

import numpy as np

from efficienteqa.cache import cache_dir
from efficienteqa.envs.synthetic.colours import colour_name, mesh_colour, part_mean_rgb
from efficienteqa.envs.synthetic.decimate import decimate
from efficienteqa.envs.synthetic.mesh import MeshPart, rgb3
from efficienteqa.envs.synthetic.obj_model import convert_model
from efficienteqa.envs.synthetic.sh3f import (
    PROPERTIES,
    entry_fields,
    key_prefix,
    licence_of,
    parse_properties,
    piece_size_m,
    plan_catalogue,
)
from efficienteqa.envs.synthetic.vocabulary import LAMP_CATEGORIES
from efficienteqa.errors import EfficientEQAError

CACHE_VERSION = "v2"  # bump when the npz/index format or the conversion changes
MAX_TRIANGLES = 8000  # per model: a 640x480 frame shows no more detail (see decimate.py)
DEFAULT_SOURCE = "/usr/share/sweethome3d/furniture"

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


# --- one model: its lit materials, its npz file, its conversion ------------------------------
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
            key=key, name=piece["name"], category=category, size_m=piece_size_m(piece),
            licence=licence, creator=piece.get("creator", "unknown"),
            catalogue=Path(zip_path).stem, colour=colour_name(mesh_colour(parts)),
            state_kind=kind if state else None, state_materials=state,
            **entry_fields(category, piece))
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


def _signature(path: Path) -> dict:
    st = path.stat()
    return {"file": path.name, "size": st.st_size, "mtime": int(st.st_mtime)}


def _convert_catalogue(zip_path: Path, dest: Path, keys: set[str] | None, progress: bool,
                       workers: int) -> dict:
    """Convert one .sh3f into ``dest`` (built in a temp folder, then renamed into place)."""
    licence, plan = plan_catalogue(zip_path)
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
        prefix = key_prefix(zip_path)
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
                licence = licence_of(parse_properties(zf.read(PROPERTIES).decode("latin-1"))[0])
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
