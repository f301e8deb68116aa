"""Furniture catalogue: vocabulary, parsing, conversion to the canonical frame, colours, cache."""

from __future__ import annotations

import io
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

from efficienteqa.envs.synthetic.catalog import Catalog, load_catalog
from efficienteqa.envs.synthetic.colours import PALETTE, colour_name, mesh_colour, recoloured
from efficienteqa.envs.synthetic.mesh import MeshPart
from efficienteqa.envs.synthetic.primitives import builtin_catalog, cylinder_part
from efficienteqa.envs.synthetic.sh3f import parse_properties
from efficienteqa.envs.synthetic.vocabulary import SMALL_CATEGORIES, canonical_category
from efficienteqa.errors import EfficientEQAError

SOURCE = Path("/usr/share/sweethome3d/furniture")
needs_furniture = pytest.mark.skipif(
    not (SOURCE / "BlendSwap-CC-0.sh3f").exists(),
    reason="Debian package sweethome3d-furniture is not installed")


@pytest.mark.parametrize("name, expected", [
    ("Large fridge", "refrigerator"), ("Refrigerator", "refrigerator"), ("Couch", "sofa"),
    ("Corner sofa", "sofa"), ("Winchester sofa", "sofa"), ("Winchester armchair", "armchair"),
    ("Oak chair", "chair"), ("Bed", "bed"), ("TV", "tv"), ("Television cabinet", "tv stand"),
    ("Vertical shelves", "bookshelf"), ("Bookcase", "bookshelf"), ("Orchids", "flowers"),
    ("Desk lamp", "desk lamp"), ("Toilets unit", "toilet"), ("Washbasin", "sink"),
    ("Cooktop", "stove"), ("Double oven", "oven"), ("Grand piano", "piano"), ("Desk", "desk"),
    ("Wardrobe", "wardrobe"), ("Bedside table", "nightstand"), ("Coffee cup", "cup"),
    ("Cactus", "cactus"), ("Truck", None), ("Spiral staircase", None), ("Shipping container", None),
])
def test_vocabulary(name: str, expected: str | None) -> None:
    assert canonical_category(name) == expected


def test_size_dependent_categories() -> None:
    assert canonical_category("Lamp", height_m=1.5) == "floor lamp"
    assert canonical_category("Lamp", height_m=0.5) == "table lamp"
    assert canonical_category("Lamp", height_m=0.6, elevation_m=1.9) == "ceiling lamp"
    assert canonical_category("Table", height_m=0.45) == "coffee table"
    assert canonical_category("Plant", height_m=0.3) == "potted plant"
    assert {"cup", "book", "vase", "laptop", "potted plant"} <= SMALL_CATEGORIES


def test_parse_properties() -> None:
    text = ("# comment\nname=Demo\nlicense=Public domain\n"
            "id#1=a\nname#1=Caf\\u00e9 table\nwidth#1 = 120.5\nmodelRotation#1=1 0 0 \\\n"
            "  0 1 0 0 0 1\n! other comment\ncategory#2:Kitchen\n")
    header, pieces = parse_properties(text)
    assert header == {"name": "Demo", "license": "Public domain"}
    assert pieces[1] == {"id": "a", "name": "Café table", "width": "120.5",
                         "modelRotation": "1 0 0 0 1 0 0 0 1"}
    assert pieces[2] == {"category": "Kitchen"}


@pytest.mark.parametrize("name, rgb", [
    ("white", (1, 1, 1)), ("black", (0.02, 0.02, 0.03)), ("grey", (0.5, 0.5, 0.52)),
    ("red", (0.9, 0.1, 0.1)), ("green", (0.1, 0.7, 0.2)), ("blue", (0.1, 0.2, 0.9)),
    ("brown", (0.5, 0.3, 0.15)), ("beige", (0.85, 0.75, 0.6)), ("yellow", (0.95, 0.9, 0.1)),
    ("orange", (1.0, 0.5, 0.0)), ("purple", (0.5, 0.1, 0.7)), ("pink", (1.0, 0.6, 0.75)),
])
def test_colour_name(name: str, rgb: tuple[float, float, float]) -> None:
    assert colour_name(rgb) == name
    assert colour_name(PALETTE[name]) == name


def test_recoloured_changes_dominant_colour_and_keeps_original() -> None:
    body = cylinder_part(0.3, 1.0, PALETTE["brown"], material="body")
    tex = np.zeros((8, 8, 3), np.uint8)
    tex[::2] = 200  # striped wood-like texture
    body.uvs, body.texture = np.zeros((len(body.positions), 2), np.float32), tex
    knob = cylinder_part(0.02, 0.02, PALETTE["black"], (0, 0, 1.0), material="knob")
    parts = [body, knob]
    for target in ("red", "blue", "white", "green"):
        out = recoloured(parts, PALETTE[target])
        assert colour_name(mesh_colour(out)) == target
        assert out[1] is knob  # small parts untouched
    assert body.colour == PALETTE["brown"] and body.texture is tex


def test_builtin_catalog_covers_categories_and_shapes() -> None:
    cat = builtin_catalog()
    need = {"sofa", "armchair", "chair", "table", "coffee table", "bed", "nightstand", "tv",
            "tv stand", "floor lamp", "refrigerator", "stove", "sink", "toilet", "bathtub", "desk",
            "bookshelf", "wardrobe", "plant", "cup", "book", "vase"}
    assert need <= set(cat.categories())
    for e in cat.entries:
        parts = cat.mesh(e.key)
        pts = np.concatenate([p.positions for p in parts])
        assert np.allclose(pts.max(0) - pts.min(0), e.size_m, atol=1e-3), e.key
        assert np.allclose((pts.max(0) + pts.min(0))[:2], 0, atol=1e-4)
        assert abs(pts[:, 2].min()) < 1e-5
        for p in parts:
            assert p.positions.dtype == np.float32 and p.normals.dtype == np.float32
            assert p.faces.dtype == np.uint32 and p.faces.max() < len(p.positions)
            assert p.normals.shape == p.positions.shape
            assert np.allclose(np.linalg.norm(p.normals, axis=1), 1, atol=1e-4)
            assert p.instance_id == 0
        assert e.licence == "CC0-1.0" and e.creator == "efficienteqa"
        assert set(e.state_materials) <= {p.material for p in parts}
    assert cat.by_category("tv")[0].state_kind == "tv"
    assert "bulb" in cat.by_category("floor lamp")[0].state_materials
    assert cat.by_category("table")[0].top_m == pytest.approx(0.75)
    assert cat.attribution(e.key for e in cat.entries) == ""


def test_meshes_are_safe_to_modify() -> None:
    cat = builtin_catalog()
    parts = cat.mesh("builtin/sofa")
    with pytest.raises(ValueError):
        parts[0].positions[0, 0] = 9.0
    parts[0].colour = (1.0, 0.0, 0.0)
    assert cat.mesh("builtin/sofa")[0].colour != (1.0, 0.0, 0.0)


def test_cylinder_normals_point_outwards() -> None:
    p = cylinder_part(0.5, 2.0, (1, 1, 1), (1.0, 2.0, 0.0))
    tri = p.positions[p.faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = np.array([1.0, 2.0, 1.0])
    assert (np.einsum("ij,ij->i", fn, tri.mean(1) - centre) > 0).all()
    assert p.area_m2 == pytest.approx(2 * np.pi * 0.5 * 2 + 2 * np.pi * 0.25, rel=0.05)


def test_missing_source_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(EfficientEQAError, match="sweethome3d-furniture"):
        load_catalog(source_dir=tmp_path / "nowhere", cache=tmp_path / "c", progress=False)


def _fake_sh3f(path: Path) -> None:
    """A catalogue with one good cube, one broken OBJ and one unknown (excluded) name."""
    cube = "\n".join(["mtllib cube.mtl"] + [f"v {x} {y} {z}" for x in (0, 2) for y in (0, 1)
                                            for z in (0, 4)]
                     + ["usemtl red", "f 1 3 4 2", "f 5 6 8 7", "f 1 2 6 5", "f 3 7 8 4",
                        "usemtl nowhere", "f 1 5 7 3", "f 2 4 8 6"])
    props = ("license=Creative Commons Attribution 3.0\n"
             "name#1=Desk\ncategory#1=Office\nmodel#1=/m/cube/cube.obj\nwidth#1=100\n"
             "depth#1=50\nheight#1=75\ncreator#1=Alice\n"
             "name#2=Bed\ncategory#2=Bedroom\nmodel#2=/m/broken/broken.obj\nwidth#2=100\n"
             "depth#2=200\nheight#2=50\ncreator#2=Bob\n"
             "name#3=Spaceship\ncategory#3=Misc\nmodel#3=/m/cube/cube.obj\nwidth#3=1\n"
             "depth#3=1\nheight#3=1\n")
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("PluginFurnitureCatalog.properties", props)
        zf.writestr("m/cube/cube.obj", cube)
        zf.writestr("m/cube/cube.mtl", "newmtl red\nKd 0.9 0.1 0.1\n")
        zf.writestr("m/broken/broken.obj", "v 0 0 0\nf 1 2 3\n")


def test_broken_model_is_skipped_and_cube_is_converted(tmp_path: Path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    _fake_sh3f(src / "Fake.sh3f")
    with pytest.warns(UserWarning, match="1 furniture models skipped"):
        cat = load_catalog(licences=("CC-BY-3.0",), source_dir=src, cache=tmp_path / "c",
                           progress=False)
    assert [e.key for e in cat.entries] == ["fake/cube"]
    assert cat.skipped[0][0] == "fake/broken"
    e = cat.entries[0]
    assert (e.category, e.colour, e.top_m, e.licence) == ("desk", "red", 0.75, "CC-BY-3.0")
    pts = np.concatenate([p.positions for p in cat.mesh(e.key)])
    assert np.allclose(pts.min(0), [-0.5, -0.25, 0]) and np.allclose(pts.max(0), [0.5, 0.25, 0.75])
    assert {p.material for p in cat.mesh(e.key)} == {"red", "nowhere"}
    assert cat.attribution([e.key]) == "- Desk by Alice, CC-BY-3.0, Fake"
    assert load_catalog(licences=("CC0-1.0",), source_dir=src, cache=tmp_path / "c",
                        progress=False).entries == []


@pytest.fixture(scope="module")
def real(tmp_path_factory: pytest.TempPathFactory) -> tuple[Catalog, Path]:
    cache = tmp_path_factory.mktemp("furniture")
    keys = ["cc0/led_tv", "cc0/large_fridge"]
    return load_catalog(cache=cache, keys=keys, progress=False), cache


@needs_furniture
def test_real_models_in_canonical_frame(real: tuple[Catalog, Path]) -> None:
    cat, _ = real
    for e in cat.entries:
        pts = np.concatenate([p.positions for p in cat.mesh(e.key)])
        lo, hi = pts.min(0), pts.max(0)
        assert np.allclose(hi - lo, e.size_m, atol=0.01), e.key
        assert np.allclose((lo + hi)[:2] / 2, 0, atol=0.005) and abs(lo[2]) < 0.005
    tv = cat.entry("cc0/led_tv")
    assert (tv.category, tv.state_kind, tv.state_materials) == ("tv", "tv", ("screen",))
    assert tv.size_m == pytest.approx((0.775, 0.142, 0.508))
    screen = next(p for p in cat.mesh(tv.key) if p.material == "screen")
    tri = screen.positions[screen.faces].astype(np.float64)
    facing = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).sum(0)
    assert facing[1] < -0.9 * np.linalg.norm(facing)  # the screen looks towards -y (front)
    biggest = screen.faces[np.argmax(np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0],
                                                             tri[:, 2] - tri[:, 0]), axis=1))]
    assert (screen.normals[biggest][:, 1] < -0.99).all()  # stored normals agree
    assert cat.entry("cc0/large_fridge").category == "refrigerator"


@needs_furniture
def test_second_load_hits_cache(real: tuple[Catalog, Path]) -> None:
    _, cache = real
    npz = sorted(cache.rglob("*.npz"))
    stamps = [p.stat().st_mtime_ns for p in npz]
    start = time.perf_counter()
    again = load_catalog(cache=cache, keys=["cc0/led_tv"], progress=False)
    assert time.perf_counter() - start < 1.0
    assert [p.stat().st_mtime_ns for p in npz] == stamps  # nothing reconverted
    assert [e.key for e in again.entries] == ["cc0/led_tv"]
    assert len(again.mesh("cc0/led_tv")) >= 2
    assert not list(cache.glob("*.tmp*"))


def test_texture_formats_are_read(tmp_path: Path) -> None:
    from PIL import Image

    from efficienteqa.envs.synthetic.obj_model import _read_texture

    buf = io.BytesIO()
    Image.new("RGB", (1024, 512), (10, 200, 30)).save(buf, format="TIFF")
    with zipfile.ZipFile(tmp_path / "t.zip", "w") as zf:
        zf.writestr("m/Wood.TIF", buf.getvalue())
        zf.writestr("m/bad.png", b"not an image")
    with zipfile.ZipFile(tmp_path / "t.zip") as zf:
        tex = _read_texture(zf, "m/", "wood.tif")
        assert tex is not None and tex.shape == (128, 256, 3) and tex.dtype == np.uint8
        assert _read_texture(zf, "m/", "bad.png") is None
        assert _read_texture(zf, "m/", "missing.jpg") is None


def test_mesh_part_type_is_shared() -> None:
    assert isinstance(builtin_catalog().mesh("builtin/cup")[0], MeshPart)


def test_all_the_packages_catalogues_are_an_assets_choice(monkeypatch) -> None:
    """"sh3d-all" furnishes houses from every catalogue of the package (CC0 and CC-BY);
    "sh3d" from the CC0 one; anything else is one line naming the choices."""
    from efficienteqa.envs.synthetic import env
    from efficienteqa.envs.synthetic.house import check_assets
    from efficienteqa.errors import EfficientEQAError

    asked: list[tuple[str, ...]] = []
    monkeypatch.setattr(env, "load_catalog", lambda licences: asked.append(tuple(licences)))
    env.catalog_for("sh3d-all")
    env.catalog_for("sh3d")
    env.catalog_for("sh3d", cc_by=True)
    assert asked == [("CC0-1.0", "CC-BY-3.0"), ("CC0-1.0",), ("CC0-1.0", "CC-BY-3.0")]
    with pytest.raises(EfficientEQAError, match="use one of sh3d, sh3d-all, builtin"):
        check_assets("sh3d-cc-by")
