"""Scenes by name: generate a synthetic house with its questions and pictures, open an HM3D
scene in Habitat-Sim, or a live robot on ROS 2."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from efficienteqa.envs.base import Environment
from efficienteqa.envs.habitat.scenes import HabitatStart
from efficienteqa.envs.synthetic.env import SyntheticEnv, catalog_for, credits
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.envs.synthetic.house import ALL_CATALOGUES, DEFAULT_ASSETS
from efficienteqa.envs.synthetic.oracle import annotate
from efficienteqa.envs.synthetic.preview import contact_sheet, topdown_map
from efficienteqa.envs.synthetic.questions import Question, generate_questions, save_questions
from efficienteqa.errors import EfficientEQAError


@dataclass
class SceneFiles:
    house: Path
    questions: Path
    map_png: Path
    views_png: Path
    n_questions: int
    n_objects: int
    n_rooms: int


def synthetic_questions(env: SyntheticEnv, per_category: int = 2, oracle: bool = True
                        ) -> list[Question]:
    """The house's questions (seeded by the house seed) with oracle step counts; ``oracle``
    False skips them (they render ~100 frames, most of the cost of opening a house), keeping
    questions whose evidence can never be seen, which the annotation would drop."""
    rng = np.random.default_rng([env.house.seed, 7])
    questions = generate_questions(env.house, rng, per_category)
    return annotate(env, questions) if oracle else questions


def write_scene(seed: int, out: Path, assets: str = DEFAULT_ASSETS, cc_by: bool = False) -> SceneFiles:
    """``house.json``, ``questions.jsonl``, ``map.png`` and ``views.png`` for ``seed`` (and
    ``ATTRIBUTION.md`` when CC-BY models are used)."""
    out.mkdir(parents=True, exist_ok=True)
    if cc_by and assets == DEFAULT_ASSETS:  # the house must say what furnished it
        assets = ALL_CATALOGUES
    catalog = catalog_for(assets)
    house = generate_house(seed, catalog, assets)
    with SyntheticEnv(house, catalog) as env:
        questions = synthetic_questions(env)
        house.save(out / "house.json")
        save_questions(questions, out / "questions.jsonl")
        topdown_map(env, questions).save(out / "map.png")
        contact_sheet(env, questions).save(out / "views.png")
    attribution = credits(house, catalog)
    if attribution:
        (out / "ATTRIBUTION.md").write_text(attribution)
    return SceneFiles(out / "house.json", out / "questions.jsonl", out / "map.png",
                      out / "views.png", len(questions), len(house.objects),
                      len(house.layout.rooms))


@dataclass
class Scene:
    """An opened scene: the environment, its name for records, and its known questions (the
    generated ones of a synthetic house; none for HM3D scenes and recorded walks). ``note``: one
    line on what opening it found (a recording's frames, and those dropped). ``credits``: the
    CC-BY models a synthetic house uses, as markdown lines (``ask`` writes ATTRIBUTION.md)."""

    env: Environment
    name: str
    questions: list[Question] = field(default_factory=list)
    note: str = ""
    credits: str = ""

    @property
    def backend(self) -> str:
        """The environment back-end without the scene: "synthetic (sh3d)" for
        "synthetic:3 (sh3d)", so records of many scenes name one back-end."""
        kind, _, rest = self.name.partition(":")
        at = rest.rfind(" (")  # the last: a recording's path may hold spaces
        return f"{kind} {rest[at + 1:] if at >= 0 else ''}".strip()


ENVS = ("synthetic", "habitat")
FIX_HABITAT = "run hm3d scenes with --scene.env habitat --scene.hm3d-root FOLDER (see docs/habitat.md)"


def open_scene(spec: str, assets: str = DEFAULT_ASSETS, *, env: str = "synthetic",
               hm3d_root: Path | str | None = None, start: HabitatStart | None = None,
               oracle: bool = True, noise: str = "none") -> Scene:
    """``synthetic:SEED`` -> the generated house with its questions (with oracle steps unless
    ``oracle`` is False: datasets carry their own);
    ``hm3d:SCENE`` with ``env="habitat"`` -> the HM3D scene under ``hm3d_root`` in Habitat-Sim,
    starting at ``start`` (HM-EQA's pose for the question);
    ``ros2`` or ``ros2:PARAMS.toml`` -> the robot on the live ROS 2 graph, with the parameters
    of the TOML file (``envs.ros2.params``) or the defaults; it has no questions;
    ``recorded:PATH`` -> a recorded walk (an .mcap file as ROS 2 records one, or a walk folder;
    ``envs.recorded``), whatever ``env`` names: a recording needs no simulator."""
    kind, _, arg = spec.partition(":")
    if env not in ENVS:
        raise EfficientEQAError(f"unknown environment {env!r}", fix=f"use one of {', '.join(ENVS)}")
    if noise != "none" and kind != "synthetic":
        raise EfficientEQAError(f"noise profile {noise!r} is for the synthetic houses, not "
                                f"{spec!r}", fix="leave out --scene.noise")
    if kind == "recorded":
        from efficienteqa.envs.recorded import open_recording

        walk = open_recording(arg)
        return Scene(walk, f"recorded:{arg} ({walk.source.layout})", note=walk.note)
    if kind == "hm3d":
        if env != "habitat" or hm3d_root is None:
            raise EfficientEQAError(f"scene {spec!r} needs Habitat-Sim and the HM3D scenes",
                                    fix=FIX_HABITAT)
        from efficienteqa.envs.habitat.env import open_habitat_scene

        return Scene(open_habitat_scene(Path(hm3d_root), arg, start), f"hm3d:{arg} (habitat-sim)")
    if kind == "ros2":
        if env == "habitat":
            raise EfficientEQAError(f"scene {spec!r} is a live robot, not a Habitat scene",
                                    fix="run it without --scene.env habitat")
        from efficienteqa.envs.ros2.env import open_ros2

        return Scene(open_ros2(arg or None), f"ros2:{Path(arg).name}" if arg else "ros2")
    if kind != "synthetic":
        raise EfficientEQAError(f"unknown scene {spec!r}",
                                fix="use synthetic:SEED, recorded:FILE.mcap, recorded:FOLDER, "
                                    "hm3d:SCENE with --scene.env habitat, or ros2[:PARAMS.toml] (a "
                                    "live robot)")
    if env != "synthetic":
        raise EfficientEQAError(f"scene {spec!r} is a generated house, not a Habitat scene",
                                fix="run synthetic scenes with --scene.env synthetic (the default)")
    try:
        seed = int(arg)
    except ValueError:
        seed = -1
    if seed < 0:
        raise EfficientEQAError(f"scene {spec!r} needs an integer seed of 0 or more",
                                fix="e.g. --scene synthetic:0")
    synthetic = SyntheticEnv.from_seed(seed, assets)
    questions = synthetic_questions(synthetic, oracle=oracle)
    credit = credits(synthetic.house, synthetic.catalog)
    if noise != "none":  # a robot's imperfections (envs/synthetic/noise.py)
        from efficienteqa.envs.synthetic.noise import NoisyEnv, profile

        return Scene(NoisyEnv(synthetic, profile(noise), seed=seed),
                     f"synthetic:{seed} ({assets}, noise {noise})", questions, credits=credit)
    return Scene(synthetic, f"synthetic:{seed} ({assets})", questions, credits=credit)
