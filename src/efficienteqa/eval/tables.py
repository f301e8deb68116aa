"""``efficienteqa report``: evaluation runs side by side, in Markdown and in one HTML page.

The paper's tables in form — Table I (method | LLM-Match | average steps, plus steps against the
oracle), Tables II and III (the Z_th and K ablations, found by comparing the runs' settings) —
plus what the paper leaves out: LLM-Match per question category, the rule judge's accuracy beside
LLM-Match for synthetic runs (whose accepted answers are known), and the cost of every run (stop
reasons, model calls and tokens, wall time, failures). Plots are SVG drawn here, so reports need
no plotting library; the HTML page inlines them, the Markdown links them as files beside it.

Every table carries the back-ends that produced its numbers and the date of its newest episode:
a number without them cannot be compared with anything. The report is built as a list of
sections of tables, figures and paragraphs once, then rendered twice.

Published runs (``results/``): ``publish_run`` writes a run's ``summary.json`` and its own
``report.html`` into its folder; ``markdown_table`` is the README's table of runs (accuracy with
its bootstrap interval, cost, optional paired differences against a reference run), deterministic
(no dates, no absolute paths); ``regenerate_readme`` rewrites every README block
``<!-- results: efficienteqa report FOLDER... --markdown -->`` ... ``<!-- /results -->`` from its
folders, in-process, so a test can check the README against ``results/``.
"""

from __future__ import annotations

import html
import json
import math
import re
import shlex
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.records import read_run
from efficienteqa.eval.summary import (
    AGENTLESS_METHODS,
    BACKEND_KEYS,
    PairedDifference,
    RunSummary,
    ablations,
    distinct_labels,
    paired,
    settings_label,
    summarise,
    summary_record,
)

SEMANTIC_SENSOR = "semantic-sensor"
SEMANTIC_WARNING = ("Perception is semantic-sensor: the agent reads the simulator's object labels as "
                    "text, not pixels, so these are not image-model numbers.")
SEMANTIC_SHORT = "reads the simulator's object labels, not pixels: not image-model numbers"
CONVENTIONS = ("LLM-Match (%) is the mean over every episode of 100 * (score - 1) / 4; a failed or "
               "ungraded episode scores 0, like a missing answer (DESIGN 3.7). Rule-judge accuracy (%), "
               "for synthetic questions whose accepted answers are known, is the share of every episode "
               "that states an accepted answer and no contradicting one (no model involved; a failed "
               "episode counts as wrong). Average steps, steps / "
               "oracle (the mean per-episode ratio, over episodes with an oracle), stop reasons and "
               "model usage are over the episodes that finished; '-' means not measured.")
EVIDENCE_NOTE = ("Computed after each episode from the ground truth (the agent never sees it): a "
                 "frame shows the evidence when every evidence object covers the oracle's pixel "
                 "threshold. First seen and first seen / oracle are over the episodes that saw it; "
                 "never seen and in top-K (the frames the answer read) over every episode whose "
                 "question has evidence.")
STOP_ORDER = ("relevancy", "budget", "explored", "none")
PLOT_W, PLOT_H, PAD = 540, 340, 56
CSS = """
body{font-family:system-ui,sans-serif;margin:24px auto;max-width:1150px;color:#222;padding:0 12px}
h1{font-size:1.4em} h2{font-size:1.2em;margin-top:2em;border-bottom:2px solid #ccc}
h3{font-size:1.02em;margin:1.6em 0 .4em}
table{border-collapse:collapse;font-size:.9em;margin:4px 0}
th,td{border:1px solid #ddd;padding:3px 9px;text-align:right} th{background:#f3f3f3}
td:first-child,th:first-child,.text{text-align:left}
.note{color:#555;font-size:.85em;margin:2px 0} .warn{color:#a40}
figure{margin:10px 16px 10px 0;display:inline-block;vertical-align:top} figcaption{color:#555;font-size:.85em}
"""


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


def _num(value: float, digits: int = 2) -> str:
    return "-" if math.isnan(value) else f"{value:.{digits}f}"


def _date(unix_s: float | None) -> str:
    return "-" if unix_s is None else time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(unix_s))


def _slug(text: str) -> str:
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
        if key in ("explore_scorer", "answer") and not values:  # runs recorded before them
            continue
        text = f"{names.get(key, key)} {', '.join(values) or '-'}"
        if key == "perception" and SEMANTIC_SENSOR in values:
            text += f" ({SEMANTIC_SHORT})"
        parts.append(text)
    newest = max((s.newest for s in summaries if s.newest is not None), default=None)
    codes = sorted({s.code_version for s in summaries})
    return [f"Back-ends: {'; '.join(parts)}. Newest episode: {_date(newest)}. Code: {', '.join(codes)}."]


# --- tables ----------------------------------------------------------------------------------------


RULE_HEADER = "Rule-judge accuracy (%) ↑"


def _episodes(s: RunSummary) -> str:
    rule = f"{s.n_rule} rule-graded, " if s.n_rule else ""
    return f"{s.n} ({rule}{s.n_judged} judged, {s.n_failed} failed)"


def _ruled(summaries: Sequence[RunSummary]) -> bool:
    """Whether any run was graded by the rule judge: its tables then show both scores."""
    return any(s.n_rule for s in summaries)


def table_one(summaries: Sequence[RunSummary], labels: Sequence[str]) -> Table:
    """The paper's Table I in form, one row per run in the order given; rule-judge accuracy
    beside LLM-Match where the runs have it."""
    ruled = _ruled(summaries)
    rows = [[lab, *([_num(s.rule_accuracy)] if ruled else []), _num(s.llm_match), _num(s.mean_steps),
             _num(s.steps_over_oracle), _episodes(s)]
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
                cells.append(_num(values[c]) + ("" if uniform else f" (n={s.n_by_category[c]})"))
        rows.append(cells)
    name = "Rule-judge accuracy" if rule else "LLM-Match"
    return Table(f"{name} (%) per question category", header, rows, provenance(summaries))


def efficiency_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> Table:
    """What each run cost: how episodes ended, model calls and tokens, time."""
    reasons = sorted({r for s in summaries for r in s.stop_reasons},
                     key=lambda r: (STOP_ORDER.index(r) if r in STOP_ORDER else len(STOP_ORDER), r))
    header = ["Method", "Done", "Failed", *(f"Stop: {r}" for r in reasons), "Calls / ep",
              "Tokens / ep (prompt + completion)", "Model s / ep", "Cached calls",
              "Wall s / ep (median)"]
    rows = []
    for s, lab in zip(summaries, labels):
        tokens = ("-" if math.isnan(s.tokens) else
                  f"{s.tokens:.0f} ({s.prompt_tokens:.0f} + {s.completion_tokens:.0f})")
        cached = "-" if math.isnan(s.cached_fraction) else f"{100 * s.cached_fraction:.0f}%"
        rows.append([lab, str(s.n_done), str(s.n_failed), *(str(s.stop_reasons.get(r, 0)) for r in reasons),
                     _num(s.calls, 1), tokens, _num(s.model_latency_s, 1), cached,
                     f"{_num(s.wall_s_mean, 1)} ({_num(s.wall_s_median, 1)})"])
    return Table("Cost per episode: stop reasons, model calls, tokens, wall time", header, rows,
                 provenance(summaries))


def evidence_table(summaries: Sequence[RunSummary], labels: Sequence[str]) -> Table | None:
    """When the evidence was first in view (ground truth, after the episode) and refused moves;
    None when no run has ground truth on its evidence."""
    if not any(s.n_evidence for s in summaries):
        return None

    def pct(v: float) -> str:
        return "-" if math.isnan(v) else f"{100 * v:.0f}%"

    rows = [[lab, _num(s.first_seen_mean), _num(s.first_seen_over_oracle), pct(s.never_seen),
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


def ablation_blocks(summaries: Sequence[RunSummary], prefix: str) -> list[Table | Figure]:
    """The paper's Tables II (Z_th: LLM-Match and steps) and III (K: LLM-Match) with their curves,
    for every group of runs that differ in that setting alone."""
    blocks: list[Table | Figure] = []
    for key, symbol, with_steps, paper in (("z_th", "Z_th", True, "II"), ("top_k", "K", False, "III")):
        for i, group in enumerate(ablations(summaries, key), 1):
            name = settings_label(group[0].method, group[0].settings, skip=[key])
            suffix = f"-{i}" if i > 1 else ""
            ruled = _ruled(group)
            header = [symbol, *([RULE_HEADER] if ruled else []), "LLM-Match (%) ↑",
                      *(["Avg steps ↓"] if with_steps else []), "Episodes"]
            rows = [[f"{s.settings[key]:g}" if isinstance(s.settings[key], float) else str(s.settings[key]),
                     *([_num(s.rule_accuracy)] if ruled else []), _num(s.llm_match),
                     *([_num(s.mean_steps)] if with_steps else []), _episodes(s)]
                    for s in group]
            blocks.append(Table(f"Ablation over {symbol}: {name} (the paper's Table {paper})",
                                header, rows, provenance(group)))
            xs = [float(s.settings[key]) for s in group]
            plots = [("llm-match", "LLM-Match (%)", [s.llm_match for s in group])]
            if ruled:
                plots.insert(0, ("rule", "Rule-judge accuracy (%)", [s.rule_accuracy for s in group]))
            if with_steps:
                plots.append(("steps", "Avg steps", [s.mean_steps for s in group]))
            for tag, y_label, ys in plots:
                points = [(x, y, "") for x, y in zip(xs, ys)]
                blocks.append(Figure(f"{prefix}-{_slug(key)}{suffix}-{tag}.svg",
                                     f"{y_label} vs {symbol}: {name}",
                                     xy_svg(points, x_label=symbol, y_label=y_label, connect=True)))
    return blocks


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


def build_sections(summaries: Sequence[RunSummary]) -> list[Section]:
    """One section per dataset, in the order the datasets first appear."""
    sections = []
    for dataset in dict.fromkeys(s.dataset for s in summaries):
        runs = [s for s in summaries if s.dataset == dataset]
        labels = distinct_labels(runs)
        prefix = _slug(dataset)
        section = Section(f"Dataset: {dataset}")
        if any(SEMANTIC_SENSOR in s.backends.get("perception", []) for s in runs):
            section.blocks.append(SEMANTIC_WARNING)
        section.blocks += [table_one(runs, labels), accuracy_figure(runs, labels, prefix)]
        if _ruled(runs):
            section.blocks.append(category_table(runs, labels, rule=True))
        section.blocks += [category_table(runs, labels), efficiency_table(runs, labels)]
        evidence = evidence_table(runs, labels)
        if evidence is not None:
            section.blocks.append(evidence)
        for extra in (failures_table(runs, labels), problems_table(runs, labels)):
            if extra is not None:
                section.blocks.append(extra)
        section.blocks += ablation_blocks(runs, prefix)
        section.blocks.append(runs_table(runs, labels))
        sections.append(section)
    return sections


# --- the plot --------------------------------------------------------------------------------------


def _ticks(lo: float, hi: float, target: int = 5) -> tuple[list[float], int]:
    """Round tick values (steps of 1, 2 or 5 times a power of ten) inside [lo, hi], and the
    decimals that print them exactly."""
    raw = (hi - lo) / target
    magnitude = 10.0 ** math.floor(math.log10(raw))
    step = next(m * magnitude for m in (1, 2, 5, 10) if m * magnitude >= raw)
    first = math.ceil(lo / step) * step
    count = int((hi - first) / step + 1e-9) + 1
    return [first + k * step for k in range(count)], max(0, -math.floor(math.log10(step) + 1e-9))


def _span(values: Sequence[float]) -> tuple[float, float]:
    lo, hi = min(values), max(values)
    if hi - lo < 1e-9:
        return lo - 1.0, hi + 1.0
    margin = 0.1 * (hi - lo)
    return lo - margin, hi + margin


def xy_svg(points: Sequence[tuple[float, float, str]], *, x_label: str, y_label: str,
           connect: bool = False, levels: Sequence[tuple[float, str]] = ()) -> str:
    """A scatter (``connect``: a line through the points in order) of (x, y, label) points, with
    optional labelled dashed horizontal ``levels``; points or levels with NaN are left out."""
    pts = [(x, y, lab) for x, y, lab in points if not (math.isnan(x) or math.isnan(y))]
    lvls = [(y, lab) for y, lab in levels if not math.isnan(y)]
    head = (f'<svg xmlns="http://www.w3.org/2000/svg" width="{PLOT_W}" height="{PLOT_H}" '
            f'viewBox="0 0 {PLOT_W} {PLOT_H}" role="img" aria-label="{html.escape(y_label)} vs '
            f'{html.escape(x_label)}" font-family="sans-serif" font-size="11">')
    if not pts and not lvls:
        return (head + f'<text x="{PLOT_W / 2}" y="{PLOT_H / 2}" text-anchor="middle">'
                "no measured value to plot</text></svg>")
    x0, x1 = _span([p[0] for p in pts] or [0.0])
    y0, y1 = _span([p[1] for p in pts] + [y for y, _ in lvls])

    def sx(v: float) -> float:
        return PAD + (PLOT_W - 2 * PAD) * (v - x0) / (x1 - x0)

    def sy(v: float) -> float:
        return PLOT_H - PAD - (PLOT_H - 1.6 * PAD) * (v - y0) / (y1 - y0)

    out = [head, f'<rect x="{PAD}" y="{0.6 * PAD}" width="{PLOT_W - 2 * PAD}" '
                 f'height="{PLOT_H - 1.6 * PAD}" fill="#fafafa" stroke="#ccc"/>']
    y_ticks, y_digits = _ticks(y0, y1)
    for v in y_ticks:
        out.append(f'<text x="{PAD - 5}" y="{sy(v) + 4:.1f}" text-anchor="end">{v:.{y_digits}f}</text>'
                   f'<line x1="{PAD}" x2="{PLOT_W - PAD}" y1="{sy(v):.1f}" y2="{sy(v):.1f}" stroke="#eee"/>')
    if pts:
        x_ticks, x_digits = _ticks(x0, x1)
        for v in x_ticks:
            out.append(f'<text x="{sx(v):.1f}" y="{PLOT_H - PAD + 16}" '
                       f'text-anchor="middle">{v:.{x_digits}f}</text>')
    out.append(f'<text x="{PLOT_W / 2}" y="{PLOT_H - 12}" text-anchor="middle">{html.escape(x_label)}</text>')
    out.append(f'<text x="14" y="{PLOT_H / 2}" transform="rotate(-90 14 {PLOT_H / 2})" '
               f'text-anchor="middle">{html.escape(y_label)}</text>')
    for y, lab in lvls:
        out.append(f'<line x1="{PAD}" x2="{PLOT_W - PAD}" y1="{sy(y):.1f}" y2="{sy(y):.1f}" '
                   f'stroke="#999" stroke-dasharray="6 4"/><text x="{PLOT_W - PAD - 4}" '
                   f'y="{sy(y) - 4:.1f}" text-anchor="end" fill="#666">{html.escape(lab)} '
                   f'(no steps): {y:.1f}</text>')
    if connect and len(pts) > 1:
        path = " ".join(f"{sx(x):.1f},{sy(y):.1f}" for x, y, _ in pts)
        out.append(f'<polyline points="{path}" fill="none" stroke="#369" stroke-width="1.5"/>')
    for x, y, lab in pts:
        tip = html.escape(f"{lab + ': ' if lab else ''}({x:g}, {y:.2f})")
        out.append(f'<circle cx="{sx(x):.1f}" cy="{sy(y):.1f}" r="4" fill="#369">'
                   f'<title>{tip}</title></circle>')
        if lab:  # on the left of points in the right third, so the label stays inside
            right = sx(x) > 0.66 * PLOT_W
            anchor = "end" if right else "start"
            out.append(f'<text x="{sx(x) + (-7 if right else 7):.1f}" y="{sy(y) - 6:.1f}" '
                       f'text-anchor="{anchor}">{html.escape(lab)}</text>')
    out.append("</svg>")
    return "\n".join(out)


# --- rendering -------------------------------------------------------------------------------------


def _md(text: str) -> str:
    """Safe in a Markdown table cell: no pipe, no line break, no raw HTML."""
    return (text.replace("\\", "\\\\").replace("|", "\\|").replace("<", "&lt;")
            .replace(">", "&gt;").replace("\r", " ").replace("\n", " "))


def _numeric(table: Table) -> list[bool]:
    """Which columns hold numbers (right-aligned): every cell starts like one, or is '-'."""
    return [i > 0 and all(re.match(r"-$|[-+]?\d[\d.,]*%?(\s|$)", row[i]) for row in table.rows)
            for i in range(len(table.header))]


def to_markdown(sections: Sequence[Section], intro: Sequence[str]) -> str:
    lines = ["# EfficientEQA evaluation report", "", *(f"{_md(p)}\n" for p in intro)]
    for section in sections:
        lines += [f"## {_md(section.title)}", ""]
        for block in section.blocks:
            if isinstance(block, Table):
                lines += [f"### {_md(block.caption)}", "",
                          "| " + " | ".join(_md(h) for h in block.header) + " |",
                          "|" + "|".join("---:" if numeric else ":---" for numeric in _numeric(block)) + "|",
                          *("| " + " | ".join(_md(c) for c in row) + " |" for row in block.rows), "",
                          *(f"_{_md(note)}_\n" for note in block.notes)]
            elif isinstance(block, Figure):
                lines += [f"![{_md(block.caption)}]({block.name})", ""]
            else:
                lines += [_md(block), ""]
    return "\n".join(lines).rstrip() + "\n"


def to_html(sections: Sequence[Section], intro: Sequence[str]) -> str:
    e = html.escape
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>EfficientEQA evaluation report"
             f"</title><style>{CSS}</style></head><body><h1>EfficientEQA evaluation report</h1>",
             *(f"<p class='note'>{e(p)}</p>" for p in intro)]
    for section in sections:
        parts.append(f"<h2>{e(section.title)}</h2>")
        for block in section.blocks:
            if isinstance(block, Table):
                align = ["" if numeric else " class=text" for numeric in _numeric(block)]
                head = "".join(f"<th{a}>{e(h)}</th>" for a, h in zip(align, block.header))
                body = "".join("<tr>" + "".join(f"<td{a}>{e(c)}</td>" for a, c in zip(align, row)) + "</tr>"
                               for row in block.rows)
                notes = "".join(f"<p class='note'>{e(n)}</p>" for n in block.notes)
                parts.append(f"<h3>{e(block.caption)}</h3><table><thead><tr>{head}</tr></thead>"
                             f"<tbody>{body}</tbody></table>{notes}")
            elif isinstance(block, Figure):
                parts.append(f"<figure>{block.svg}<figcaption>{e(block.caption)}</figcaption></figure>")
            else:
                parts.append(f"<p{' class=warn' if block == SEMANTIC_WARNING else ''}>{e(block)}</p>")
    parts.append("</body></html>")
    return "\n".join(parts)


# --- entry points ----------------------------------------------------------------------------------


def _shown(folder: Path, root: Path) -> str:
    """A folder as tables name it: relative to ``root`` when inside it, else absolute."""
    try:
        return folder.relative_to(root.resolve()).as_posix()
    except ValueError:
        return str(folder)


def run_folders(folders: Sequence[Path], root: Path | None = None) -> list[Path]:
    """The folders resolved (relative ones against ``root``, default the working directory), in
    the order given, a folder given twice once."""
    base = Path.cwd() if root is None else Path(root)
    return list(dict.fromkeys((base / f).resolve() for f in folders))


def read_summaries(folders: Sequence[Path], root: Path | None = None) -> list[RunSummary]:
    """Each run folder summarised, in the order given (a folder given twice counts once); a
    run's ``source`` is its folder relative to ``root`` (default the working directory) when
    inside it. A folder that is not a run raises ``read_run``'s one-line error."""
    base = Path.cwd() if root is None else Path(root)
    out = []
    for folder in run_folders(folders, base):
        manifest, episodes = read_run(folder)
        out.append(summarise(manifest, episodes.rows(), torn=episodes.torn + episodes.foreign,
                             source=_shown(folder, base)))
    return out


def overview_rows(summaries: Sequence[RunSummary]) -> tuple[list[str], list[list[str]]]:
    """Table I for an 80-column console: dataset, method, rule-judge accuracy (where any run has
    it), LLM-Match, steps, steps / oracle, and episodes done of those run."""
    ruled = _ruled(summaries)
    rows = []
    for dataset in dict.fromkeys(s.dataset for s in summaries):
        runs = [s for s in summaries if s.dataset == dataset]
        rows += [[dataset, lab, *([_num(s.rule_accuracy)] if ruled else []), _num(s.llm_match),
                  _num(s.mean_steps), _num(s.steps_over_oracle), f"{s.n_done}/{s.n}"]
                 for s, lab in zip(runs, distinct_labels(runs))]
    return ["Dataset", "Method", *(["Rule %"] if ruled else []), "LLM-Match", "Steps",
            "Steps/oracle", "Done"], rows


def _intro(summaries: Sequence[RunSummary], stamp: bool) -> list[str]:
    written = f", written {_date(time.time())}" if stamp else ""
    intro = [f"{len(summaries)} run(s){written}.", CONVENTIONS]
    torn = sum(s.torn for s in summaries)
    if torn:
        intro.append(f"{torn} line(s) in episodes.jsonl were skipped: unreadable (a run killed "
                     "mid-write) or another method's; see the Runs tables.")
    if not summaries:
        intro.append("No runs were given.")
    return intro


def write_run_report(summaries: Sequence[RunSummary], out: Path, *, stamp: bool = True) -> tuple[Path, Path]:
    """Write ``report.md`` (with its plots as .svg files beside it) and ``report.html`` (plots
    inline, no other file needed) into ``out``. ``stamp`` False: no date written, so the same
    runs give the same files."""
    sections = build_sections(summaries)
    intro = _intro(summaries, stamp)
    out.mkdir(parents=True, exist_ok=True)
    for section in sections:
        for block in section.blocks:
            if isinstance(block, Figure):
                (out / block.name).write_text(block.svg + "\n")
    md, page = out / "report.md", out / "report.html"
    md.write_text(to_markdown(sections, intro))
    page.write_text(to_html(sections, intro))
    return md, page


def write_folders_report(folders: Sequence[Path], out: Path) -> tuple[Path, Path]:
    """Summarise the runs in ``folders`` and write ``out/report.md`` and ``out/report.html``."""
    return write_run_report(read_summaries(folders), out)


# --- published runs: summary.json, the README's table ----------------------------------------------

SUMMARY_FILE = "summary.json"
REPORT_HTML = "report.html"
README_BLOCK = re.compile(r"<!-- results: (?P<command>[^\n]*?) -->\n(?P<body>.*?)<!-- /results -->",
                          re.DOTALL)
MARKDOWN_BACKENDS = (("environment", "environment"), ("perception", "perception"), ("vlm", "VLM"),
                     ("relevancy", "relevancy"), ("explore_scorer", "explore scorer"),
                     ("answer", "answer"), ("judge", "judge"))


def paired_differences(summaries: Sequence[RunSummary],
                       reference: RunSummary | None) -> list[PairedDifference | None]:
    """Each run's paired differences against ``reference`` (None for the reference itself, and
    for every run when there is no reference)."""
    if reference is None:
        return [None for _ in summaries]
    name = distinct_labels([reference])[0]
    return [None if s.source == reference.source else paired(s, reference, name) for s in summaries]


def publish_run(folder: Path, summary: RunSummary, difference: PairedDifference | None = None) -> Path:
    """Write ``summary.json`` and ``report.html`` (this run alone, undated) into the run's
    folder: with ``run.json`` and ``episodes.jsonl``, what a published run under ``results/``
    holds. Returns the summary's path."""
    path = Path(folder) / SUMMARY_FILE
    path.write_text(json.dumps(summary_record(summary, difference), indent=1, sort_keys=True,
                               ensure_ascii=False) + "\n")
    (Path(folder) / REPORT_HTML).write_text(to_html(build_sections([summary]), _intro([summary], False)))
    return path


def _pct(share: float) -> str:
    return "-" if math.isnan(share) else f"{100 * share:.0f}"


def _interval(value: float, ci: tuple[float, float], digits: int = 1, signed: bool = False) -> str:
    if math.isnan(value):
        return "-"
    sign = "+" if signed else ""
    text = f"{value:{sign}.{digits}f}"
    if not any(math.isnan(c) for c in ci):
        text += f" [{ci[0]:{sign}.{digits}f}, {ci[1]:{sign}.{digits}f}]"
    return text


def _accuracy_cell(s: RunSummary, mixed: bool) -> str:
    text = _interval(s.accuracy, s.accuracy_ci)
    marks = {"llm-match": " (LLM-Match)", "choice": " (letter)"}
    return text + marks.get(s.accuracy_judge, "") if mixed else text


def markdown_backends(summaries: Sequence[RunSummary]) -> str:
    """The line under a README table: every back-end that made its numbers, and the code."""
    parts = []
    for key, name in MARKDOWN_BACKENDS:
        values = {v for s in summaries for v in s.backends.get(key, [])}
        if key == "answer" and not values:  # the answer option, where no back-end names it
            values = {str(s.settings["answer"]) for s in summaries
                      if s.settings.get("answer") and s.method not in AGENTLESS_METHODS}
        parts.append(f"{name} {', '.join(sorted(values)) or '-'}")
    codes = sorted({s.code_version for s in summaries})
    return f"Back-ends: {'; '.join(parts)}. Code: {', '.join(codes)}."


def markdown_table(summaries: Sequence[RunSummary],
                   differences: Sequence[PairedDifference | None] = ()) -> str:
    """The README's table: one row per run, then the back-ends and code versions. Accuracy is
    the rule judge's where a run has it, else LLM-Match, with its 95% bootstrap interval; shares
    are %, costs per episode. With ``differences`` (``paired_differences``): accuracy and steps
    against the reference run, paired over the same questions. No dates, no absolute paths."""
    labels = distinct_labels(summaries)
    kinds = {s.accuracy_judge for s in summaries if s.accuracy_judge}
    mixed = len(kinds) > 1
    names = {"rule": "rule judge", "choice": "chosen letter", "llm-match": "LLM-Match"}
    judge = " or ".join(names[k] for k in names if k in kinds) or "rule judge"
    header = ["Method", f"Accuracy, {judge} (%) [95% CI]", "LLM-Match", "Steps", "Steps / oracle",
              "Evidence seen (%)", "Relevancy stops (%)", "Median wall s", "Calls / ep",
              "Tokens / ep", "n"]
    paired_columns = any(d is not None for d in differences)
    if paired_columns:
        reference = next(d.reference for d in differences if d is not None)
        header += [f"Δ accuracy vs {reference} [95% CI]", "Δ steps [95% CI]", "Paired n"]
    rows = []
    for i, (s, lab) in enumerate(zip(summaries, labels)):
        row = [lab, _accuracy_cell(s, mixed), _num(s.llm_match, 1), _num(s.mean_steps, 1),
               _num(s.steps_over_oracle, 2), _pct(s.evidence_seen), _pct(s.relevancy_stops),
               _num(s.wall_s_median, 1), _num(s.calls, 1), _num(s.tokens, 0), str(s.n)]
        if paired_columns:
            d = differences[i] if i < len(differences) else None
            row += (["reference", "reference", "-"] if d is None else
                    [_interval(d.accuracy, d.accuracy_ci, signed=True),
                     _interval(d.steps, d.steps_ci, signed=True), f"{d.n}"])
        rows.append(row)
    table = Table("", header, rows)
    align = ["---:" if numeric else ":---" for numeric in _numeric(table)]
    lines = ["| " + " | ".join(_md(h) for h in header) + " |", "|" + "|".join(align) + "|",
             *("| " + " | ".join(_md(c) for c in row) + " |" for row in rows), "",
             _md(markdown_backends(summaries))]
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class ReportArgs:
    """What ``efficienteqa report`` was asked for, as a README block states it."""

    folders: list[Path]
    paired_against: Path | None = None
    markdown: bool = False


def parse_report_command(command: str) -> ReportArgs:
    """``efficienteqa report FOLDER... [--paired-against REF] [--markdown]`` as written in a
    README block; anything else raises."""
    words = shlex.split(command)
    if words[:2] != ["efficienteqa", "report"]:
        raise EfficientEQAError(f"not an `efficienteqa report` command: {command!r}",
                                fix="write <!-- results: efficienteqa report FOLDER... --markdown -->")
    folders: list[Path] = []
    reference = None
    markdown = False
    rest = iter(words[2:])
    for word in rest:
        if word == "--markdown":
            markdown = True
        elif word.startswith("--paired-against"):
            value = word.partition("=")[2] or next(rest, "")
            if not value:
                raise EfficientEQAError(f"--paired-against needs a folder: {command!r}", fix="name the run")
            reference = Path(value)
        elif word.startswith("-"):
            raise EfficientEQAError(f"unknown option {word} in {command!r}",
                                    fix="use only FOLDER..., --paired-against and --markdown")
        else:
            folders.append(Path(word))
    if not folders:
        raise EfficientEQAError(f"no run folder in {command!r}", fix="name at least one folder")
    return ReportArgs(folders, reference, markdown)


def report_markdown(folders: Sequence[Path], paired_against: Path | None = None,
                    root: Path | None = None) -> str:
    """The Markdown table of the runs in ``folders`` (relative to ``root``, default the working
    directory), with paired differences against ``paired_against`` when given."""
    summaries = read_summaries(folders, root)
    reference = None if paired_against is None else read_summaries([paired_against], root)[0]
    return markdown_table(summaries, paired_differences(summaries, reference))


def readme_blocks(text: str) -> list[tuple[str, str]]:
    """The results blocks of a README: (command, body) for each, in order."""
    return [(m["command"], m["body"]) for m in README_BLOCK.finditer(text)]


def regenerate_readme(text: str, root: Path) -> str:
    """``text`` with the body of every results block replaced by what its command generates
    from the run folders under ``root`` (read in this process; nothing is written)."""
    def block(m: re.Match[str]) -> str:
        args = parse_report_command(m["command"])
        body = report_markdown(args.folders, args.paired_against, root)
        return f"<!-- results: {m['command']} -->\n{body}<!-- /results -->"

    return README_BLOCK.sub(block, text)
