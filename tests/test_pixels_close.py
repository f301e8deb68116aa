"""Close reads (perception/pixels/close.py): a second pass on crops around supports finds a
small object the full pass misses, and reads at most the crops it is given."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from efficienteqa.geometry import Pose2D
from efficienteqa.observation import Observation
from efficienteqa.perception.pixels.backend import PixelPerception
from efficienteqa.perception.pixels.close import CloseReads, close_read, support_crops
from efficienteqa.perception.pixels.segment import PixelClasses

CATEGORIES = ("void", "wall", "floor:office", "door", "desk", "cup")
WALL, DESK, CUP = 1, 4, 5
BROWN, RED = (120, 80, 40), (230, 20, 20)
K = np.array([[320.0, 0, 320], [0, 320.0, 240], [0, 0, 1]])
SEEN_FROM = 90  # the stub sees a cup of this many pixels of its half-size input, not fewer


class Stub:
    """A classifier that reads colours: brown is desk, a red blob a cup when it has SEEN_FROM
    pixels in its half-size input (else the desk it stands on), the rest wall. It counts its
    calls."""

    def __init__(self) -> None:
        self.calls: list[tuple[int, int]] = []

    def __call__(self, rgb: np.ndarray, depth_m: np.ndarray) -> PixelClasses:
        self.calls.append(rgb.shape[:2])
        half = rgb[1::2, 1::2].astype(int)
        red = (half[..., 0] > 180) & (half[..., 1] < 80)
        brown = (np.abs(half - BROWN).sum(-1) < 60)
        category = np.full(red.shape, WALL, np.uint8)
        category[brown] = DESK
        blobs, _ = ndimage.label(red)
        sizes = np.bincount(blobs.ravel())
        category[red] = np.where(sizes[blobs[red]] >= SEEN_FROM, CUP, DESK)
        zeros = np.zeros_like(category)
        return PixelClasses(category, zeros, zeros, CATEGORIES, ("grey",), ("on",),
                            np.full(category.shape, 0.9, np.float32))


def frame(desks: list[tuple[int, int, float]], cup: int = 16, tall: int = 100) -> Observation:
    """A 640x480 frame: a wall 4 m away, and desks (left column, width, depth) ``tall`` rows
    tall from row 300, each with a red cup of ``cup`` x ``cup`` pixels on its top, centred."""
    rgb = np.full((480, 640, 3), 200, np.uint8)
    depth = np.full((480, 640), 4.0, np.float32)
    for left, width, d in desks:
        rgb[300:300 + tall, left:left + width] = BROWN
        depth[300:300 + tall, left:left + width] = d
        mid = left + width // 2 - cup // 2
        rgb[300 - cup:300, mid:mid + cup] = RED
        depth[300 - cup:300, mid:mid + cup] = d - 0.05
    return Observation(rgb=rgb, depth_m=depth, cam_to_world=np.eye(4), intrinsics=K,
                       pose=Pose2D(0.0, 0.0, 0.0))


def categories(perception: PixelPerception, obs: Observation) -> list[str]:
    seen, labels = perception.read(obs)
    assert seen.instance is not None
    ids = sorted(set(np.unique(seen.instance).tolist()) - {-1, 0})
    return sorted(labels.label(i).category for i in ids)  # type: ignore[union-attr]


def test_the_crop_pass_finds_a_small_object_the_full_pass_misses():
    obs = frame([(260, 120, 2.5)])  # a 16x16 cup: 64 pixels at half size, under SEEN_FROM
    assert categories(PixelPerception(Stub()), obs) == ["desk"]
    stub = Stub()
    assert categories(PixelPerception(stub, close_reads=2), obs) == ["cup", "desk"]
    assert len(stub.calls) == 2  # the full pass and one crop (one desk in view)
    assert stub.calls[1] == CloseReads().input_hw


def test_close_reads_are_bounded_nearest_support_first():
    desks = [(20, 80, 3.0), (180, 80, 1.6), (340, 80, 2.2), (500, 80, 2.8)]
    obs = frame(desks)
    stub = Stub()
    full = stub(obs.rgb, obs.depth_m)
    every = support_crops(full, obs.depth_m, K, CloseReads(crops=10))
    assert len(every) == 4  # four desks in reach, four crops
    stub = Stub()
    classes, crops = close_read(stub, full, obs.rgb, obs.depth_m, K, CloseReads(crops=2))
    assert len(crops) == 2 and len(stub.calls) == 2  # at most N crops read
    # the nearest two desks (1.6 m and 2.2 m): their cups are pasted, the others' are not
    assert [c.x0 <= 220 < c.x0 + c.w for c in crops] == [True, False]
    cups = [bool((classes.category[:, (left + 40) // 2] == CUP).any()) for left, _, _ in desks]
    assert cups == [False, True, True, False]


def test_supports_out_of_reach_or_too_small_are_not_read_and_off_reads_none():
    stub = Stub()
    obs = frame([(260, 120, 4.5)])  # beyond within_m
    full = stub(obs.rgb, obs.depth_m)
    assert support_crops(full, obs.depth_m, K, CloseReads()) == []
    obs = frame([(300, 20, 2.0)], cup=2, tall=20)  # 10 x 10 pixels at half size
    assert support_crops(stub(obs.rgb, obs.depth_m), obs.depth_m, K, CloseReads()) == []
    obs = frame([(260, 120, 2.5)])
    stub = Stub()
    PixelPerception(stub, close_reads=0).read(obs)
    assert len(stub.calls) == 1
    with pytest.raises(ValueError):
        CloseReads(crops=-1)


def test_evaluate_refuses_a_negative_number_of_close_reads_before_any_work():
    from typer.testing import CliRunner

    from efficienteqa import cli

    result = CliRunner().invoke(cli.app, ["perception", "evaluate", "--seeds", "100",
                                          "--close-reads", "-1"])
    assert result.exit_code != 0
    assert "--close-reads must be 0 or more" in str(result.exception) + result.output
