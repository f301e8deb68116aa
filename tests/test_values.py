"""Semantic value map: running average, disk radius, smoothing; LSV and GSV formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest

from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.values import SemanticValueMap, gsv_from_yes, lsv_from_confidences

GRID = GridSpec((0.0, 0.0), 0.1, (40, 50))  # 5 m x 4 m


def _within(xy: tuple[float, float], radius_m: float) -> np.ndarray:
    x, y = GRID.centres()
    return (x - xy[0]) ** 2 + (y - xy[1]) ** 2 <= radius_m ** 2


def test_paint_is_a_running_average_on_overlapping_disks():
    vm = SemanticValueMap(GRID)
    vm.paint([(2.0, 2.0)], [1.0])
    vm.paint(np.array([[2.8, 2.0]]), np.array([0.0]))
    a, b = _within((2.0, 2.0), 1.0), _within((2.8, 2.0), 1.0)
    raw = vm.raw
    assert (a & b).any() and (a & ~b).any() and (b & ~a).any()
    np.testing.assert_allclose(raw[a & b], 0.5)
    np.testing.assert_allclose(raw[a & ~b], 1.0)
    np.testing.assert_allclose(raw[b & ~a], 0.0)
    assert (raw[~(a | b)] == 0).all() and (vm.count[~(a | b)] == 0).all()
    assert (vm.count[a & b] == 2).all()


def test_paint_respects_radius_and_several_points_in_one_call():
    vm = SemanticValueMap(GRID, radius_m=0.55)
    vm.paint([(1.0, 1.0), (3.5, 2.5)], [0.4, 0.9])
    np.testing.assert_array_equal(vm.count > 0, _within((1.0, 1.0), 0.55) | _within((3.5, 2.5), 0.55))
    assert vm.raw[_within((1.0, 1.0), 0.55)].max() == pytest.approx(0.4)


def test_paint_near_and_beyond_the_border():
    vm = SemanticValueMap(GRID)
    vm.paint([(0.1, 0.1), (100.0, 100.0)], [1.0, 1.0])
    assert vm.count[0, 0] == 1 and vm.count.sum() == _within((0.1, 0.1), 1.0).sum()
    with pytest.raises(ValueError):
        vm.paint([(1.0, 1.0)], [1.0, 2.0])


def test_smoothing_spreads_keeps_the_total_and_is_memoised():
    vm = SemanticValueMap(GRID)
    vm.paint([(2.5, 2.0)], [1.0])
    raw, smooth = vm.raw, vm.smoothed()
    assert smooth.sum() == pytest.approx(raw.sum(), rel=1e-6)
    assert smooth.max() < raw.max()
    assert ((smooth > 1e-3) & (raw == 0)).any()  # spread beyond the disk
    assert smooth is not vm.smoothed() and np.array_equal(smooth, vm.smoothed())
    vm.paint([(0.5, 0.5)], [1.0])
    assert not np.array_equal(smooth, vm.smoothed())


def test_lsv_normalises_over_prompted_letters_and_scales_by_point_count():
    lsv = lsv_from_confidences({"A": 60, "B": 30, "C": 10}, ["A", "B", "C"])
    assert lsv == pytest.approx({"A": 0.6, "B": 0.3, "C": 0.1})
    two = lsv_from_confidences({"A": 0.8, "B": 0.2, "C": 0.9}, ["A", "B"])  # C not prompted
    assert two == pytest.approx({"A": 0.8 * 2 / 3, "B": 0.2 * 2 / 3})
    assert lsv_from_confidences({"A": 1.0}, ["A", "B", "C"]) == pytest.approx(
        {"A": 1.0, "B": 0.0, "C": 0.0})
    assert lsv_from_confidences({"A": -1.0, "B": float("nan")}, ["A", "B", "C"]) == pytest.approx(
        {k: 1 / 3 for k in "ABC"})
    assert lsv_from_confidences({}, ["A", "B"]) == pytest.approx({"A": 1 / 3, "B": 1 / 3})
    assert lsv_from_confidences({"A": 1.0}, []) == {}


def test_gsv_formula_and_clamping():
    assert gsv_from_yes(0.0) == pytest.approx(1 / 3)
    assert gsv_from_yes(1.0) == pytest.approx(math.e ** 2 / 3)
    assert gsv_from_yes(0.5) == pytest.approx(math.e / 3)
    assert gsv_from_yes(-0.2) == pytest.approx(1 / 3)
    assert gsv_from_yes(7.0) == pytest.approx(math.e ** 2 / 3)
    assert gsv_from_yes(float("nan")) == pytest.approx(1 / 3)
