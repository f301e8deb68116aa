"""The steering benchmark's summary (experiments.explore_bench.method_summary): an explorer that
ends "explored" before step 5 failed (its map held no frontier), it is not a fast episode."""

from __future__ import annotations

from experiments.explore_bench import EXPLORED_EARLY_STEP, method_summary


def _row(qid: str, explored: list[int | None], first_seen: list[int | None]) -> dict:
    n = len(explored)
    return {"id": qid, "house": 129, "oracle": 2, "budget": 30,
            "frontier-only": {"first_seen": first_seen, "explored": explored,
                              "steps": [e or 30 for e in explored], "refused": [0] * n,
                              "coverage": [0.5] * n}}


def test_an_explored_stop_before_step_5_is_counted_as_a_failure():
    rows = [_row("a", [EXPLORED_EARLY_STEP - 1, None], [None, 3]),
            _row("b", [EXPLORED_EARLY_STEP, 12], [None, None]),
            _row("c", [None, None], [2, 2])]
    f = method_summary(rows, "frontier-only", to_budget=False)
    assert f["explored_early_n"] == 1 and f["explored_early_ids"] == ["a"]
    assert f["explored_n"] == 3  # every "explored" stop, early or not
    # The early one never saw the evidence: it counts as the budget + 1, not as its 4 steps.
    assert f["never_n"] == 3 and f["steps"] == (31 + 3 + 31 + 31 + 2 + 2) / 6
