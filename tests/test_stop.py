"""The relevancy stopping rule (DESIGN 3.4) on constructed Sim sequences."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from efficienteqa.stop import RelevancyStopper, StopConfig, step_budget


def run(sims, **cfg):
    cfg.setdefault("rule", "paper")  # DESIGN 3.4's rule unless a test names another
    stopper = RelevancyStopper(StopConfig(**cfg))
    return [stopper.check(step, s) for step, s in enumerate(sims, start=1)]


def test_budget_is_three_steps_per_root_square_metre():
    assert step_budget(100.0) == 30
    assert step_budget(120.28) == 32  # int(10.967 * 3) = int(32.9)
    assert step_budget(0.01) == 1
    with pytest.raises(ValueError, match="floor area must be a positive number"):
        step_budget(0.0)
    with pytest.raises(ValueError, match="floor area"):
        step_budget(float("nan"))


def test_no_stop_before_step_ten_however_high_the_outlier():
    sims = [0.1, 0.2, 0.1, 0.2, 50.0, 0.1, 0.2, 0.1, 0.2]
    checks = run(sims)
    assert checks[4].z > 3 and not any(c.stop for c in checks)


@pytest.mark.parametrize("min_step, stops_at", [(10, [10]), (9, [10]), (11, [])])
def test_the_minimum_step_itself_may_stop(min_step, stops_at):
    """An outlier exactly at step ``min_step`` stops ("never before", not "only after")."""
    sims = [0.1, 0.2] * 4 + [0.15, 5.0]  # the outlier is step 10
    checks = run(sims, min_step=min_step)
    assert checks[9].z > 3 and [c.step for c in checks if c.stop] == stops_at


def test_stops_at_the_first_outlier_from_step_ten():
    sims = [0.1, 0.2] * 5 + [0.15, 5.0, 9.0]
    checks = run(sims)
    assert [c.step for c in checks if c.stop] == [12, 13]
    assert checks[11].z > 3


def test_mean_and_sample_std_of_the_earlier_frames_only():
    sims = [0.3, 0.5, 0.4, 0.9]
    c = run(sims)[3]
    assert c.mu == pytest.approx(np.mean(sims[:3]))
    assert c.sigma == pytest.approx(np.std(sims[:3], ddof=1))
    assert c.z == pytest.approx((0.9 - c.mu) / c.sigma)
    assert c.threshold == pytest.approx(c.mu + 3 * c.sigma)


def test_threshold_is_strict():
    # history 0, 1, 2: mu = 1 and sample sigma = 1 exactly, so Sim 4 is exactly z = 3: no stop;
    # a hair above stops.
    at = run([0.0, 1.0, 2.0, 4.0], min_step=1)[-1]
    above = run([0.0, 1.0, 2.0, 4.0 + 1e-9], min_step=1)[-1]
    assert (at.mu, at.sigma, at.z, at.threshold) == (1.0, 1.0, 3.0, 4.0) and not at.stop
    assert above.stop


def test_a_spread_at_the_guard_counts_as_zero():
    # history 0, 1, 2: sigma = 1 exactly; with sigma_eps = 1 there is no z, so no stop
    at = run([0.0, 1.0, 2.0, 9.0], min_step=1, sigma_eps=1.0)[-1]
    assert (at.sigma, at.z, at.threshold, at.stop) == (1.0, None, 4.0, False)
    assert run([0.0, 1.0, 2.0, 9.0], min_step=1, sigma_eps=0.99)[-1].stop


def test_each_check_records_its_step_and_sim():
    checks = run([0.3, 0.5, 0.4])
    assert [(c.step, c.sim) for c in checks] == [(1, 0.3), (2, 0.5), (3, 0.4)]


def test_zero_spread_never_stops():
    checks = run([0.5] * 12 + [0.9])
    assert checks[-1].sigma == 0.0 and checks[-1].z is None and not checks[-1].stop


def test_first_two_frames_have_no_z():
    checks = run([0.1, 0.9, 0.2])
    assert checks[0].mu is None and checks[0].z is None
    assert checks[1].sigma is None and checks[1].z is None
    assert checks[2].z is not None


def test_disabled_and_other_thresholds():
    sims = [0.1, 0.2] * 5 + [0.25]
    z = run(sims)[-1].z
    assert 1 < z < 3
    assert run(sims, z_th=1.0)[-1].stop
    assert not run(sims, z_th=1.0, enabled=False)[-1].stop
    assert run(sims, z_th=1.0, min_step=12)[-1].stop is False


def test_non_finite_relevancy_is_an_error():
    with pytest.raises(ValueError, match="finite"):
        RelevancyStopper().check(1, float("nan"))


@given(st.lists(st.floats(-1e3, 1e3), min_size=3, max_size=60))
def test_incremental_statistics_match_the_batch_ones(sims):
    checks = run(sims)
    for i, c in enumerate(checks[2:], start=2):
        assert c.mu == pytest.approx(np.mean(sims[:i]), abs=1e-6)
        assert c.sigma == pytest.approx(np.std(sims[:i], ddof=1), abs=1e-6)


# Stop rules beyond the paper (DESIGN 8): each on a sequence where it and "paper" disagree.

SPIKE_AT_8 = [0.10, 0.12, 0.11, 0.13, 0.10, 0.12, 0.11, 0.90, 0.12, 0.11, 0.13, 0.12]


def stops(sims, **cfg):
    return [c.step for c in run(sims, **cfg) if c.stop]


def test_paper_misses_a_spike_before_step_ten_and_lookback_stops_at_ten():
    """The README demo's case: the spike at step 8 inflates sigma, paper never fires after it."""
    assert stops(SPIKE_AT_8) == []
    checks = run(SPIKE_AT_8, rule="lookback")
    assert [c.step for c in checks if c.stop] == [10, 11, 12]
    assert checks[9].tested_step == 8 and checks[9].z > 3
    # leave-one-out: the other nine frames' mean and sample std
    others = SPIKE_AT_8[:7] + SPIKE_AT_8[8:10]
    assert checks[9].mu == pytest.approx(np.mean(others))
    assert checks[9].sigma == pytest.approx(np.std(others, ddof=1))


def test_lookback_does_not_stop_on_an_early_frame_that_is_no_outlier():
    sims = [0.1, 0.3, 0.2, 0.35, 0.15, 0.3, 0.25, 0.4, 0.2, 0.3]
    assert stops(sims, rule="lookback") == []


def test_robust_baseline_is_not_inflated_by_an_earlier_spike():
    """After a spike, paper's sigma is large; median/MAD barely moves, so a second spike fires."""
    sims = [0.10, 0.12, 0.11, 0.13, 0.10, 0.95, 0.12, 0.11, 0.13, 0.12, 0.11, 0.60]
    assert stops(sims) == []
    checks = run(sims, rule="robust")
    assert [c.step for c in checks if c.stop] == [12]
    assert checks[11].mu == pytest.approx(np.median(sims[:11]))
    mad = np.median(np.abs(np.array(sims[:11]) - np.median(sims[:11])))
    assert checks[11].sigma == pytest.approx(1.4826 * mad)


def test_floor_under_sigma_stops_a_flat_history_from_firing_on_a_small_bump():
    sims = [0.500, 0.501, 0.500, 0.501, 0.500, 0.501, 0.500, 0.501, 0.500, 0.52]
    assert stops(sims) == [10]  # sigma 5e-4: a 0.02 bump is z ~ 39
    checks = run(sims, rule="floor", sigma_floor=0.02)
    assert not checks[9].stop and checks[9].sigma == pytest.approx(0.02)
    assert stops(sims[:9] + [0.7], rule="floor", sigma_floor=0.02) == [10]  # a real spike does


def test_absolute_stops_on_evidence_in_view_from_the_start_which_is_never_an_outlier():
    sims = [0.80, 0.78, 0.20, 0.81, 0.79, 0.25, 0.80, 0.22, 0.79, 0.80, 0.81]
    assert stops(sims, rule="lookback+robust+floor") == []  # high from the start: no outlier
    checks = run(sims, rule="lookback+robust+floor+absolute")
    assert [c.step for c in checks if c.stop][:1] == [10]  # never before min_step
    assert checks[9].tested_step == 4 and checks[9].z < 3  # the best frame, and not by z
    assert stops(sims, rule="lookback+robust+floor+absolute", sim_abs=0.9) == []
    low = [0.1, 0.3, 0.2, 0.35, 0.15, 0.3, 0.25, 0.4, 0.2, 0.3, 0.74]
    never_z = {"rule": "floor+absolute", "sigma_floor": 1.0}  # z < 1: only Sim can stop
    assert stops(low, **never_z) == []  # just under 0.75
    assert stops(low[:-1] + [0.75], **never_z) == [11]  # at the threshold: stops


def test_the_default_rule_is_the_benchmarked_combination():
    assert StopConfig().rule == "lookback+robust+floor+absolute"
    assert (StopConfig().sigma_floor, StopConfig().sim_abs) == (0.1, 0.75)
    # the README demo's case: a spike before step 10 stops the robot at step 10
    stopper = RelevancyStopper()
    assert [c.step for c in (stopper.check(s, x) for s, x in enumerate(SPIKE_AT_8, 1))
            if c.stop][:1] == [10]


def test_combined_rule_and_unknown_names():
    assert stops(SPIKE_AT_8, rule="lookback+floor") == [10, 11, 12]
    assert stops(SPIKE_AT_8, rule="lookback+robust")[:1] == [10]
    for bad in ("bogus", "lookback+lookback", "paper+floor", ""):
        with pytest.raises(ValueError, match="unknown stop rule"):
            StopConfig(rule=bad)


def test_paper_preset_keeps_the_paper_rule_and_the_option_reaches_the_config():
    from efficienteqa.config.presets import build_config, resolve
    from efficienteqa.errors import EfficientEQAError

    assert resolve({}, "paper").run.stop.rule == "paper"
    assert build_config({"stop_rule": "lookback+floor"}).stop.rule == "lookback+floor"
    assert resolve({"stop.rule": "robust"}, "paper").run.stop.rule == "robust"
    with pytest.raises(EfficientEQAError, match="unknown stop rule"):
        build_config({"stop_rule": "nope"})


def test_with_a_gate_judging_every_frame_z_gated_acts_and_is_the_threshold_recorded():
    """The gate passed every frame: Z_th decides nothing (any value stops at the same step),
    z_gated does, and each check records the threshold that acted."""
    sims = [0.30, 0.32, 0.29, 0.31, 0.30, 0.45, 0.30]

    def stop_at(**options) -> tuple[int | None, list]:
        stopper = RelevancyStopper(StopConfig(min_step=2, **options))
        checks = [stopper.check(t, s, eligible=True) for t, s in enumerate(sims, 1)]
        return next((c.step for c in checks if c.stop), None), checks

    assert stop_at(z_th=1.0)[0] == stop_at(z_th=100.0)[0]
    low, checks = stop_at(z_gated=1.0)
    assert low is not None and stop_at(z_gated=50.0)[0] is None
    assert all(c.z_applied == 1.0 for c in checks if c.mu is not None)
    tested = [c for c in checks if c.threshold is not None]
    assert tested and all(abs(c.threshold - (c.mu + c.sigma)) < 1e-9 for c in tested)
    turned_down = RelevancyStopper(StopConfig(min_step=2)).check(1, 0.3, eligible=False)
    assert turned_down.z_applied is None and turned_down.threshold is None
