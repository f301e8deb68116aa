"""Region thresholds per category: chosen on validation frames, recorded with the weights, and
applied by the segmenter to that category alone."""

from __future__ import annotations

import json

import numpy as np
import pytest

from efficienteqa.perception.pixels.segment import MIN_CONFIDENCE, PixelClasses, read_frame
from efficienteqa.perception.pixels.thresholds import Candidates, choose, overall, write_thresholds

CATEGORIES = ("void", "wall", "floor:kitchen", "door", "chair", "sink")
K = np.array([[8.0, 0, 8], [0, 8.0, 4], [0, 0, 1]])


def _frame(confidence: float) -> tuple[PixelClasses, np.ndarray]:
    """A chair on the left and a sink on the right, both at ``confidence``."""
    category = np.full((4, 8), 1, np.uint8)
    category[1:3, 1:4] = 4
    category[1:3, 5:8] = 5
    classes = PixelClasses(category, np.zeros_like(category), np.zeros_like(category),
                           CATEGORIES, ("grey",), ("on",),
                           np.full(category.shape, confidence, np.float32))
    return classes, np.full((8, 16), 3.0, np.float32)


def _kept(classes: PixelClasses, depth: np.ndarray) -> list[str]:
    instance, labels = read_frame(classes, depth, K, np.eye(4))
    ids = sorted(set(np.unique(instance).tolist()) - {0, -1})
    return sorted(labels.label(i).category for i in ids)


def test_a_category_threshold_keeps_its_unsure_regions_and_no_others(monkeypatch):
    monkeypatch.setattr("efficienteqa.perception.pixels.segment.MIN_REGION_PIXELS", 1)
    classes, depth = _frame(MIN_CONFIDENCE - 0.2)
    assert _kept(classes, depth) == []  # one global threshold drops both
    from dataclasses import replace

    lowered = replace(classes, min_confidence={"sink": MIN_CONFIDENCE - 0.3})
    assert _kept(lowered, depth) == ["sink"]
    raised = replace(_frame(MIN_CONFIDENCE + 0.1)[0], min_confidence={"chair": 0.95})
    assert _kept(raised, depth) == ["sink"]


def test_choose_lowers_a_hard_category_and_raises_a_noisy_one():
    """Sinks: right but unsure (found only below the global threshold). Cabinets: sure ones are
    right, unsure ones wrong. The choice finds each category's best F1."""
    c = Candidates()
    for _ in range(10):
        c.regions["sink"].append((0.35, True, 0.0))
        c.objects["sink"].append([(0.35, 0.9, 0.0)])
        c.regions["cabinet"].append((0.8, True, 0.0))
        c.objects["cabinet"].append([(0.8, 0.9, 0.0)])
        c.regions["cabinet"].append((0.65, False, 0.0))
    chosen = choose(c)
    assert chosen["sink"]["threshold"] <= 0.35 < MIN_CONFIDENCE
    assert chosen["sink"]["recall"] == 1.0 and chosen["sink"]["recall_at_default"] == 0.0
    assert 0.65 < chosen["cabinet"]["threshold"] <= 0.8
    assert chosen["cabinet"]["precision"] == 1.0 and chosen["cabinet"]["precision_at_default"] == 0.5
    before, after = overall(c, {}), overall(c, {k: v["threshold"] for k, v in chosen.items()})
    assert after[0] > before[0] and after[1] > before[1]


def test_a_rare_or_never_found_category_keeps_the_global_threshold():
    c = Candidates()
    c.regions["toilet"].append((0.3, True, 0.0))
    c.objects["toilet"].append([(0.3, 1.0, 0.0)])
    for _ in range(10):  # wall lamps in view, never covered by a right region
        c.objects["wall lamp"].append([])
        c.regions["wall lamp"].append((0.5, False, 0.0))
    assert choose(c) == {}


def test_thresholds_are_recorded_beside_the_weights_and_loaded_with_them(tmp_path):
    import torch

    from efficienteqa.perception.pixels.backend import PixelPerception
    from efficienteqa.perception.pixels.net import PixelNet, Vocabulary, save_weights, sha256_of

    vocab = Vocabulary(CATEGORIES, ("grey",), ("on", "off", "open", "closed"))
    torch.manual_seed(0)
    path = tmp_path / "pixels.pt"
    save_weights(path, PixelNet(vocab, (8, 8, 8, 8, 8)), vocab, {})
    digest = sha256_of(path)
    write_thresholds(path, {"sink": {"threshold": 0.3}}, {"houses": "3900-3909"})
    meta = json.loads(path.with_suffix(".json").read_text())
    assert meta["region_thresholds"] == {"sink": 0.3} and meta["sha256"] == digest
    perception = PixelPerception.load(path)
    rgb = np.zeros((32, 32, 3), np.uint8)
    assert perception.classify(rgb, np.ones((32, 32), np.float32)).min_confidence == {"sink": 0.3}


def test_thresholds_refuse_houses_outside_validation_before_any_work():
    from typer.testing import CliRunner

    from efficienteqa import cli

    result = CliRunner().invoke(cli.app, ["perception", "thresholds", "--seeds", "3000-3001"])
    assert result.exit_code != 0
    assert "not validation houses" in str(result.exception) + result.output


@pytest.mark.parametrize("confidence", [0.2, 0.9])
def test_without_thresholds_the_global_one_acts(monkeypatch, confidence):
    monkeypatch.setattr("efficienteqa.perception.pixels.segment.MIN_REGION_PIXELS", 1)
    classes, depth = _frame(confidence)
    assert _kept(classes, depth) == ([] if confidence < MIN_CONFIDENCE else ["chair", "sink"])


# -- evaluation slices: recoloured objects, held-out meshes, frames posed as walks -------------
def test_object_tags_mark_recoloured_objects_and_held_out_meshes():
    from types import SimpleNamespace

    from efficienteqa.perception.pixels.evaluate import (
        HELD_OUT_MESH,
        RECOLOURED,
        TRAINED_MESH,
        object_tags,
    )

    objects = [SimpleNamespace(id=1, colour_rgb=(1.0, 0.0, 0.0), model_key="sofa-a"),
               SimpleNamespace(id=2, colour_rgb=None, model_key="sofa-b"),
               SimpleNamespace(id=3, colour_rgb=None, model_key="chair-a")]
    assert object_tags(objects, frozenset()) == {1: [RECOLOURED]}
    assert object_tags(objects, frozenset({"sofa-b"})) == {
        1: [RECOLOURED, TRAINED_MESH], 2: [HELD_OUT_MESH], 3: [TRAINED_MESH]}


def test_object_tags_mark_the_catalogue_in_houses_of_every_catalogue():
    """Weights trained on the CC0 houses never saw the CC-BY catalogues; weights trained on
    every catalogue never saw the held-out one only. Doors carry no catalogue slice."""
    from types import SimpleNamespace

    from efficienteqa.perception.pixels.evaluate import (
        TRAINED_CATALOGUE,
        UNSEEN_CATALOGUE,
        object_tags,
        unseen_catalogue,
    )
    from efficienteqa.perception.pixels.houses import HELDOUT_CATALOGUE

    entries = {"cc0/sofa": ("CC0-1.0", "BlendSwap-CC-0"),
               "ccby/sofa": ("CC-BY-3.0", "BlendSwap-CC-BY"),
               "kl/sofa": ("CC-BY-3.0", HELDOUT_CATALOGUE), "cc0/door": ("CC0-1.0", "BlendSwap-CC-0")}
    catalog = SimpleNamespace(entry=lambda key: SimpleNamespace(licence=entries[key][0],
                                                                catalogue=entries[key][1]))
    objects = [SimpleNamespace(id=i, colour_rgb=None, model_key=key, category=key.split("/")[1])
               for i, key in enumerate(entries, start=1)]
    assert object_tags(objects, frozenset()) == {}
    assert object_tags(objects, frozenset(), unseen_catalogue(catalog, "sh3d")) == {
        1: [TRAINED_CATALOGUE], 2: [UNSEEN_CATALOGUE], 3: [UNSEEN_CATALOGUE]}
    assert object_tags(objects, frozenset(), unseen_catalogue(catalog, "sh3d-all")) == {
        1: [TRAINED_CATALOGUE], 2: [TRAINED_CATALOGUE], 3: [UNSEEN_CATALOGUE]}


def test_a_tagged_object_is_counted_in_its_slice(env_seed3):
    """score_frame puts a recoloured object in view into the "recoloured" slice too."""
    from efficienteqa.perception.pixels.backend import PixelPerception
    from efficienteqa.perception.pixels.evaluate import RECOLOURED, Scores, score_frame
    from efficienteqa.perception.visible import visible_objects

    obs = env_seed3.observe()
    truth = env_seed3.scene_labels()
    big = max(visible_objects(obs, truth), key=lambda o: o.pixels)
    blind = PixelPerception(lambda rgb, depth: PixelClasses(
        np.zeros((obs.depth_m.shape[0] // 2, obs.depth_m.shape[1] // 2), np.uint8),
        np.zeros((1, 1), np.uint8), np.zeros((1, 1), np.uint8),
        ("void", "wall", "floor:kitchen", "door", "chair"), ("grey",), ("on",)))
    scores = Scores()
    score_frame(obs, truth, blind, frozenset(), scores, {big.instance_id: [RECOLOURED]})
    assert scores.tallies[RECOLOURED].true == 1 and scores.tallies[RECOLOURED].found == 0
    assert scores.tallies["all"].true > 1


def test_frames_at_walk_poses_come_from_the_walk(env_seed3):
    from efficienteqa.perception.pixels.evaluate import heldout_frames

    start = env_seed3.house.start
    walk = [[start.x, start.y, start.yaw + 0.1 * k] for k in range(9)]
    frames = list(heldout_frames([3], 3, poses={3: walk}))
    assert [round(f[0].pose.yaw - start.yaw, 3) for f in frames] == [0.0, 0.4, 0.8]


def test_bad_poses_files_are_refused_in_one_line(tmp_path):
    from efficienteqa.errors import EfficientEQAError
    from efficienteqa.perception.pixels.evaluate import heldout_frames, read_poses

    bad = tmp_path / "poses.json"
    bad.write_text('{"houses": {"100": {"poses": [[1, "x", 0]]}}}')
    with pytest.raises(EfficientEQAError, match="unreadable poses file"):
        read_poses(bad)
    with pytest.raises(EfficientEQAError, match="cannot read the poses file"):
        read_poses(tmp_path / "missing.json")
    with pytest.raises(EfficientEQAError, match="no walk of house 101"):
        next(heldout_frames([100, 101], 2, poses={100: [[0.0, 0.0, 0.0]]}))
