"""Training data that breaks the generator's shortcuts: recolouring, held-out meshes, crops by
rarity, and the training loop's device, checkpoint and resume."""

import json
from dataclasses import replace

import numpy as np
import pytest

from efficienteqa.envs.synthetic.catalog import Catalog, CatalogEntry
from efficienteqa.envs.synthetic.generate import COLOURABLE, generate_house, recolour_share_of
from efficienteqa.envs.synthetic.primitives import builtin_catalog
from efficienteqa.perception.pixels.dataset import (
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


def _entry(key, category):
    return CatalogEntry(key=key, name=key, category=category, size_m=(1.0, 1.0, 1.0),
                        licence="CC0-1.0", creator="t", catalogue="t")


def test_heldout_keys_are_a_stable_share_of_each_category_with_several_models():
    entries = ([_entry(f"x/chair{i}", "chair") for i in range(10)]
               + [_entry("x/sofa-a", "sofa"), _entry("x/sofa-b", "sofa"), _entry("x/lamp", "lamp")])
    keys = heldout_model_keys(Catalog(entries))
    assert heldout_model_keys(Catalog(entries[::-1])) == keys  # order of the catalogue: none
    assert len([k for k in keys if "chair" in k]) == 2
    assert len([k for k in keys if "sofa" in k]) == 1 and "x/lamp" not in keys


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
