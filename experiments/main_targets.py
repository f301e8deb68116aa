"""The main table's targets (results/main-heldout/): EfficientEQA's mean steps over white-box
ExploreEQA's (target <= 0.6) and its accuracy gain (target >= +10 points), paired over the
questions both runs answered, each with a paired bootstrap 95% interval (scipy.stats.bootstrap:
the differences as the report's paired columns, the ratio of mean steps by percentile).

    python -m experiments.main_targets results/main-heldout/default results/main-heldout/explore-eqa
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np
from scipy.stats import bootstrap

from efficienteqa.eval.records import read_run
from efficienteqa.eval.stats import BOOTSTRAP_RESAMPLES, BOOTSTRAP_SEED, CONFIDENCE, mean_interval
from efficienteqa.eval.summary import match_value


def _episodes(run: Path) -> dict[str, dict]:
    _, episodes = read_run(run)
    return {r["id"]: r for r in episodes.rows() if r.get("status") == "done" and r.get("rule")}


def _interval(statistic, *samples: np.ndarray) -> tuple[float, float]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ci = bootstrap(samples, statistic, paired=True, vectorized=False, n_resamples=BOOTSTRAP_RESAMPLES,
                       confidence_level=CONFIDENCE, method="percentile",
                       rng=np.random.default_rng(BOOTSTRAP_SEED)).confidence_interval
    return float(ci.low), float(ci.high)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run", type=Path, help="EfficientEQA's run folder")
    ap.add_argument("reference", type=Path, help="white-box ExploreEQA's run folder")
    args = ap.parse_args()
    ours, ref = _episodes(args.run), _episodes(args.reference)
    ids = sorted(set(ours) & set(ref))
    if len(ids) < 2:
        raise SystemExit(f"error: {len(ids)} questions in both runs; need at least 2")
    steps = np.array([ours[k]["steps"] for k in ids], float), np.array([ref[k]["steps"] for k in ids], float)
    right = (np.array([match_value(ours[k], "rule") / 100 for k in ids]),
             np.array([match_value(ref[k], "rule") / 100 for k in ids]))
    ratio = steps[0].mean() / steps[1].mean()
    r_low, r_high = _interval(lambda a, b: np.mean(a) / np.mean(b), *steps)
    # Differences as the report's paired columns compute them (BCa over per-question differences).
    d_low, d_high = mean_interval(list(steps[0] - steps[1]))
    gain = 100 * (right[0].mean() - right[1].mean())
    g_low, g_high = (100 * v for v in mean_interval(list(right[0] - right[1])))
    # The targets' bar: the point estimate meets the target and the paired interval of the
    # difference excludes 0; whether the interval clears the target itself is printed too.
    steps_met = ratio <= 0.6 and d_high < 0
    gain_met = gain >= 10 and g_low > 0
    print(f"paired questions: {len(ids)}")
    print(f"mean steps: {steps[0].mean():.1f} vs {steps[1].mean():.1f}; difference "
          f"{steps[0].mean() - steps[1].mean():+.1f} [{d_low:+.1f}, {d_high:+.1f}]; ratio {ratio:.3f} "
          f"[{r_low:.3f}, {r_high:.3f}]; target <= 0.6: {'met' if steps_met else 'missed'} "
          f"(the ratio's interval {'is' if r_high <= 0.6 else 'is not'} all below 0.6)")
    print(f"accuracy: {100 * right[0].mean():.1f}% vs {100 * right[1].mean():.1f}%; gain {gain:+.1f} "
          f"points [{g_low:+.1f}, {g_high:+.1f}]; target >= +10: {'met' if gain_met else 'missed'} "
          f"(the interval {'is' if g_low >= 10 else 'is not'} all above +10)")

if __name__ == "__main__":
    main()
