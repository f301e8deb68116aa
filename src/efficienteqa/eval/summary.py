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
  the same interval; ``eval.stats``). Paired differences (``eval.compare.paired``) compare two
  runs on the episode ids both finished, with a bootstrap interval over the per-question
  differences.
- Means skip missing values and are NaN when nothing is left, so an empty run never crashes.

A run's settings and its label are ``eval.run_labels``; comparisons between runs (paired
differences, ablation groups, unique labels) are ``eval.compare``.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from efficienteqa.eval.judge import score_value
from efficienteqa.eval.run_labels import label, preset_settings, settings
from efficienteqa.eval.stats import (
    BOOTSTRAP_RESAMPLES,
    BOOTSTRAP_SEED,
    CONFIDENCE,
    PairedDifference,
    is_number,
    mean,
    mean_interval,
    median,
)

# The back-ends a table states, in the order it states them, from the rows' ``backends``.
BACKEND_KEYS = ("environment", "perception", "sightings", "vlm", "relevancy", "grouping",
                "explore_scorer", "answer")
UNCATEGORISED = "(none)"


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
            totals.update({str(k): int(v) for k, v in counts.items() if is_number(v)})
    return dict(totals)


def match_value(row: Mapping[str, Any], key: str = "judge") -> float:
    """One episode's LLM-Match (0-100): its grade's value; 0 when failed or not graded.
    ``key="rule"``: the rule judge's grade, ``key="choice"``: the letter's (100 right, 0 wrong)."""
    judged = row.get(key) if row.get("status") == "done" else None
    if not isinstance(judged, Mapping):
        return 0.0
    value = judged.get("value")
    if is_number(value):
        return float(value)
    score = judged.get("score")
    return score_value(score if isinstance(score, int) else None)


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
              if is_number(r.get("steps")) and is_number(r.get("oracle_steps")) and r["oracle_steps"] > 0]
    usage = [r.get("usage") or {} for r in done]
    calls = sum(u.get("calls") or 0 for u in usage)
    judges = [r["judge"].get("judge") for r in done if isinstance(r.get("judge"), Mapping)]
    backends = {k: _distinct((r.get("backends") or {}).get(k) for r in done) for k in BACKEND_KEYS}
    backends["judge"] = _distinct(judges) or _distinct([manifest.get("judge")])
    if n_rule:
        backends["judge"] = ["rule", *backends["judge"]]
    finished = [float(r["finished"]) for r in rows if is_number(r.get("finished"))]
    planned = manifest.get("questions")
    known = [r for r in done if isinstance(r.get("evidence_in_top_k"), bool)]
    seen = [r for r in known if is_number(r.get("evidence_first_seen_step"))]
    seen_ratios = [r["evidence_first_seen_step"] / r["oracle_steps"] for r in seen
                   if is_number(r.get("oracle_steps")) and r["oracle_steps"] > 0]
    refusing = [r for r in done if is_number(r.get("refused_moves")) and is_number(r.get("steps"))]
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
                       if explored and is_number(r.get("steps"))},
    )


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
