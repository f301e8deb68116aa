"""Means and bootstrap intervals over per-episode values, and the record of a paired difference.

Kept apart from the run's summary (``eval.summary``) because they are plain statistics over
numbers, used also by the comparisons between runs (``eval.compare``) and by experiments that
read episodes themselves. Conventions: means skip missing values (None, NaN) and are NaN when
nothing is left; intervals are 95% bootstrap intervals with a fixed seed, so the same values
give the same interval.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, TypeGuard

CONFIDENCE = 0.95
BOOTSTRAP_RESAMPLES = 9999
BOOTSTRAP_SEED = 0


def mean(values: Iterable[Any]) -> float:
    """The mean of the numbers among ``values`` (None and NaN skipped); NaN when none are left."""
    numbers = [float(v) for v in values if is_number(v)]
    return math.fsum(numbers) / len(numbers) if numbers else math.nan


def median(values: Iterable[Any]) -> float:
    numbers = [float(v) for v in values if is_number(v)]
    return statistics.median(numbers) if numbers else math.nan


def is_number(v: Any) -> TypeGuard[float]:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def mean_interval(values: Sequence[float], confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The ``confidence`` bootstrap interval of the mean of ``values`` (``scipy.stats.bootstrap``,
    BCa, a fixed seed so the same values give the same interval; the percentile interval where
    BCa is undefined). NaN under two values; a point where every value is the same. The values
    are sorted first, so the interval does not depend on their order (a report's row order, a
    benchmark's sorted ids)."""
    numbers = sorted(float(v) for v in values if is_number(v))
    if len(numbers) < 2:
        return math.nan, math.nan
    if max(numbers) == min(numbers):
        return numbers[0], numbers[0]
    import warnings

    import numpy as np
    from scipy.stats import bootstrap

    data = (np.asarray(numbers),)
    for method in ("BCa", "percentile"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ci = bootstrap(data, np.mean, confidence_level=confidence, n_resamples=BOOTSTRAP_RESAMPLES,
                           method=method, rng=np.random.default_rng(BOOTSTRAP_SEED)).confidence_interval
        low, high = float(ci.low), float(ci.high)
        if math.isfinite(low) and math.isfinite(high):
            return low, high
    return math.nan, math.nan


@dataclass(frozen=True)
class PairedDifference:
    """``run`` minus ``reference`` on the episodes both have: accuracy (points, over the ids both
    runs recorded, graded by the judge both share) and steps (over the ids both finished with
    steps), each with its paired bootstrap interval; NaN where the runs share nothing to compare."""

    reference: str
    judge: str
    n: int
    accuracy: float
    accuracy_ci: tuple[float, float]
    n_steps: int
    steps: float
    steps_ci: tuple[float, float]
