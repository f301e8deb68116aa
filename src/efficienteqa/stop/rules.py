"""The stop rules: relevancy-based early stopping (DESIGN 3.4).

Every valid frame gets ``Sim(I_t, Q)``. Against the mean and *sample* standard deviation of the
frames before it, ``z = (Sim_t - mu) / sigma``; the robot stops at the first frame with
``z > z_th``, never before ``min_step``. Under this rule (``paper``) the statistics are kept
incrementally (Welford), so a check costs the same at step 5 and at step 500; the rules beyond
the paper recompute their baseline from the history at each check (a few hundred floats).

Stop rules beyond the paper (DESIGN 8), named by ``StopConfig.rule``; components join with "+":

- ``paper``: DESIGN 3.4 exactly. ``mu``, ``sigma`` = mean, sample std (n-1) of ``Sim_1..Sim_{t-1}``;
  stop at the first ``t >= min_step`` with ``(Sim_t - mu) / sigma > z_th``.
- ``robust``: ``mu`` = median, ``sigma`` = 1.4826 * MAD of the earlier frames (the modified
  z-score of Iglewicz-Hoaglin, ``0.6745 (x - median) / MAD``), so one spike barely moves the
  baseline.
- ``floor``: ``sigma = max(sigma, sigma_floor)``: a flat history does not make a small bump an
  outlier.
- ``lookback``: from ``min_step`` on, the best frame of the whole history ``j = argmax Sim`` is
  tested against all the other frames (leave-one-out ``mu``, ``sigma``), so a spike at step 8
  stops the robot at step 10 if it is still an outlier there.
- ``absolute``: the tested frame also stops the robot, from ``min_step`` on, when its Sim is at
  least ``sim_abs`` whatever the baseline: evidence in view from the first steps raises the
  baseline with it, so it is never an outlier. ``sim_abs`` (0.75) is on MiniLM's scale, like
  ``sigma_floor``; a scorer of another scale needs its own (or a rule without ``absolute``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from efficienteqa.config.knobs import knob
from efficienteqa.stop.gate import GATES

Z_TH = 3.0
PAPER_MIN_STEP = 10  # DESIGN 3.4: never before the 10th step
MIN_STEP = PAPER_MIN_STEP
# The agent's default floor (agent.AgentConfig.stop): its answerability gate keeps a stop off
# frames that cannot answer, so the robot may stop from its second step (DESIGN 9).
GATED_MIN_STEP = 2
STEPS_PER_SQRT_M2 = 3
SIGMA_FLOOR = 0.1  # chosen on training houses 0-20 (experiments/stop_bench.py), MiniLM scale
MAD_TO_SIGMA = 1.4826  # 1 / 0.6745: MAD of a normal sample -> its standard deviation
SIM_ABS = 0.75  # chosen on training houses 0-20 (experiments/stop_bench.py), MiniLM scale
Z_GATED = 1.0  # the threshold for a frame an answerability gate passed (DESIGN 9)
RULE_PARTS = ("lookback", "robust", "floor", "absolute")
# The default: better than "paper" on every measure of experiments/stop_bench.py, chosen on
# training houses 0-20 and checked on held-out houses 2000-2009 (DESIGN 8, results/stop/).
DEFAULT_STOP_RULE = "lookback+robust+floor+absolute"
STOP_RULES = ("paper", "lookback", "robust", "floor", "lookback+floor", "lookback+robust",
              "robust+floor", "lookback+robust+floor", "lookback+robust+floor+absolute")


def rule_parts(rule: str) -> frozenset[str]:
    """The components of a rule name: ``paper`` has none, ``lookback+floor`` two."""
    if rule == "paper":
        return frozenset()
    parts = rule.split("+")
    if not parts or any(p not in RULE_PARTS for p in parts) or len(set(parts)) != len(parts):
        raise ValueError(f"unknown stop rule {rule!r}: use paper or {', '.join(RULE_PARTS)} "
                         "joined by '+'")
    return frozenset(parts)


def baseline(history: list[float] | np.ndarray, robust: bool = False,
             sigma_floor: float = 0.0) -> tuple[float | None, float | None]:
    """``(mu, sigma)`` of ``history``: mean and sample std (n-1), or with ``robust`` the median
    and ``1.4826 * median(|x - median|)``; sigma raised to ``sigma_floor``. None until two
    values exist."""
    x = np.asarray(history, dtype=float)
    if len(x) < 2:
        return (float(x[0]) if len(x) else None), None
    if robust:
        mu = float(np.median(x))
        sigma = MAD_TO_SIGMA * float(np.median(np.abs(x - mu)))
    else:
        mu, sigma = float(x.mean()), float(x.std(ddof=1))
    return mu, max(sigma, sigma_floor)


def zscore(sim: float, mu: float | None, sigma: float | None, eps: float = 1e-9) -> float | None:
    """``(sim - mu) / sigma``; None where sigma is missing or at most ``eps`` (the guard)."""
    if mu is None or sigma is None or sigma <= eps:
        return None
    return (sim - mu) / sigma


def step_budget(floor_area_m2: float, per_sqrt_m2: float = STEPS_PER_SQRT_M2) -> int:
    """DESIGN 3.1: ``int(sqrt(area) * 3)`` steps, at least 1."""
    if not math.isfinite(floor_area_m2) or floor_area_m2 <= 0:
        raise ValueError(f"floor area must be a positive number of m^2, got {floor_area_m2}")
    return max(1, int(math.sqrt(floor_area_m2) * per_sqrt_m2))


def env_step_budget(env: object) -> int | None:
    """The step budget of an episode in a simulated scene, the one place it is computed:
    ``step_budget`` of the environment's ``budget_area_m2`` where it names one (Habitat: by its
    ``budget_area`` option, ExploreEQA's x-z bounding box of the whole navmesh unless asked
    for the floor), else of its ``floor_area_m2`` (the synthetic houses). None for an
    environment that knows no area (a robot, a recording). The evaluation reads it, never the
    agent."""
    area = getattr(env, "budget_area_m2", None)
    if area is None:
        area = getattr(env, "floor_area_m2", None)
    return None if area is None else step_budget(float(area))


COUNT_FROM = ("instances", "views")  # StopConfig.count_from
QUESTION_WORDS = ("asked", "perceived")  # StopConfig.question_words


@dataclass(frozen=True)
class StopConfig:
    """The stop module's knobs (DESIGN 3.4), with the answerability gate beyond the paper
    (DESIGN 9). Which threshold acts: with no gate, or the ``model`` gate (asked only once a
    frame is an outlier), a frame stops at z > ``z_th``; a gate that judges every frame
    (``rules``, ``sightings``, and ``auto`` where it picks one of those) stops a frame it passed
    at z > ``z_gated`` and never one it turned down (``z_th_acts``)."""

    z_th: float = knob(Z_TH, help="The relevancy z-score a frame must exceed to stop the robot "
                       "(the paper's Z_th), with no gate or the model gate; refused with a gate "
                       "that judges every frame (see stop.z_gated).")
    min_step: int = knob(MIN_STEP, alias="min_stop_step", help="Never stop before this step "
                         f"(the agent's default {GATED_MIN_STEP}; the paper's: {PAPER_MIN_STEP}).")
    enabled: bool = knob(True, alias="early_stop", off="no_early_stop",
                         help="Stop early by relevancy (off: explore to the budget).")
    sigma_eps: float = knob(1e-9, help="A spread of earlier Sims at or below this counts as "
                            "zero: no z, no stop.")
    rule: str = knob(DEFAULT_STOP_RULE, alias="stop_rule", help="paper (DESIGN 3.4: mean and "
                     "std of the earlier frames) | lookback | robust | floor | absolute, or "
                     "parts joined by '+'.")
    sigma_floor: float = knob(SIGMA_FLOOR, beyond=True, help="The spread's floor under rules "
                              "with 'floor' (fitted to MiniLM's scale on training houses).")
    sim_abs: float = knob(SIM_ABS, beyond=True, help="The Sim that stops outright under rules "
                          "with 'absolute' (MiniLM's scale).")
    z_gated: float = knob(Z_GATED, beyond=True, help="The z-score a frame that a gate judging "
                          "every frame (rules, sightings: the default) passed must exceed to "
                          "stop the robot; stop.z_th acts elsewhere.")
    gate: str = knob("auto", beyond=True, help="The answerability gate a relevancy stop must "
                     "pass: auto (rules with a perception that describes objects, sightings "
                     "with the VLM's sightings, else model) | rules (the question's target in "
                     "the frame's description) | sightings | model (one yes/no call to the VLM "
                     "per outlier) | none (the paper's stop).")
    gate_final: bool = knob(True, beyond=True, help="Stop at a frame the rules gate finds "
                            "answers outright (a count group wholly in view) without waiting for "
                            "a relevancy outlier.")
    question_words: str = knob("perceived", beyond=True, help="The question the relevancy "
                               "scores frames against: asked (as the user typed it, the paper's) "
                               "| perceived (slips "
                               "mended, rooms by their canonical names, the phrases the target "
                               "resolved to categories in the perception's words: 'the couch in "
                               "the lounge' scores as 'the sofa in the living room').")
    count_from: str = knob("instances", beyond=True, help="Where a count question's group "
                           "comes from, for the gate and the direct answer's count: instances "
                           "(the episode's instance map, each object once over all views: "
                           "mapping/instances.py) | views (each frame's sightings, members "
                           "merged across views by place).")

    def __post_init__(self) -> None:
        rule_parts(self.rule)  # raises on an unknown name
        if self.gate not in GATES:
            raise ValueError(f"gate must be one of {GATES}, not {self.gate!r}")
        if self.question_words not in QUESTION_WORDS:
            raise ValueError(f"question_words must be one of {QUESTION_WORDS}, not "
                             f"{self.question_words!r}")
        if self.count_from not in COUNT_FROM:
            raise ValueError(f"count_from must be one of {COUNT_FROM}, not {self.count_from!r}")
        for name in ("z_th", "z_gated", "sigma_floor", "sim_abs"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be a finite number, got {getattr(self, name)}")


def gated_stop() -> StopConfig:
    """The agent's default stop: the gated floor (``min_step`` 2), since the default gate judges
    every frame (DESIGN 9); the paper's floor of 10 is ``StopConfig``'s own default."""
    return StopConfig(min_step=GATED_MIN_STEP)


@dataclass(frozen=True)
class StopCheck:
    """One frame's check. ``mu``/``sigma`` are over the earlier frames (None until two exist);
    ``z`` is None where sigma is missing or zero. ``z_applied``: the threshold that acted on the
    tested frame, ``z_th``, or ``z_gated`` where an answerability gate passed it (None where the
    gate turned it down: it cannot stop the robot); ``threshold`` = mu + z_applied * sigma, the
    Sim the tested frame had to exceed. ``tested_step``: the frame tested (the current one, or
    under ``lookback`` the best so far, with ``mu``/``sigma`` over all the other frames)."""

    step: int
    sim: float
    mu: float | None
    sigma: float | None
    z: float | None
    threshold: float | None
    stop: bool
    tested_step: int | None = None
    z_applied: float | None = None


def applied_z(config: StopConfig, eligible: bool | None) -> float | None:
    """The z-score threshold for a frame with the gate's verdict ``eligible``: ``z_th`` without
    a verdict (no gate, or a gate asked only after the stop rule flagged the frame), ``z_gated``
    where the gate passed it, None where it turned it down (it cannot stop the robot)."""
    if eligible is None:
        return config.z_th
    return config.z_gated if eligible else None


def z_th_acts(gate: str) -> bool:
    """Whether ``z_th`` can decide a stop with the answerability gate ``gate`` (``stop.gate.GATES``):
    not where the gate judges every frame first (``auto``, ``rules``, ``sightings``), since each
    frame then stops at ``z_gated`` or not at all."""
    return gate in ("none", "model")


class RelevancyStopper:
    """Feed it one Sim per valid frame, in order; it says when the frame is an outlier."""

    def __init__(self, config: StopConfig | None = None) -> None:
        self.config = config or StopConfig()
        self.parts = rule_parts(self.config.rule)
        self.history: list[tuple[int, float]] = []
        self.eligible: list[bool | None] = []  # per frame: the gate's verdict (None: no gate)
        self.n = 0
        self._mean = 0.0
        self._m2 = 0.0  # sum of squared deviations from the running mean

    @property
    def mu(self) -> float | None:
        return self._mean if self.n >= 1 else None

    @property
    def sigma(self) -> float | None:
        return math.sqrt(self._m2 / (self.n - 1)) if self.n >= 2 else None

    def check(self, step: int, sim: float, eligible: bool | None = None) -> StopCheck:
        """Test ``sim`` against the history, then add it to the history. ``eligible``: an
        answerability gate's verdict on the frame (None: no gate). False: the frame cannot
        answer, so it never stops the robot, and under ``lookback`` the best frame the gate
        passed is the one tested; its Sim still enters the baseline. True: the frame stops the
        robot at the lower threshold ``z_gated`` (the gate has said it answers; relevancy only
        has to place it above the typical frame)."""
        if not math.isfinite(sim):
            raise ValueError(f"relevancy must be finite, got {sim} at step {step}")
        cfg = self.config
        if self.parts:
            return self._check_beyond(step, sim, eligible)
        mu, sigma = self.mu, self.sigma
        z_th = applied_z(cfg, eligible)
        z = threshold = None
        if mu is not None and sigma is not None:
            threshold = mu + z_th * sigma if z_th is not None else None
            if sigma > cfg.sigma_eps:
                z = (sim - mu) / sigma
        stop = (cfg.enabled and z_th is not None and step >= cfg.min_step and z is not None
                and z > z_th)
        self._add(step, sim, eligible)
        return StopCheck(step, sim, mu, sigma, z, threshold, stop, step, z_th)

    def _check_beyond(self, step: int, sim: float, eligible: bool | None) -> StopCheck:
        cfg = self.config
        robust = "robust" in self.parts
        floor = cfg.sigma_floor if "floor" in self.parts else 0.0
        sims = [s for _, s in self.history]
        tested, value, others = step, sim, sims
        ok = eligible
        if "lookback" in self.parts and step >= cfg.min_step and sims:
            every = sims + [sim]
            verdicts = self.eligible + [eligible]
            allowed = np.array([v is not False for v in verdicts])
            j = int(np.argmax(np.where(allowed, every, -np.inf)))  # the first of equal maxima
            ok = verdicts[j]
            tested = self.history[j][0] if j < len(sims) else step
            value, others = every[j], every[:j] + every[j + 1:]
        mu, sigma = baseline(others, robust, floor)
        z = zscore(value, mu, sigma, cfg.sigma_eps)
        z_th = applied_z(cfg, ok)
        threshold = (mu + z_th * sigma if mu is not None and sigma is not None
                     and z_th is not None else None)
        outlier = z is not None and z_th is not None and z > z_th
        high = "absolute" in self.parts and value >= cfg.sim_abs
        stop = cfg.enabled and ok is not False and step >= cfg.min_step and (outlier or high)
        self._add(step, sim, eligible)
        return StopCheck(step, sim, mu, sigma, z, threshold, stop, tested, z_th)

    def _add(self, step: int, sim: float, eligible: bool | None = None) -> None:
        self.history.append((step, sim))
        self.eligible.append(eligible)
        self.n += 1
        delta = sim - self._mean
        self._mean += delta / self.n
        self._m2 += delta * (sim - self._mean)
