"""Training data that breaks the generator's shortcuts: recolouring, held-out meshes, crops by
rarity, and the training loop's device, checkpoint and resume."""

import json
import sys
from dataclasses import replace

import numpy as np
import pytest

from conftest import needs_egl
from efficienteqa.envs.synthetic.catalog import Catalog, CatalogEntry
from efficienteqa.envs.synthetic.generate import COLOURABLE, generate_house, recolour_share_of
from efficienteqa.envs.synthetic.primitives import builtin_catalog
from efficienteqa.perception.pixels.houses import (
    heldout_model_keys,
    training_env,
    uses_heldout_mesh,
)


def test_generator_houses_are_unchanged_by_the_hook():
    catalog = builtin_catalog()
    for seed in (3, 100, 2000):
        a = generate_house(seed, catalog, "builtin")
        b = generate_house(seed, catalog, "builtin", recolour_share=0.0)
        assert json.dumps(a.to_json()) == json.dumps(b.to_json())


def test_recolouring_reaches_the_share_and_changes_colours_only():
    catalog = builtin_catalog()
    recoloured = colourable = 0
    for seed in range(3000, 3006):
        plain = generate_house(seed, catalog, "builtin")
        more = generate_house(seed, catalog, "builtin", recolour_share=0.5)
        assert more.start == plain.start
        assert [(o.id, o.model_key, o.x, o.y) for o in more.objects] == \
            [(o.id, o.model_key, o.x, o.y) for o in plain.objects]
        was = {o.id: o.colour for o in plain.objects}
        for o in more.objects:
            if o.category in COLOURABLE:
                colourable += 1
                recoloured += o.colour_rgb is not None
            else:
                assert o.colour == was[o.id] and o.colour_rgb is None
    assert colourable > 10 and recoloured >= 0.5 * colourable


def test_recolour_share_of_picks_another_colour():
    house = generate_house(3001, builtin_catalog(), "builtin")
    objs = [o for o in house.objects if o.category in COLOURABLE]
    before = {o.id: o.colour for o in objs if o.colour_rgb is None}
    changed = recolour_share_of(np.random.default_rng(0), house.objects, 1.0)
    assert changed == len(before) and all(o.colour_rgb is not None for o in objs)
    assert all(o.colour != before[o.id] for o in objs if o.id in before)


def _entry(key, category, catalogue="t"):
    return CatalogEntry(key=key, name=key, category=category, size_m=(1.0, 1.0, 1.0),
                        licence="CC0-1.0", creator="t", catalogue=catalogue)


def test_heldout_keys_are_a_stable_share_of_each_category_with_several_models():
    entries = ([_entry(f"x/chair{i}", "chair") for i in range(10)]
               + [_entry("x/sofa-a", "sofa"), _entry("x/sofa-b", "sofa"), _entry("x/lamp", "lamp")])
    keys = heldout_model_keys(Catalog(entries))
    assert heldout_model_keys(Catalog(entries[::-1])) == keys  # order of the catalogue: none
    assert len([k for k in keys if "chair" in k]) == 2
    assert len([k for k in keys if "sofa" in k]) == 1 and "x/lamp" not in keys


def test_heldout_keys_hold_out_a_whole_catalogue_and_a_fifth_of_each_other_one():
    """Every model of the held-out catalogue is kept out; the fifth is counted per catalogue, so
    one catalogue's held-out meshes stay the same when another catalogue is loaded beside it."""
    from efficienteqa.perception.pixels.houses import HELDOUT_CATALOGUE

    first = [_entry(f"a/chair{i}", "chair", "A") for i in range(4)]
    second = [_entry(f"b/chair{i}", "chair", "B") for i in range(4)] + [_entry("b/bed", "bed", "B")]
    style = [_entry("k/chair", "chair", HELDOUT_CATALOGUE), _entry("k/bed", "bed", HELDOUT_CATALOGUE)]
    alone = heldout_model_keys(Catalog(first))
    every = heldout_model_keys(Catalog(first + second + style))
    assert len(alone) == 1 and alone <= every
    assert {"k/chair", "k/bed"} <= every and "b/bed" not in every
    assert len([k for k in every if k.startswith("b/chair")]) == 1
    assert len(every) == 4  # pooled, the 8 chairs would give 1, not 1 + 1


def _two_sofa_catalog():
    """The builtin catalogue with a second sofa model (same mesh, another key)."""
    base = builtin_catalog()
    sofa = next(e for e in base.entries if e.category == "sofa")
    twin = replace(sofa, key=sofa.key + "-twin")
    meshes = {e.key: base.mesh(e.key) for e in base.entries}
    meshes[twin.key] = base.mesh(sofa.key)
    return Catalog([*base.entries, twin], meshes=meshes)


def test_training_houses_never_use_a_heldout_mesh(monkeypatch):
    catalog = _two_sofa_catalog()
    heldout = heldout_model_keys(catalog)
    assert len(heldout) == 1
    from efficienteqa.envs.synthetic import env as env_module

    monkeypatch.setattr(env_module, "catalog_for", lambda assets, cc_by=False: catalog)
    used_full = set()
    used_train = set()
    for seed in range(3000, 3012):
        house = generate_house(seed, catalog, "builtin")
        used_full |= {o.model_key for o in house.objects}
        hit = [o.id for o in house.objects if o.model_key in heldout]
        if hit:
            assert uses_heldout_mesh(house, hit[0], heldout)
            assert uses_heldout_mesh(house, hit[0])  # the catalogue's own held-out set
        with training_env(seed, "builtin", 0.0, hold_out=True) as env:
            used_train |= {o.model_key for o in env.house.objects}
    assert heldout <= used_full  # the generator does use it...
    assert not heldout & used_train  # ...training houses never
    assert not uses_heldout_mesh(generate_house(3000, catalog, "builtin"),
                                 next(o.id for o in generate_house(3000, catalog, "builtin").objects
                                      if o.model_key not in heldout), heldout)
    with pytest.raises(KeyError):
        uses_heldout_mesh(generate_house(3000, catalog, "builtin"), 10_000, heldout)


# -- crops by rarity ----------------------------------------------------------------------------
def _frames_with_one_rare_patch(n=20):
    cat = np.ones((n, 240, 320), np.uint8)  # wall everywhere...
    cat[7, 100:106, 200:206] = 50  # ...but a 6x6 patch of category 50 in one frame
    return {"rgb": np.zeros((n, 240, 320, 3), np.uint8), "depth": np.ones((n, 240, 320), np.float16),
            "category": cat, "colour": np.full_like(cat, 255), "state": np.full_like(cat, 255)}


def test_crops_by_rarity_find_the_rare_category():
    from efficienteqa.perception.pixels.batches import CropSampler
    from efficienteqa.perception.pixels.frames import build_vocabulary

    frames, vocab = _frames_with_one_rare_patch(), build_vocabulary()

    def share_with_patch(rarity: float) -> float:
        sampler = CropSampler(frames, vocab, (160, 224), np.random.default_rng(0), rarity)
        hits = sum(bool((sampler.batch(1)[1] == 50).any()) for _ in range(200))
        return hits / 200

    assert share_with_patch(1.0) > 0.4  # half the centres are the patch's category
    assert share_with_patch(0.0) < 0.1  # uniform crops: the one frame in 20, when it is in view


def test_class_weights_follow_the_crops_drawn():
    from efficienteqa.perception.pixels.batches import CropSampler, weights_of_counts
    from efficienteqa.perception.pixels.frames import build_vocabulary

    frames, vocab = _frames_with_one_rare_patch(), build_vocabulary()
    sampler = CropSampler(frames, vocab, (160, 224), np.random.default_rng(0), 1.0)
    state = sampler.rng.bit_generator.state
    counts = sampler.crop_counts(100, len(vocab.categories))
    assert sampler.rng.bit_generator.state == state  # training's draws are not disturbed
    assert counts[50] > 0 and counts[1] > counts[50]
    w = weights_of_counts(counts)
    assert float(w[50]) > float(w[1])


# -- device, checkpoint and resume --------------------------------------------------------------
TINY = (4, 8, 8, 8, 8)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    from efficienteqa.perception.pixels.dataset import render_dataset

    out = tmp_path_factory.mktemp("pixels-shortcut-data")
    for seeds in (range(3000, 3001), range(3900, 3901)):
        render_dataset(seeds, out, frames_per_house=3, seed=0, progress=False, workers=1,
                       assets="builtin")
    return out


@needs_egl
def test_meta_records_recolouring_and_heldout_keys(data):
    meta = json.loads((data / "meta.json").read_text())
    assert meta["recolour_share"] == 0.5 and meta["heldout_model_keys"] == []  # builtin: 1 each


@needs_egl
def test_an_interrupted_training_resumes_to_the_same_weights(data, tmp_path, monkeypatch):
    import torch

    from efficienteqa.errors import EfficientEQAError
    from efficienteqa.perception.pixels import train as train_module
    from efficienteqa.perception.pixels.train import TrainConfig, checkpoint_path, train

    config = TrainConfig(steps=6, batch=2, crop=(32, 48), widths=TINY, threads=1, device="cpu",
                         checkpoint_every=2)
    whole = tmp_path / "whole.pt"
    record = train(data, whole, config, log=sys.stdout)
    assert record["resumed_at_step"] is None and record["device"].startswith("cpu")
    assert not checkpoint_path(whole).exists()  # finished: no checkpoint left

    real, calls = train_module.losses, []

    def crash_at_step_4(*args, **kwargs):
        calls.append(1)
        if len(calls) == 4:
            raise RuntimeError("power cut")
        return real(*args, **kwargs)

    parts = tmp_path / "parts.pt"
    monkeypatch.setattr(train_module, "losses", crash_at_step_4)
    with pytest.raises(RuntimeError):
        train(data, parts, config, log=sys.stdout)
    monkeypatch.setattr(train_module, "losses", real)
    assert checkpoint_path(parts).is_file()
    with pytest.raises(EfficientEQAError, match="another training"):
        train(data, parts, replace(config, steps=7, resume=True), log=sys.stdout)
    again = train(data, parts, replace(config, resume=True), log=sys.stdout)
    assert again["resumed_at_step"] == 2 and again["steps_done"] == 6
    a = torch.load(whole, weights_only=True)
    b = torch.load(parts, weights_only=True)
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert again["loss_history"] == record["loss_history"]


def test_device_choice():
    import torch

    from efficienteqa.errors import EfficientEQAError
    from efficienteqa.perception.pixels.train import pick_device

    assert pick_device("cpu").type == "cpu"
    assert pick_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    with pytest.raises(EfficientEQAError):
        pick_device("tpu")
    if not torch.cuda.is_available():
        with pytest.raises(EfficientEQAError, match="no CUDA"):
            pick_device("cuda")


def test_code_version_names_the_copied_source(monkeypatch):
    from efficienteqa.perception.pixels.dataset import code_version

    monkeypatch.setenv("EFFICIENTEQA_CODE_VERSION", "abc1234")
    assert code_version() == "abc1234"
    monkeypatch.delenv("EFFICIENTEQA_CODE_VERSION")
    assert code_version() != "abc1234"


@needs_egl
def test_loss_history_means_each_window_over_its_own_steps(data, tmp_path, monkeypatch):
    from efficienteqa.perception.pixels import train as train_module
    from efficienteqa.perception.pixels.train import TrainConfig, train

    real = train_module.losses

    def fixed_parts(*args, **kwargs):
        loss, _ = real(*args, **kwargs)
        return loss, {"category": 1.0, "colour": 1.0, "state": 1.0}

    monkeypatch.setattr(train_module, "losses", fixed_parts)
    # 45 steps log every 2: the last window holds one step
    config = TrainConfig(steps=45, batch=1, crop=(32, 48), widths=TINY, threads=1, device="cpu",
                         checkpoint_every=0)
    record = train(data, tmp_path / "w.pt", config, log=sys.stdout)
    assert record["loss_history"][-1]["step"] == 45
    assert all(h["category"] == 1.0 for h in record["loss_history"])


@pytest.mark.parametrize("args", [["--widths", "16,32"], ["--widths", "a,b,c,d,e"],
                                  ["--device", "tpu"]])
def test_train_refuses_bad_widths_and_devices(args, monkeypatch, capsys, tmp_path):
    from efficienteqa import cli
    from efficienteqa.perception.pixels.frames import build_vocabulary

    data = tmp_path / "data"
    data.mkdir()
    (data / "meta.json").write_text(json.dumps({"vocabulary": build_vocabulary().to_json(),
                                                "houses": [3000]}))
    (data / "houses-3000-3000.npz").write_bytes(b"")
    monkeypatch.setattr(sys, "argv", ["efficienteqa", "perception", "train", "--data", str(data),
                                      "--out", str(tmp_path / "w.pt"), "--steps", "1", *args])
    with pytest.raises(SystemExit) as exit_info:
        cli.main()
    out = capsys.readouterr().out
    assert exit_info.value.code == 1 and len(out.strip().splitlines()) == 1 and "error" in out
