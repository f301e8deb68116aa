"""Relevancy-based early stopping (SPEC 3.4).

Every valid frame gets ``Sim(I_t, Q)``. Against the mean and *sample* standard deviation of the
frames before it, ``z = (Sim_t - mu) / sigma``; the robot stops at the first frame with
``z > z_th``, never before ``min_step``. Statistics are kept incrementally (Welford), so a check
costs the same at step 5 and at step 500.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Z_TH = 3.0
MIN_STEP = 10
STEPS_PER_SQRT_M2 = 3


def step_budget(floor_area_m2: float, per_sqrt_m2: float = STEPS_PER_SQRT_M2) -> int:
    """SPEC 3.1: ``int(sqrt(area) * 3)`` steps, at least 1."""
    if not math.isfinite(floor_area_m2) or floor_area_m2 <= 0:
        raise ValueError(f"floor area must be a positive number of m^2, got {floor_area_m2}")
    return max(1, int(math.sqrt(floor_area_m2) * per_sqrt_m2))


@dataclass(frozen=True)
class StopConfig:
    """``z_th``: the outlier threshold; ``min_step``: no stop before this step; ``enabled``:
    False runs to the budget (the ExploreEQA baselines); ``sigma_eps``: a spread at or below it
    counts as zero (the guard: no z, no stop)."""

    z_th: float = Z_TH
    min_step: int = MIN_STEP
    enabled: bool = True
    sigma_eps: float = 1e-9


@dataclass(frozen=True)
class StopCheck:
    """One frame's check. ``mu``/``sigma`` are over the earlier frames (None until two exist);
    ``z`` is None where sigma is missing or zero; ``threshold`` = mu + z_th * sigma."""

    step: int
    sim: float
    mu: float | None
    sigma: float | None
    z: float | None
    threshold: float | None
    stop: bool


class RelevancyStopper:
    """Feed it one Sim per valid frame, in order; it says when the frame is an outlier."""

    def __init__(self, config: StopConfig | None = None) -> None:
        self.config = config or StopConfig()
        self.n = 0
        self._mean = 0.0
        self._m2 = 0.0  # sum of squared deviations from the running mean

    @property
    def mu(self) -> float | None:
        return self._mean if self.n >= 1 else None

    @property
    def sigma(self) -> float | None:
        return math.sqrt(self._m2 / (self.n - 1)) if self.n >= 2 else None

    def check(self, step: int, sim: float) -> StopCheck:
        """Test ``sim`` against the history, then add it to the history."""
        if not math.isfinite(sim):
            raise ValueError(f"relevancy must be finite, got {sim} at step {step}")
        cfg = self.config
        mu, sigma = self.mu, self.sigma
        z = threshold = None
        if mu is not None and sigma is not None:
            threshold = mu + cfg.z_th * sigma
            if sigma > cfg.sigma_eps:
                z = (sim - mu) / sigma
        stop = cfg.enabled and step >= cfg.min_step and z is not None and z > cfg.z_th
        self._add(sim)
        return StopCheck(step, sim, mu, sigma, z, threshold, stop)

    def _add(self, sim: float) -> None:
        self.n += 1
        delta = sim - self._mean
        self._mean += delta / self.n
        self._m2 += delta * (sim - self._mean)
