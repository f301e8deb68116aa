"""Pixel perception reads RGB-D and the pose only, and describes what its network sees."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.geometry import Pose2D
from efficienteqa.observation import Observation, PromptPoint
from efficienteqa.perception.pixels.backend import PixelPerception
from efficienteqa.perception.pixels.frames import build_vocabulary, frame_labels
from efficienteqa.perception.pixels.net import IGNORE, PixelNet, Vocabulary, save_weights
from efficienteqa.perception.pixels.segment import PixelClasses, read_frame
from efficienteqa.question import parse_question
from efficienteqa.stack import build_perception


class StrippedObservation:
    """A frame that has RGB, depth, intrinsics, pose and camera-to-world, and raises on
    anything else (the instance buffer above all)."""

    _KEEP = ("rgb", "depth_m", "intrinsics", "pose", "cam_to_world")

    def __init__(self, obs: Observation) -> None:
        for name in self._KEEP:
            object.__setattr__(self, name, getattr(obs, name))

    def __getattr__(self, name: str) -> object:
        raise AttributeError(f"pixel perception read {name!r} of the frame")


class StrippedEnv:
    """An environment without instance buffers or scene labels: it moves and renders, and
    raises on any other attribute (``scene_labels``, ``house``...)."""

    def __init__(self, env: SyntheticEnv) -> None:
        object.__setattr__(self, "_env", env)

    def observe(self, pose: Pose2D | None = None) -> StrippedObservation:
        return StrippedObservation(self._env.observe(pose))

    def __getattr__(self, name: str) -> object:
        raise AttributeError(f"pixel perception read {name!r} of the environment")


@pytest.fixture(scope="module")
def weights(tmp_path_factory) -> object:
    """A small untrained network with the real vocabulary's shape, saved as the product
    saves weights (the committed weights are too slow to matter here, and any net will do:
    what is tested is what the perception reads)."""
    torch.manual_seed(0)
    vocab = Vocabulary(("void", "wall", "floor:kitchen", "floor:hallway", "door", "table",
                        "chair", "cup"), ("white", "brown", "red"), ("on", "off", "open",
                                                                      "closed"))
    net = PixelNet(vocab, (8, 8, 8, 8, 8))
    for p in net.parameters():  # strong random weights, so the classes vary across a frame
        torch.nn.init.normal_(p, std=0.5)
    path = tmp_path_factory.mktemp("weights") / "pixels.pt"
    save_weights(path, net, vocab, {"note": "test"})
    return path


def _poses(env: SyntheticEnv) -> list[Pose2D]:
    start = env.house.start
    return [start, Pose2D(start.x, start.y, start.yaw + 2.0), Pose2D(start.x, start.y,
                                                                     start.yaw - 2.0)]


def test_a_stripped_environment_gives_byte_identical_descriptions(env_seed3, weights,
                                                                   monkeypatch):
    full = PixelPerception.load(weights, room_votes=True)  # as the stack builds it
    monkeypatch.setattr("efficienteqa.perception.pixels.backend.WEIGHTS", weights)
    stripped = build_perception("pixels", StrippedEnv(env_seed3))  # the stack asks env nothing
    target = parse_question("What is on the table in the kitchen?")
    for pose in _poses(env_seed3):
        obs = env_seed3.observe(pose)
        bare = StrippedEnv(env_seed3).observe(pose)
        prompts = [PromptPoint("A", (pose.x + 1.0, pose.y), (320.0, 400.0)),
                   PromptPoint("B", (pose.x, pose.y + 2.0), (100.0, 300.0))]
        assert stripped.frame(bare) == full.frame(obs)  # type: ignore[arg-type]
        assert stripped.relevancy_text(bare) == full.relevancy_text(obs)  # type: ignore[arg-type]
        assert (stripped.explore_request(bare, prompts).directions  # type: ignore[arg-type]
                == full.explore_request(obs, prompts).directions)
        a, b = stripped.sightings(bare, target), full.sightings(obs, target)  # type: ignore[attr-defined]
        assert a.things == b.things and a.floor.keys() == b.floor.keys()
    with pytest.raises(AttributeError, match="instance"):
        _ = bare.instance  # the stripped frame would have caught a read


def _perfect(obs: Observation, env: SyntheticEnv) -> PixelClasses:
    """What a perfect network would say of ``obs``: its training labels."""
    vocab = build_vocabulary()
    labels = frame_labels(obs, env.house, vocab)
    keep = {k: np.where(labels[k] == IGNORE, 0, labels[k]) for k in ("category", "colour",
                                                                      "state")}
    return PixelClasses(keep["category"], keep["colour"], keep["state"], vocab.categories,
                        vocab.colours, vocab.states)


def test_perfect_classes_describe_what_the_semantic_sensor_does(env_seed3):
    """With every pixel's class right, the instances and rooms the pixel path makes give the
    label-reading description's room, rooms in view and objects (category, colour, state,
    bearing, distance, support). Where a door leads is the one thing the frame may not show:
    the sensor knows the scene's door sides, pixels only the floor seen beyond the door."""
    from efficienteqa.perception.semantic import SemanticPerception

    obs = env_seed3.observe()
    perfect = _perfect(obs, env_seed3)
    a = PixelPerception(lambda rgb, depth: perfect).describe(obs)
    b = SemanticPerception(env_seed3.scene_labels()).describe(obs)
    assert a.room == b.room == "living room" and a.rooms_in_view == b.rooms_in_view
    assert len(b.objects) >= 4

    def seen(objects):
        return [(o.label.category, o.label.colour, o.label.state, o.bearing, o.distance_m, o.on)
                for o in objects]

    assert seen(a.objects) == seen(b.objects)


def test_a_region_is_cut_where_depth_jumps(monkeypatch):
    """Two chairs of one category, one behind the other, are two instances."""
    categories = ("void", "wall", "floor:kitchen", "door", "chair")
    category = np.full((4, 8), 1, np.uint8)
    category[1:3, 1:7] = 4
    depth = np.full((8, 16), 3.0, np.float32)
    depth[:, 8:] = 5.0  # the right chair stands 2 m further
    k = np.array([[8.0, 0, 8], [0, 8.0, 4], [0, 0, 1]])
    cam = np.eye(4)
    classes = PixelClasses(category, np.zeros_like(category), np.zeros_like(category),
                           categories, ("grey",), ("on",))
    monkeypatch.setattr("efficienteqa.perception.pixels.segment.MIN_REGION_PIXELS", 1)
    instance, labels = read_frame(classes, depth, k, cam)
    ids = sorted(set(np.unique(instance).tolist()) - {0, -1})
    assert len(ids) == 2
    assert {labels.label(i).category for i in ids} == {"chair"}


def test_evaluate_refuses_training_houses_and_unreadable_seeds_before_any_work():
    from typer.testing import CliRunner

    from efficienteqa import cli

    for seeds, said in (("3000-3010", "training house"), ("1o0-129", "cannot read"),
                        ("129-100", "cannot read")):
        result = CliRunner().invoke(cli.app, ["perception", "evaluate", "--seeds", seeds,
                                              "--frames-per-house", "1"])
        assert result.exit_code != 0
        assert said in str(result.exception) + result.output, seeds
