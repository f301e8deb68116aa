"""The instruments of the steering and stop targets: idle steps (experiments.common.idle_steps) and an
eval run's target rows (experiments.targets.run_targets)."""

from __future__ import annotations

import json
import math

from experiments.common import idle_steps
from experiments.targets import run_targets


def test_an_idle_step_is_the_step_befores_pose_and_view_again():
    poses = [(1.0, 2.0, 0.0), (1.0, 2.0, 0.0),  # step 2: the same view again
             (1.0, 2.0, 2.0),  # a turn is a new view
             (3.0, 2.0, 2.0), (3.004, 2.0, 2.0 + 2 * math.pi),  # step 5: the same, yaw wrapped
             (1.0, 2.0, 0.0)]  # step 1's view again, but not the step before's
    assert idle_steps(poses) == [2, 5]
    assert idle_steps(poses[:1]) == []


def _row(qid: str, category: str, reference: str, steps: int, stop: str, first: int | None,
         score: int, oracle: int | None = 2) -> dict:
    return {"id": qid, "status": "done", "category": category, "reference": reference,
            "steps": steps, "budget": 30, "stop_reason": stop, "oracle_steps": oracle,
            "evidence_first_seen_step": first, "rule": {"score": score}}


def test_run_targets_reads_the_issues_rows_from_episodes(tmp_path):
    rows = [_row("a", "count", "3", 10, "relevancy", 4, 5),
            _row("b", "count", "2", 30, "budget", 12, 1),  # waited to the budget: counted
            _row("c", "count", "4", 6, "relevancy", None, 1),  # never saw it: not a wait
            _row("d", "existence", "no", 3, "explored", None, 1, oracle=None),  # said "yes"
            _row("e", "existence", "no", 8, "searched", None, 5, oracle=None),
            _row("f", "colour", "red", 5, "relevancy", 5, 5)]
    for r, px in zip(rows, (300.0, None, 160.0, None, None, 20.0)):
        if px is not None:
            r["evidence_stop_pixels"] = px
    (tmp_path / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    got = run_targets(tmp_path)
    assert got["count_sight_to_stop_mean"] == (6 + 18) / 2 and got["count_sight_to_stop_n"] == 2
    assert (got["no_answered_no"], got["no_questions"]) == (1, 2)
    assert got["right"] == 3 and got["accuracy_rule"] == 0.5
    assert got["steps_x_oracle"] == (10 + 30 + 6 + 5) / 4 / 2
    assert got["never_seen_before_stop"] == 1 and got["with_evidence"] == 4
    assert got["explored_early"] == ["d"]  # "explored" at step 3: a failure
    assert (got["recorded_stops"], got["recorded_stops_showing_250px"],
            got["recorded_stops_showing_150px"]) == (3, 1, 2)
