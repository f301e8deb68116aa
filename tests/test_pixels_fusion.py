"""Objects fused over views: an object seen unsure from several poses is described once the
views together are sure of it; one unsure view alone is not enough."""

from __future__ import annotations

import numpy as np

from efficienteqa.perception.pixels.fusion import FUSED_MIN, ObjectEvidence, cell_keys
from efficienteqa.perception.pixels.segment import MIN_CONFIDENCE, PixelClasses, read_frame

CATEGORIES = ("void", "wall", "floor:kitchen", "door", "chair", "sink")
K = np.array([[8.0, 0, 8], [0, 8.0, 4], [0, 0, 1]])
UNSURE = MIN_CONFIDENCE - 0.15  # each view alone drops it, FUSED_MIN / UNSURE views keep it


def _unsure_sink() -> PixelClasses:
    category = np.full((4, 8), 1, np.uint8)
    category[1:3, 2:6] = 5
    return PixelClasses(category, np.zeros_like(category), np.zeros_like(category), CATEGORIES,
                        ("grey",), ("on",), np.full(category.shape, UNSURE, np.float32))


def _sinks(evidence: ObjectEvidence | None) -> int:
    depth = np.full((8, 16), 3.0, np.float32)
    instance, labels = read_frame(_unsure_sink(), depth, K, np.eye(4), evidence=evidence)
    ids = set(np.unique(instance).tolist()) - {0, -1}
    return sum(labels.label(i).category == "sink" for i in ids)


def test_an_object_seen_unsure_in_several_views_is_described(monkeypatch):
    monkeypatch.setattr("efficienteqa.perception.pixels.segment.MIN_REGION_PIXELS", 1)
    evidence = ObjectEvidence()
    needed = int(np.ceil(FUSED_MIN / UNSURE))
    seen = [_sinks(evidence) for _ in range(needed)]
    assert seen == [0] * (needed - 1) + [1]
    assert [_sinks(None) for _ in range(needed)] == [0] * needed  # without fusion, never


def test_a_place_counts_once_per_view():
    evidence = ObjectEvidence()
    keys = cell_keys(np.array([[1.0, 1.0, 0.5], [1.05, 1.0, 0.5]]), 5)
    assert len(keys) == 1
    evidence.add_view([(keys, 0.5), (keys, 0.4)])  # two regions of one view on one place
    assert evidence.support(keys) == 0.5
    evidence.add_view([(keys, 0.3)])
    assert abs(evidence.support(keys) - 0.8) < 1e-9
    other = cell_keys(np.array([[1.0, 1.0, 0.5]]), 4)  # same place, another category
    assert evidence.support(other) == 0.0


def test_cells_are_three_dimensional():
    """A cup on a table and the table under it are different places."""
    low = cell_keys(np.array([[1.0, 1.0, 0.3]]), 5)
    high = cell_keys(np.array([[1.0, 1.0, 0.9]]), 5)
    assert not set(low.tolist()) & set(high.tolist())


def test_fragments_of_one_object_are_one_instance_and_two_objects_stay_two(monkeypatch):
    """A chair cut in two where depth jumps (its back behind its seat) is one chair; two chairs
    a metre apart stay two; door leaves are never merged."""
    from efficienteqa.perception.pixels.segment import FRAGMENT_MERGE_M, merge_fragments

    points = np.zeros((4, 8, 3))
    points[..., 0] = np.arange(8)[None, :] * (FRAGMENT_MERGE_M / 4)  # x grows along a row
    left, near, far = (np.zeros((4, 8), bool) for _ in range(3))
    left[:, 0], near[:, 2], far[:, 7] = True, True, True  # centres 0, 2/4 and 7/4 merge distances
    chair, door = 4, 3
    merged = merge_fragments([(chair, left), (chair, near), (chair, far)], points, door=door)
    assert [(c, int(m.sum())) for c, m in merged] == [(chair, 8), (chair, 4)]
    doors = merge_fragments([(door, left), (door, near)], points, door=door)
    assert len(doors) == 2
    monkeypatch.setattr("efficienteqa.perception.pixels.segment.FRAGMENT_MERGE_M", 0.0)
    assert len(merge_fragments([(chair, left), (chair, near)], points, door=door)) == 2
