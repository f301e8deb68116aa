"""One evaluation run in numbers: the figures the paper reports (LLM-Match, average steps) and the
ones that say what they cost (steps against the oracle, stop reasons, model calls, tokens, time).

Pure functions over a run's manifest and its episode rows (``records.read_run``), so the same
summary backs the console, the Markdown and the HTML report. Conventions, stated once:

- LLM-Match is the mean over *every* episode of the run: a failed episode, or a done one without
  a grade, scores 0 like a missing answer (DESIGN 3.7). A run with no grade at all has no score
  (NaN): 0 would read as "everything was wrong".
- Rule-judge accuracy (synthetic datasets, ``eval.synthetic_judge``) is the share (%) of *every*
  episode that the rule judge graded right, by the same convention: a failed or ungraded
  episode counts as wrong, and a run without rule grades has none (NaN). It is reported beside
  LLM-Match, not instead of it.
- Letter accuracy (closed-set multiple choice, HM-EQA ``--closed-set``) is the share (%) of every
  episode whose chosen letter is the reference's (the row's ``choice`` grade), by the same
  convention.
- Steps, steps/oracle, stop reasons and model usage are over the done episodes; wall time is over
  every episode that recorded one (a failure costs time too).
- Evidence in view (``report.evidence``) is over the done episodes whose question has ground
  truth (synthetic questions with evidence): the mean first-seen step and the mean per-episode
  ratio first-seen / oracle steps are over the episodes that saw the evidence, the never-seen
  share and the in-top-K share over all of them. Refused moves per step: the moves the
  environment refused over the steps taken, over the done episodes that record them.
- Accuracy, the headline score of a published run (``summary.json``, the README's tables), is
  the rule-judge accuracy where the run has rule grades, else the letter accuracy where it has
  letter grades, else LLM-Match, each with a 95%
  bootstrap interval over the episodes (``scipy.stats.bootstrap``, fixed seed: the same run gives
  the same interval). Paired differences (``paired``) compare two runs on the episode ids both
  finished, with a bootstrap interval over the per-question differences.
- Means skip missing values and are NaN when nothing is left, so an empty run never crashes.
"""

from __future__ import annotations

import math
import statistics
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from functools import cache
from typing import Any, TypeGuard

from efficienteqa.eval.judge import score_value
from efficienteqa.eval.records import RUN_FORMAT, upgrade
from efficienteqa.knobs import flatten

# The back-ends a table states, in the order it states them, from the rows' ``backends``.
BACKEND_KEYS = ("environment", "perception", "sightings", "vlm", "relevancy", "grouping",
                "explore_scorer", "answer")
# Settings that change no result: left out when runs are compared for ablations.
NEUTRAL_SETTINGS = frozenset({"cache"})
# How a setting that differs from the default is written in a label (the paper's symbols).
LABEL_NAMES = {"z_th": "Z_th", "top_k": "K", "max_steps": "budget", "min_step": "min step",
               "sigma_eps": "sigma_eps", "seed": "seed"}
UNCATEGORISED = "(none)"
# Methods that run no agent (the Blind LLM answers the question alone): the agent's settings in
# their run.json change nothing, so their labels leave them out.
AGENTLESS_METHODS = frozenset({"blind"})
CONFIDENCE = 0.95
BOOTSTRAP_RESAMPLES = 9999
BOOTSTRAP_SEED = 0


@dataclass(frozen=True)
class RunSummary:
    """A run's figures. LLM-Match values are 0-100; ``steps_over_oracle`` is the mean per-episode
    ratio ``steps / oracle_steps``; times are seconds per episode; ``newest`` is the finish time
    of the last episode (Unix seconds, None without episodes)."""

    method: str
    dataset: str
    label: str
    source: str
    settings: dict[str, Any]
    n: int
    n_done: int
    n_failed: int
    n_judged: int
    planned: int | None
    torn: int
    llm_match: float
    by_category: dict[str, float]
    n_by_category: dict[str, int]
    mean_steps: float
    steps_over_oracle: float
    n_oracle: int
    stop_reasons: dict[str, int]
    calls: float
    prompt_tokens: float
    completion_tokens: float
    model_latency_s: float
    cached_fraction: float
    wall_s_mean: float
    wall_s_median: float
    backends: dict[str, list[str]]
    code_version: str
    newest: float | None
    errors: dict[str, int] = field(default_factory=dict)
    # Model replies not read plainly, per kind of call (explore, relevancy, answer), summed over
    # the done episodes that record them.
    problems: dict[str, int] = field(default_factory=dict)
    cost_usd: float = 0.0  # dollars of every episode's model calls, failed ones included
    # False where a model of the run (its VLM or judge) is a server's with no listed price
    # (``models.backends.PRICES``): its cost is then unknown, not 0
    priced: bool = True
    rule_accuracy: float = math.nan
    n_rule: int = 0
    rule_by_category: dict[str, float] = field(default_factory=dict)
    n_evidence: int = 0  # done episodes with ground truth on the evidence
    first_seen_mean: float = math.nan
    first_seen_over_oracle: float = math.nan
    never_seen: float = math.nan  # share (0-1) of n_evidence
    evidence_in_top_k: float = math.nan  # share (0-1) of n_evidence
    refused_per_step: float = math.nan
    choice_accuracy: float = math.nan  # 0-100, closed-set letter grades
    n_choice: int = 0
    accuracy_judge: str = ""  # "rule", "choice", "llm-match", or "" when the run has no grade
    accuracy: float = math.nan  # 0-100: rule-judge accuracy, else letter accuracy, else LLM-Match
    accuracy_ci: tuple[float, float] = (math.nan, math.nan)
    relevancy_stops: float = math.nan  # share (0-1) of the done episodes
    # Per episode id (for paired differences; not part of summary.json): the accuracy value
    # (0-100, every episode) and the steps (done episodes that explored).
    episode_accuracy: dict[str, float] = field(default_factory=dict, repr=False, compare=False)
    episode_steps: dict[str, float] = field(default_factory=dict, repr=False, compare=False)
    # The named configuration the run started from and its settings (``preset_settings``), for
    # labels; None for a run that did not record them (format 1). Not part of summary.json.
    preset: str | None = field(default=None, repr=False, compare=False)
    baseline: dict[str, Any] | None = field(default=None, repr=False, compare=False)

    @property
    def cost_per_episode(self) -> float | None:
        """Dollars per episode, None where unknown (a model without a listed price)."""
        return self.cost_usd / self.n if self.priced and self.n else None

    @property
    def tokens(self) -> float:
        """Prompt plus completion tokens per episode."""
        return self.prompt_tokens + self.completion_tokens

    @property
    def evidence_seen(self) -> float:
        """Share (0-1) of the episodes with evidence that ever had it in view."""
        return 1 - self.never_seen


def has_price(spec: Any) -> bool:
    """Whether the dollars of a VLM spec's calls are known: local models and no model cost 0;
    an OpenAI-compatible server's model is known only where ``PRICES`` lists it."""
    from efficienteqa.models.backends import PRICES

    if not isinstance(spec, str) or not spec.startswith("openai:"):
        return True
    return spec.partition(":")[2].partition("@")[0] in PRICES


def _problem_totals(done: Sequence[Mapping[str, Any]]) -> dict[str, int]:
    """Each kind's problems summed over the rows whose ``extra`` counts them (none before the
    counts were recorded: an empty dict, not zeros)."""
    totals: Counter[str] = Counter()
    for r in done:
        counts = (r.get("extra") or {}).get("problems")
        if isinstance(counts, Mapping):
            totals.update({str(k): int(v) for k, v in counts.items() if _is_number(v)})
    return dict(totals)


def mean(values: Iterable[Any]) -> float:
    """The mean of the numbers among ``values`` (None and NaN skipped); NaN when none are left."""
    numbers = [float(v) for v in values if _is_number(v)]
    return math.fsum(numbers) / len(numbers) if numbers else math.nan


def median(values: Iterable[Any]) -> float:
    numbers = [float(v) for v in values if _is_number(v)]
    return statistics.median(numbers) if numbers else math.nan


def _is_number(v: Any) -> TypeGuard[float]:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def mean_interval(values: Sequence[float], confidence: float = CONFIDENCE) -> tuple[float, float]:
    """The ``confidence`` bootstrap interval of the mean of ``values`` (``scipy.stats.bootstrap``,
    BCa, a fixed seed so the same values give the same interval; the percentile interval where
    BCa is undefined). NaN under two values; a point where every value is the same. The values
    are sorted first, so the interval does not depend on their order (a report's row order, a
    benchmark's sorted ids)."""
    numbers = sorted(float(v) for v in values if _is_number(v))
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


def match_value(row: Mapping[str, Any], key: str = "judge") -> float:
    """One episode's LLM-Match (0-100): its grade's value; 0 when failed or not graded.
    ``key="rule"``: the rule judge's grade, ``key="choice"``: the letter's (100 right, 0 wrong)."""
    judged = row.get(key) if row.get("status") == "done" else None
    if not isinstance(judged, Mapping):
        return 0.0
    value = judged.get("value")
    if _is_number(value):
        return float(value)
    score = judged.get("score")
    return score_value(score if isinstance(score, int) else None)


# Settings a method sets itself whatever the options say (eval.methods.method_config): not
# worth naming in its label. ExploreEQA never stops early, so its stop settings do nothing.
_EXPLORE_EQA = {"steering", "gate", "min_step", "z_gated"}
METHOD_SETS: dict[str, set[str]] = {"explore-eqa": _EXPLORE_EQA,
                                    "explore-eqa-blackbox": _EXPLORE_EQA,
                                    "frontier-only": {"steering"}, "random": {"steering"}}


def settings(manifest: Mapping[str, Any]) -> dict[str, Any]:
    """The run's configuration as one flat dict (the agent's sections' fields by their own
    names, which are unique; the stack; the judge): what ablations compare and labels name.
    ``stop.enabled`` becomes ``early_stop``, an override ``sfe.NAME``. An older
    run's settings are read as what they meant (``records.upgrade``)."""
    manifest = upgrade(dict(manifest))
    flat: dict[str, Any] = {}
    for section in (manifest.get("config") or {}).values():
        for key, value in dict(section).items():
            if isinstance(value, Mapping):  # overrides: "sfe.view_gain"
                flat.update({f"{key}.{'.'.join(path)}": v for path, v in flatten(value).items()})
            else:
                flat[key] = value
    if "enabled" in flat:
        flat["early_stop"] = flat.pop("enabled")
    flat.update(dict(manifest.get("stack") or {}))
    for key in ("judge", "closed_set", "assets", "noise"):
        if key in manifest:
            flat[key] = manifest[key]
    return flat


@cache
def _default_settings() -> tuple[tuple[str, Any], ...]:
    from efficienteqa.agent import AgentConfig

    return tuple(settings({"config": asdict(AgentConfig()), "format": RUN_FORMAT}).items())


@cache
def _paper_settings() -> tuple[tuple[str, Any], ...]:
    """The settings in which ``agent.PAPER_CONFIG`` differs from the defaults."""
    from efficienteqa.agent import PAPER_CONFIG

    paper = settings({"config": asdict(PAPER_CONFIG), "format": RUN_FORMAT})
    return tuple((k, paper[k]) for k, default in _default_settings() if paper[k] != default)


def _is_paper_configuration(flat: Mapping[str, Any]) -> bool:
    """Every setting of the paper's configuration, and the VLM's semantic values (DESIGN 3.3)."""
    return (all(k in flat and flat[k] == v for k, v in _paper_settings())
            and flat.get("explore_scorer") == "vlm")


def _fmt_setting(value: Any) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def preset_settings(manifest: Mapping[str, Any]) -> dict[str, Any] | None:
    """The settings (``settings``) of the named configuration the run started from, as the run
    recorded them; None for a run that did not (format 1)."""
    manifest = upgrade(dict(manifest))
    config = manifest.get("preset_config")
    return settings({"config": config, "format": RUN_FORMAT}) if isinstance(config, Mapping) else None


def label(manifest: Mapping[str, Any]) -> str:
    """A short name for tables: the method, the named configuration the run started from, and
    the agent settings the run changed against it ("efficienteqa Z_th=2", "efficienteqa paper
    configuration K=10", "explore-eqa closed-set"). A run that did not record its named
    configuration (format 1) is named by the settings that differ from today's defaults."""
    preset = manifest.get("preset")
    # A setting the run did not record yet is what its time ran with: not a change to name.
    unrecorded = list(upgrade(dict(manifest)).get("unrecorded") or ())
    return settings_label(str(manifest.get("method", "?")), settings(manifest), unrecorded,
                          preset=preset if isinstance(preset, str) else None,
                          baseline=preset_settings(manifest))


# Settings that act only where the steering or a gate reads the question's target.
TARGET_SETTINGS = frozenset({"reading", "matching", "gate_final"})

# How a label names a named configuration: the paper's by this phrase, one named after the
# method or "default" by nothing, any other by its name less the method's ("per-token" for the
# explore-eqa run of configs/explore-eqa-per-token.toml).
PRESET_LABELS = {"paper": "paper configuration", "paper-offline": "paper configuration",
                 "default": ""}


def _preset_label(method: str, preset: str | None) -> str:
    if preset is None or preset == method:
        return ""
    return PRESET_LABELS.get(preset, preset.removeprefix(f"{method}-"))


# The order in which a label names settings: the order flat records gave them (settings added
# late first, as ``records.ADDED_SETTINGS`` put them), so an old run's label reads as it did.
LABEL_ORDER = ("reading", "matching", "gate_final", "step_weight", "explorer", "top_k",
               "max_steps", "seed", "confidence", "answer_at", "refusal_retries",
               "stop_clearance_m", "prompts", "distinct_views", "exploration", "answer",
               "answer_every_step", "answer_probability", "token_answer", "gate", "steering",
               "z_th", "min_step", "early_stop", "sigma_eps", "rule", "sigma_floor", "sim_abs",
               "z_gated")


def _label_rank(key: str) -> int:
    return LABEL_ORDER.index(key) if key in LABEL_ORDER else len(LABEL_ORDER)


def settings_label(method: str, flat: Mapping[str, Any], skip: Iterable[str] = (), *,
                   preset: str | None = None, baseline: Mapping[str, Any] | None = None) -> str:
    """``method`` plus the settings in ``flat`` (``settings``) that differ from ``baseline``,
    the run's named configuration ``preset``'s, leaving out ``skip`` (an ablation table names
    its own variable). ``baseline`` None (a format-1 run): against today's defaults, named
    "paper configuration" where it is the paper's."""
    parts = [method]
    skipped = set(skip) | METHOD_SETS.get(method, set())
    if flat.get("steering") == "none" and flat.get("gate") == "none":
        skipped |= TARGET_SETTINGS  # nothing reads the target: these cannot act
    if method in AGENTLESS_METHODS:
        against: Iterable[tuple[str, Any]] = ()
    elif baseline is not None:
        parts += [p for p in [_preset_label(method, preset)] if p]
        against = baseline.items()
    else:
        if _is_paper_configuration(flat):
            parts.append("paper configuration")
            skipped |= {k for k, _ in _paper_settings()}
        against = _default_settings()
    for key, default in sorted(against, key=lambda kv: _label_rank(kv[0])):
        if key in flat and key not in skipped and flat[key] != default:
            if key == "early_stop":
                parts.append("no early stop" if not flat[key] else "early stop")
            else:
                parts.append(f"{LABEL_NAMES.get(key, key)}={_fmt_setting(flat[key])}")
    if flat.get("closed_set"):
        parts.append("closed-set")
    if flat.get("noise") not in (None, "none"):  # a robot's imperfections in the houses
        parts.append(f"noise={flat['noise']}")
    return " ".join(parts)


# Back-end labels as earlier runs recorded them, and as they read now.
RECORDED_LABELS = {"paper (M verbalized guesses, grouped; SPEC 3.5)":
                   "paper (M verbalized guesses, grouped; DESIGN 3.5)"}


def _distinct(values: Iterable[Any]) -> list[str]:
    return sorted({RECORDED_LABELS.get(str(v), str(v)) for v in values if v not in (None, "")})


def summarise(manifest: Mapping[str, Any], rows: Sequence[Mapping[str, Any]], *, torn: int = 0,
              source: str = "") -> RunSummary:
    """The figures of one run (see the module docstring for what each mean is over). ``torn``:
    unreadable lines skipped in ``episodes.jsonl``; ``source``: where the run was read from."""
    done = [r for r in rows if r.get("status") == "done"]
    values = [match_value(r) for r in rows]
    n_judged = sum(isinstance(r.get("judge"), Mapping) for r in done)
    scored = n_judged > 0
    rule_values = [match_value(r, "rule") for r in rows]
    n_rule = sum(isinstance(r.get("rule"), Mapping) for r in done)
    choice_values = [match_value(r, "choice") for r in rows]
    n_choice = sum(isinstance(r.get("choice"), Mapping) for r in done)

    categories: dict[str, list[float]] = {}
    rule_categories: dict[str, list[float]] = {}
    for r, v, rv in zip(rows, values, rule_values):
        categories.setdefault(str(r.get("category") or UNCATEGORISED), []).append(v)
        rule_categories.setdefault(str(r.get("category") or UNCATEGORISED), []).append(rv)

    # A run in which no episode took a step (the Blind LLM) has no average steps, not 0.
    explored = any((r.get("steps") or 0) > 0 or r.get("stop_reason") is not None for r in done)
    ratios = [r["steps"] / r["oracle_steps"] for r in done
              if _is_number(r.get("steps")) and _is_number(r.get("oracle_steps")) and r["oracle_steps"] > 0]
    usage = [r.get("usage") or {} for r in done]
    calls = sum(u.get("calls") or 0 for u in usage)
    judges = [r["judge"].get("judge") for r in done if isinstance(r.get("judge"), Mapping)]
    backends = {k: _distinct((r.get("backends") or {}).get(k) for r in done) for k in BACKEND_KEYS}
    backends["judge"] = _distinct(judges) or _distinct([manifest.get("judge")])
    if n_rule:
        backends["judge"] = ["rule", *backends["judge"]]
    finished = [float(r["finished"]) for r in rows if _is_number(r.get("finished"))]
    planned = manifest.get("questions")
    known = [r for r in done if isinstance(r.get("evidence_in_top_k"), bool)]
    seen = [r for r in known if _is_number(r.get("evidence_first_seen_step"))]
    seen_ratios = [r["evidence_first_seen_step"] / r["oracle_steps"] for r in seen
                   if _is_number(r.get("oracle_steps")) and r["oracle_steps"] > 0]
    refusing = [r for r in done if _is_number(r.get("refused_moves")) and _is_number(r.get("steps"))]
    taken = sum(r["steps"] for r in refusing)
    kind, accuracy_values = (("rule", rule_values) if n_rule else ("choice", choice_values)
                             if n_choice else ("llm-match", values) if scored else ("", []))
    ids = [str(r.get("id")) for r in rows]

    return RunSummary(
        method=str(manifest.get("method", "?")), dataset=str(manifest.get("dataset", "?")),
        label=label(manifest), source=source, settings=settings(manifest),
        preset=manifest.get("preset") if isinstance(manifest.get("preset"), str) else None,
        baseline=preset_settings(manifest),
        n=len(rows), n_done=len(done), n_failed=len(rows) - len(done), n_judged=n_judged,
        planned=planned if isinstance(planned, int) else None, torn=torn,
        llm_match=mean(values) if scored else math.nan,
        by_category={c: (mean(v) if scored else math.nan) for c, v in sorted(categories.items())},
        n_by_category={c: len(v) for c, v in sorted(categories.items())},
        mean_steps=mean(r.get("steps") for r in done) if explored else math.nan,
        steps_over_oracle=mean(ratios) if explored else math.nan, n_oracle=len(ratios) if explored else 0,
        stop_reasons=dict(Counter(str(r.get("stop_reason") or "none") for r in done).most_common()),
        calls=mean(u.get("calls") for u in usage),
        prompt_tokens=mean(u.get("prompt_tokens") for u in usage),
        completion_tokens=mean(u.get("completion_tokens") for u in usage),
        model_latency_s=mean(u.get("latency_s") for u in usage),
        cached_fraction=(sum(u.get("cached_calls") or 0 for u in usage) / calls if calls else math.nan),
        wall_s_mean=mean(r.get("wall_s") for r in rows), wall_s_median=median(r.get("wall_s") for r in rows),
        backends=backends, code_version=str(manifest.get("code_version") or "?"),
        newest=max(finished) if finished else None,
        errors=dict(Counter(str(r.get("error") or "unknown error") for r in rows
                            if r.get("status") != "done").most_common()),
        problems=_problem_totals(done),
        cost_usd=round(sum(float((r.get("usage") or {}).get("cost_usd") or 0.0) for r in rows), 6),
        priced=all(has_price(spec) for spec in (
            (manifest.get("stack") or {}).get("vlm"), manifest.get("judge"))),
        rule_accuracy=mean(rule_values) if n_rule else math.nan, n_rule=n_rule,
        rule_by_category={c: mean(v) for c, v in sorted(rule_categories.items())} if n_rule else {},
        choice_accuracy=mean(choice_values) if n_choice else math.nan, n_choice=n_choice,
        n_evidence=len(known),
        first_seen_mean=mean(r["evidence_first_seen_step"] for r in seen),
        first_seen_over_oracle=mean(seen_ratios),
        never_seen=1 - len(seen) / len(known) if known else math.nan,
        evidence_in_top_k=mean(float(r["evidence_in_top_k"]) for r in known),
        refused_per_step=sum(r["refused_moves"] for r in refusing) / taken if taken else math.nan,
        accuracy_judge=kind, accuracy=mean(accuracy_values), accuracy_ci=mean_interval(accuracy_values),
        relevancy_stops=(sum(r.get("stop_reason") == "relevancy" for r in done) / len(done)
                         if explored else math.nan),
        episode_accuracy=dict(zip(ids, accuracy_values)),
        episode_steps={str(r.get("id")): float(r["steps"]) for r in done
                       if explored and _is_number(r.get("steps"))},
    )


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


def paired(run: RunSummary, reference: RunSummary, reference_label: str = "") -> PairedDifference:
    """Paired differences of ``run`` against ``reference`` over the questions both answered,
    matched by episode id: the per-question differences, their mean and its bootstrap interval."""
    judge = run.accuracy_judge if run.accuracy_judge == reference.accuracy_judge else ""
    ids = [k for k in run.episode_accuracy if k in reference.episode_accuracy] if judge else []
    accuracy = [run.episode_accuracy[k] - reference.episode_accuracy[k] for k in ids]
    both = [k for k in run.episode_steps if k in reference.episode_steps]
    steps = [run.episode_steps[k] - reference.episode_steps[k] for k in both]
    return PairedDifference(reference=reference_label or reference.label, judge=judge, n=len(ids),
                            accuracy=mean(accuracy), accuracy_ci=mean_interval(accuracy),
                            n_steps=len(both), steps=mean(steps), steps_ci=mean_interval(steps))


def _json_number(value: Any) -> Any:
    if isinstance(value, float):
        return round(value, 6) if math.isfinite(value) else None
    if isinstance(value, (tuple, list)):
        return [_json_number(v) for v in value]
    if isinstance(value, dict):
        return {k: _json_number(v) for k, v in value.items()}
    return value


def summary_record(s: RunSummary, difference: PairedDifference | None = None) -> dict[str, Any]:
    """A run's ``summary.json``: every figure of ``RunSummary`` (NaN as null, shares 0-1, scores
    0-100), without the folder it was read from or the per-episode values, so the file depends on
    the run's files alone; ``difference``: its paired differences against a reference run."""
    record = {k: v for k, v in asdict(s).items()
              if k not in ("source", "episode_accuracy", "episode_steps", "preset", "baseline")}
    record.update(tokens=s.tokens, evidence_seen=s.evidence_seen, confidence=CONFIDENCE,
                  bootstrap={"resamples": BOOTSTRAP_RESAMPLES, "seed": BOOTSTRAP_SEED})
    if difference is not None:
        record["paired"] = asdict(difference)
    return _json_number(record)


def ablations(summaries: Sequence[RunSummary], key: str) -> list[list[RunSummary]]:
    """Groups of at least two runs of one method on one dataset whose settings differ only in
    ``key`` (e.g. "z_th", "top_k"), each sorted by that value: the paper's Tables II and III."""
    groups: dict[tuple[Any, ...], list[RunSummary]] = {}
    for s in summaries:
        if key not in s.settings:
            continue
        rest = tuple(sorted((k, repr(v)) for k, v in s.settings.items()
                            if k != key and k not in NEUTRAL_SETTINGS))
        groups.setdefault((s.dataset, s.method, rest), []).append(s)
    return [sorted(g, key=lambda s: _order(s.settings[key])) for g in groups.values()
            if len({repr(s.settings[key]) for s in g}) > 1]


def _order(value: Any) -> tuple[int, float, str]:
    """Numbers first, ascending; anything else (None: the default budget) after, by name."""
    return (0, float(value), "") if _is_number(value) else (1, 0.0, str(value))


def distinct_labels(summaries: Sequence[RunSummary]) -> list[str]:
    """Each run's label, made unique where two runs share one: first by the back-ends that tell
    them apart (VLM, perception, sightings, relevancy), then by the folder they came from."""
    out = [s.label for s in summaries]
    for keys in (("vlm", "perception", "sightings", "relevancy", "judge"), ("source",)):
        counts = Counter(out)
        for i, s in enumerate(summaries):
            if counts[out[i]] > 1:
                same = [t for t in summaries if t.label == s.label]
                extra = [_shown(k, _lookup(s, k)) for k in keys
                         if len({str(_lookup(t, k)) for t in same}) > 1]
                if extra:
                    out[i] = f"{out[i]} ({', '.join(extra)})"
    return out


def _shown(key: str, value: Any) -> str:
    """A back-end that tells two runs apart, as their labels say it: the judge as "judge X", or
    "rule judge only" where the run had no LLM judge; another missing one as "no KEY"."""
    if key == "judge":
        return f"judge {value}" if value else "rule judge only"
    return f"no {key}" if value is None else str(value)


def _lookup(s: RunSummary, key: str) -> Any:
    return s.source if key == "source" else s.settings.get(key)
