"""End to end with the real furniture package (skipped where it is not installed)."""

import json
from pathlib import Path

import numpy as np
import pytest

from conftest import needs_egl
from efficienteqa.envs.synthetic.catalog import DEFAULT_SOURCE
from efficienteqa.envs.synthetic.house import House
from efficienteqa.envs.synthetic.questions import evidence_visible, load_questions
from efficienteqa.geometry import Pose2D
from efficienteqa.scenes import write_scene

pytestmark = [
    needs_egl,
    pytest.mark.slow,
    pytest.mark.skipif(not Path(DEFAULT_SOURCE).exists(),
                       reason="apt-get install sweethome3d-furniture"),
]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    out = tmp_path_factory.mktemp("scene")
    write_scene(1, out)
    return out


def test_scene_files(scene):
    house = House.load(scene / "house.json")
    assert 5 <= len(house.layout.rooms) <= 9
    licences = {o["licence"] for o in json.loads((scene / "house.json").read_text())["objects"]}
    assert licences == {"CC0-1.0"}
    assert not (scene / "ATTRIBUTION.md").exists()
    assert (scene / "map.png").stat().st_size > 10_000
    assert (scene / "views.png").stat().st_size > 10_000
    categories = {o.category for o in house.objects}
    assert {"sofa", "bed", "refrigerator", "toilet", "door"} <= categories


def test_real_furniture_questions_are_answerable(scene):
    from efficienteqa.envs.synthetic.env import SyntheticEnv, catalog_for

    house = House.load(scene / "house.json")
    questions = load_questions(scene / "questions.jsonl")
    assert len({q.category for q in questions}) >= 5
    with SyntheticEnv(house, catalog_for("sh3d")) as env:
        for q in questions:
            if q.evidence:
                obs = env.observe(Pose2D(*q.oracle_pose))
                assert evidence_visible(obs.instance, q.evidence), q.question


@pytest.mark.parametrize("category", ["tv", "desk lamp"])
def test_on_and_off_look_different(category):
    """A lit screen or lamp is clearly brighter than the same object switched off."""
    from dataclasses import replace

    from efficienteqa.envs.synthetic.build import object_parts
    from efficienteqa.envs.synthetic.env import catalog_for
    from efficienteqa.envs.synthetic.house import PlacedObject
    from efficienteqa.envs.synthetic.render import Renderer
    from efficienteqa.envs.synthetic.scene_geometry import SceneGeometry
    from efficienteqa.geometry import CameraSpec, camera_to_world

    catalog = catalog_for("sh3d")
    entry = catalog.by_category(category)[0]
    obj = PlacedObject(1, category, entry.key, entry.name, 0, 0.0, 0.0, 0.8, 0.0, entry.size_m,
                       entry.colour, entry.licence, state="on")
    camera = CameraSpec().scaled(320, 240)
    eye = camera_to_world(Pose2D(0.0, -1.0, np.pi / 2), camera)  # in front (-y), facing +y
    brightness = {}
    with Renderer(camera) as renderer:
        for state in ("on", "off"):
            renderer.set_scene(SceneGeometry(object_parts(replace(obj, state=state), catalog)))
            frame = renderer.render(eye)
            assert (frame.instance == 1).sum() > 150
            brightness[state] = frame.rgb[frame.instance == 1].mean()
    assert brightness["on"] > brightness["off"] + 15, brightness
