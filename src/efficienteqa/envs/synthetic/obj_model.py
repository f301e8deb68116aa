"""One Sweet Home 3D model (OBJ + MTL + textures inside a package zip) as canonical MeshParts.

The canonical local frame: metres, z up, origin at the bottom centre of the bounding box, front
facing -y. Separate from the catalogue because it is pure geometry: parsing and rescaling one
model, with no knowledge of the cache, the licences or which pieces are house-worthy.
"""

from __future__ import annotations

import contextlib
import zipfile
from io import BytesIO

import numpy as np
import numpy.typing as npt

from efficienteqa.envs.synthetic.mesh import MeshPart, rgb3
from efficienteqa.envs.synthetic.sh3f import piece_size_m

TEXTURE_MAX_PX = 256


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


_OBJ_TO_LOCAL = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], np.float64)  # (x, y, z) -> (x, -z, y)


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
    w, d, h = piece_size_m(piece)
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
