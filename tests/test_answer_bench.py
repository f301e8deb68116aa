"""The answer experiment's pure parts (experiments/answer_bench.py): the AUC it reports
(experiments.common.auc) and the category table."""

from __future__ import annotations

import pytest
from scipy.stats import mannwhitneyu

from experiments import answer_bench as bench
from experiments.common import auc


def test_auc_separates_ranks_ties_count_half_and_matches_mann_whitney():
    assert auc([0.9, 0.8, 0.2, 0.1], [True, True, False, False]) == 1.0
    assert auc([0.1, 0.2, 0.8, 0.9], [True, True, False, False]) == 0.0
    assert auc([0.5, 0.5, 0.5], [True, False, True]) == 0.5  # a constant confidence
    assert auc([0.7, 0.5, 0.5, 0.1], [True, True, False, False]) == 0.875
    assert auc([0.3, 0.4], [True, True]) is None  # no wrong answer to compare with
    scores = [0.37, 0.6, 0.37, 0.89, 0.5, 0.37, 0.72, 0.36, 0.6]
    right = [False, True, True, True, False, False, True, False, True]
    u = mannwhitneyu([s for s, r in zip(scores, right) if r],
                     [s for s, r in zip(scores, right) if not r]).statistic
    assert auc(scores, right) == pytest.approx(u / (5 * 4))


def test_category_table_counts_right_of_asked_in_category_order():
    rows = [{"category": "colour", "right": True}, {"category": "count", "right": False},
            {"category": "colour", "right": False}, {"category": "count", "right": True},
            {"category": "count", "right": True}]
    table = bench.category_table(rows)
    assert list(table) == ["count", "colour", "all"]  # absent categories left out
    assert table == {"count": (2, 3), "colour": (1, 2), "all": (3, 5)}
    text = bench.format_table("default", [dict(r, confidence=0.5, seconds=1.0) for r in rows])
    assert "| default | 2/3 | 1/2 | 3/5 (60%) | 0.50 | 1.0 |" in text
