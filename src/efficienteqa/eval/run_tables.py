"""The tables of runs side by side (the paper's Table I in form, per category, cost, evidence,
failures, parse problems, where each run came from) and the accuracy-against-steps figure, as
document blocks (``Table``, ``Figure``, ``Section``) that ``eval.tables`` renders in Markdown and
HTML. Every table carries its provenance: the back-ends, the newest episode and the code."""

from __future__ import annotations

import math
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from efficienteqa.eval.plots import xy_svg
from efficienteqa.eval.summary import BACKEND_KEYS, RunSummary

SEMANTIC_SENSOR = "semantic-sensor"
SEMANTIC_SHORT = "reads the simulator's object labels, not pixels: not image-model numbers"
PIXELS = "pixels"
PIXELS_SHORT = ("reads RGB-D through the project's own network, trained on its synthetic renders: "
                "not figures of a pretrained image model")
EVIDENCE_NOTE = ("Computed after each episode from the ground truth (the agent never sees it): a "
                 "frame shows the evidence when every evidence object covers the oracle's pixel "
                 "threshold. First seen and first seen / oracle are over the episodes that saw it; "
                 "never seen and in top-K (the frames the answer read) over every episode whose "
                 "question has evidence.")
STOP_ORDER = ("relevancy", "budget", "explored", "none")


# --- the document ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Table:
    caption: str
    header: list[str]
    rows: list[list[str]]
    notes: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Figure:
    name: str  # the .svg file beside report.md
    caption: str
    svg: str


@dataclass
class Section:
    title: str
    blocks: list[Table | Figure | str] = field(default_factory=list)


# --- numbers as text -------------------------------------------------------------------------------


def num(value: float, digits: int = 2) -> str:
    return "-" if math.isnan(value) else f"{value:.{digits}f}"


def utc_date(unix_s: float | None) -> str:
    return "-" if unix_s is None else time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(unix_s))


def slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "-", text).strip("-").lower() or "runs"


def provenance(summaries: Sequence[RunSummary]) -> list[str]:
    """The note under a table: its back-ends (every distinct value where runs differ, with what
    semantic-sensor perception means), the newest episode and the code."""
    names = {"vlm": "VLM", "explore_scorer": "explore scorer"}
    parts = []
    for key in (*BACKEND_KEYS, "judge"):
        if key == "grouping":
            continue
        values = sorted({v for s in summaries for v in s.backends.get(key, [])})
        if key in ("explore_scorer", "answer", "sightings") and not values:  # recorded before them
            continue
        text = f"{names.get(key, key)} {', '.join(values) or '-'}"
        if key == "perception" and SEMANTIC_SENSOR in values:
            text += f" ({SEMANTIC_SHORT})"
        if key == "perception" and PIXELS in values:
            text += f" ({PIXELS_SHORT})"
        parts.append(text)
    newest = max((s.newest for s in summaries if s.newest is not None), default=None)
    codes = sorted({s.code_version for s in summaries})
    return [f"Back-ends: {'; '.join(parts)}. Newest episode: {utc_date(newest)}. Code: {', '.join(codes)}."]

# --- tables ----------------------------------------------------------------------------------------


RULE_HEADER = "Rule-judge accuracy (%) ↑"


def episodes_cell(s: RunSummary) -> str:
    rule = f"{s.n_rule} rule-graded, " if s.n_rule else ""
    return f"{s.n} ({rule}{s.n_judged} judged, {s.n_failed} failed)"


def any_ruled(summaries: Sequence[RunSummary]) -> bool:
    """Whether any run was graded by the rule judge: its tables then show both scores."""
    return any(s.n_rule for s in summaries)


def table_one(summaries: Sequence[RunSummary], labels: Sequence[str]) -> Table:
    """The paper's Table I in form, one row per run in the order given; rule-judge accuracy
    beside LLM-Match where the runs have it."""
    ruled = any_ruled(summaries)
    rows = [[lab, *([num(s.rule_accuracy)] if ruled else []), num(s.llm_match), num(s.mean_steps),
             num(s.steps_over_oracle), episodes_cell(s)]
            for s, lab in zip(summaries, labels)]
    return Table("Methods compared (the paper's Table I)",
                 ["Method", *([RULE_HEADER] if ruled else []), "LLM-Match (%) ↑", "Avg steps ↓",
                  "Steps / oracle ↓", "Episodes"],
                 rows, provenance(summaries))


def category_table(summaries: Sequence[RunSummary], labels: Sequence[str], rule: bool = False) -> Table:
    """LLM-Match (``rule``: rule-judge accuracy) per question category; the header carries n when
    every run has the same."""
    categories = sorted({c for s in summaries for c in s.by_category})
    header = ["Method"]
    for c in categories:
        ns = {s.n_by_category.get(c, 0) for s in summaries}
        header.append(f"{c} (n={ns.pop()})" if len(ns) == 1 else c)
    uniform = all(len({s.n_by_category.get(c, 0) for s in summaries}) == 1 for c in categories)
    rows = []
    for s, lab in zip(summaries, labels):
        cells = [lab]
        values = s.rule_by_category if rule else s.by_category
        for c in categories:
            if c not in values:
                cells.append("-")
            else:
                cells.append(num(values[c]) + ("" if uniform else f" (n={s.n_by_category[c]})"))
        rows.append(cells)
    name = "Rule-judge accuracy" if rule else "LLM-Match"
    return Table(f"{name} (%) per question category", header, rows, provenance(summaries))


def efficiency_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> Table:
    """What each run cost: how episodes ended, model calls and tokens, dollars, time."""
    reasons = sorted({r for s in summaries for r in s.stop_reasons},
                     key=lambda r: (STOP_ORDER.index(r) if r in STOP_ORDER else len(STOP_ORDER), r))
    header = ["Method", "Done", "Failed", *(f"Stop: {r}" for r in reasons), "Calls / ep",
              "Tokens / ep (prompt + completion)", "Model s / ep", "Cached calls",
              "$ / ep ($ in all)", "Wall s / ep (median)"]
    rows = []
    for s, lab in zip(summaries, labels):
        tokens = ("-" if math.isnan(s.tokens) else
                  f"{s.tokens:.0f} ({s.prompt_tokens:.0f} + {s.completion_tokens:.0f})")
        cached = "-" if math.isnan(s.cached_fraction) else f"{100 * s.cached_fraction:.0f}%"
        dollars = ("unknown (a model without a listed price)" if s.cost_per_episode is None
                   else f"{s.cost_per_episode:.4f} ({s.cost_usd:.2f})")
        rows.append([lab, str(s.n_done), str(s.n_failed), *(str(s.stop_reasons.get(r, 0)) for r in reasons),
                     num(s.calls, 1), tokens, num(s.model_latency_s, 1), cached, dollars,
                     f"{num(s.wall_s_mean, 1)} ({num(s.wall_s_median, 1)})"])
    return Table("Cost per episode: stop reasons, model calls, tokens, dollars, wall time", header, rows,
                 provenance(summaries))


def evidence_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> Table | None:
    """When the evidence was first in view (ground truth, after the episode) and refused moves;
    None when no run has ground truth on its evidence."""
    if not any(s.n_evidence for s in summaries):
        return None

    def pct(v: float) -> str:
        return "-" if math.isnan(v) else f"{100 * v:.0f}%"

    rows = [[lab, num(s.first_seen_mean), num(s.first_seen_over_oracle), pct(s.never_seen),
             pct(s.evidence_in_top_k), pct(s.refused_per_step), str(s.n_evidence)]
            for s, lab in zip(summaries, labels)]
    return Table("Evidence in view: first-seen step, against the oracle, never seen",
                 ["Method", "First seen, step ↓", "First seen / oracle ↓", "Never seen ↓",
                  "Evidence in top-K ↑", "Refused moves / step ↓", "Episodes with evidence"],
                 rows, [EVIDENCE_NOTE, *provenance(summaries)])


def failures_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> Table | None:
    rows = [[lab, error, str(count)] for s, lab in zip(summaries, labels)
            for error, count in list(s.errors.items())[:5]]
    if not rows:
        return None
    return Table("Failures (the five commonest errors per run)", ["Method", "Error", "Episodes"], rows,
                 provenance(summaries))


def problems_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> Table | None:
    """Model replies that were not read plainly, per kind of call; None when no run counts any."""
    kinds = ("explore", "relevancy", "answer")
    if not any(s.problems for s in summaries):
        return None
    rows = [[lab, *(str(s.problems.get(k, 0)) if s.problems else "-" for k in kinds), str(s.n_done)]
            for s, lab in zip(summaries, labels)]
    return Table("Replies not read plainly (parse problems, summed over the episodes)",
                 ["Method", "Explore calls", "Relevancy and gate calls", "Answer calls", "Episodes"],
                 rows, provenance(summaries))


def runs_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> Table:
    """Where every row came from, and whether the run is complete and intact."""
    rows = []
    for s, lab in zip(summaries, labels):
        planned = "-" if s.planned is None else str(s.planned)
        torn = f"{s.torn} skipped" if s.torn else "0"
        rows.append([lab, s.source, f"{s.n} of {planned}", torn, s.code_version])
    return Table("Runs", ["Method", "Folder", "Episodes", "Torn lines", "Code"], rows,
                 provenance(summaries))


def accuracy_figure(summaries: Sequence[RunSummary], labels: Sequence[str], prefix: str) -> Figure:
    """LLM-Match (rule-judge accuracy where every run has it) against average steps, one
    labelled point per run; a run that took no steps (the Blind LLM) is a dashed level line."""
    rule = all(s.n_rule for s in summaries) and bool(summaries)
    name = "Rule-judge accuracy" if rule else "LLM-Match"

    def score(s: RunSummary) -> float:
        return s.rule_accuracy if rule else s.llm_match

    points = [(s.mean_steps, score(s), lab) for s, lab in zip(summaries, labels)
              if not math.isnan(s.mean_steps)]
    levels = [(score(s), lab) for s, lab in zip(summaries, labels) if math.isnan(s.mean_steps)]
    return Figure(f"{prefix}-accuracy-steps.svg", f"{name} vs average steps (up and left is better)",
                  xy_svg(points, x_label="Avg steps", y_label=f"{name} (%)", levels=levels))
