"""``efficienteqa report``: evaluation runs side by side, in Markdown and in one HTML page.

The paper's tables in form — Table I (method | LLM-Match | average steps, plus steps against the
oracle), Tables II and III (the Z_th and K ablations, found by comparing the runs' settings) —
plus what the paper leaves out: LLM-Match per question category, the rule judge's accuracy beside
LLM-Match for synthetic runs (whose accepted answers are known), and the cost of every run (stop
reasons, model calls and tokens, wall time, failures). Plots are SVG drawn by ``eval.plots``,
so reports need no plotting library; the HTML page inlines them, the Markdown links them as files
beside it.

Every table carries the back-ends that produced its numbers and the date of its newest episode:
a number without them cannot be compared with anything. The report is built as a list of
sections of tables, figures and paragraphs once (the run tables in ``eval.run_tables``, the
ablations in ``eval.ablation_tables``), then rendered twice, here.

Published runs (``results/``): ``publish_run`` writes a run's ``summary.json`` and its own
``report.html`` into its folder. The README's table of runs and the blocks of the README and
docs/RESULTS.md that it fills are in ``eval.readme_tables``.
"""

from __future__ import annotations

import html
import json
import re
import time
from collections.abc import Sequence
from pathlib import Path

from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.ablation_tables import ablation_blocks
from efficienteqa.eval.compare import distinct_labels, paired
from efficienteqa.eval.records import read_run
from efficienteqa.eval.run_tables import (
    SEMANTIC_SENSOR,
    Figure,
    Section,
    Table,
    accuracy_figure,
    any_ruled,
    category_table,
    efficiency_table,
    evidence_table,
    failures_table,
    num,
    problems_table,
    runs_table,
    slug,
    table_one,
    utc_date,
)
from efficienteqa.eval.stats import PairedDifference
from efficienteqa.eval.summary import RunSummary, summarise, summary_record
from efficienteqa.redact import redact_urls, redacted

SEMANTIC_WARNING = ("Perception is semantic-sensor: the agent reads the simulator's object labels as "
                    "text, not pixels, so these are not image-model numbers.")
CONVENTIONS = ("LLM-Match (%) is the mean over every episode of 100 * (score - 1) / 4; a failed or "
               "ungraded episode scores 0, like a missing answer (DESIGN 3.7). Rule-judge accuracy (%), "
               "for synthetic questions whose accepted answers are known, is the share of every episode "
               "that states an accepted answer and no contradicting one (no model involved; a failed "
               "episode counts as wrong). Average steps, steps / "
               "oracle (the mean per-episode ratio, over episodes with an oracle), stop reasons and "
               "model usage are over the episodes that finished; '-' means not measured.")
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


# --- the report ------------------------------------------------------------------------------------


def build_sections(summaries: Sequence[RunSummary]) -> list[Section]:
    """One section per dataset, in the order the datasets first appear."""
    sections = []
    for dataset in dict.fromkeys(s.dataset for s in summaries):
        runs = [s for s in summaries if s.dataset == dataset]
        labels = distinct_labels(runs)
        prefix = slug(dataset)
        section = Section(f"Dataset: {dataset}")
        if any(SEMANTIC_SENSOR in s.backends.get("perception", []) for s in runs):
            section.blocks.append(SEMANTIC_WARNING)
        section.blocks += [table_one(runs, labels), accuracy_figure(runs, labels, prefix)]
        if any_ruled(runs):
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


# --- rendering -------------------------------------------------------------------------------------


def md_cell(text: str) -> str:
    """Safe in a Markdown table cell: no pipe, no line break, no raw HTML."""
    return (text.replace("\\", "\\\\").replace("|", "\\|").replace("<", "&lt;")
            .replace(">", "&gt;").replace("\r", " ").replace("\n", " "))


def numeric_columns(table: Table) -> list[bool]:
    """Which columns hold numbers (right-aligned): every cell starts like one, or is '-'."""
    return [i > 0 and all(re.match(r"-$|[-+]?\d[\d.,]*%?(\s|$)", row[i]) for row in table.rows)
            for i in range(len(table.header))]


def to_markdown(sections: Sequence[Section], intro: Sequence[str]) -> str:
    lines = ["# EfficientEQA evaluation report", "", *(f"{md_cell(p)}\n" for p in intro)]
    for section in sections:
        lines += [f"## {md_cell(section.title)}", ""]
        for block in section.blocks:
            if isinstance(block, Table):
                lines += [f"### {md_cell(block.caption)}", "",
                          "| " + " | ".join(md_cell(h) for h in block.header) + " |",
                          "|" + "|".join("---:" if numeric else ":---"
                                         for numeric in numeric_columns(block)) + "|",
                          *("| " + " | ".join(md_cell(c) for c in row) + " |" for row in block.rows), "",
                          *(f"_{md_cell(note)}_\n" for note in block.notes)]
            elif isinstance(block, Figure):
                lines += [f"![{md_cell(block.caption)}]({block.name})", ""]
            else:
                lines += [md_cell(block), ""]
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
                align = ["" if numeric else " class=text" for numeric in numeric_columns(block)]
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
    ruled = any_ruled(summaries)
    rows = []
    for dataset in dict.fromkeys(s.dataset for s in summaries):
        runs = [s for s in summaries if s.dataset == dataset]
        rows += [[dataset, lab, *([num(s.rule_accuracy)] if ruled else []), num(s.llm_match),
                  num(s.mean_steps), num(s.steps_over_oracle), f"{s.n_done}/{s.n}"]
                 for s, lab in zip(runs, distinct_labels(runs))]
    return ["Dataset", "Method", *(["Rule %"] if ruled else []), "LLM-Match", "Steps",
            "Steps/oracle", "Done"], rows


def _intro(summaries: Sequence[RunSummary], stamp: bool) -> list[str]:
    written = f", written {utc_date(time.time())}" if stamp else ""
    intro = [f"{len(summaries)} run(s){written}.", CONVENTIONS]
    torn = sum(s.torn for s in summaries)
    if torn:
        intro.append(f"{torn} line(s) in episodes.jsonl were skipped: unreadable (a run killed "
                     "mid-write), another method's or of no question of the run; see the Runs "
                     "tables.")
    if not summaries:
        intro.append("No runs were given.")
    return intro


def write_run_report(summaries: Sequence[RunSummary], out: Path, *, stamp: bool = True) -> tuple[Path, Path]:
    """Write ``report.md`` (with its plots as .svg files beside it) and ``report.html`` (plots
    inline, no other file needed) into ``out``. ``stamp`` False: no date written, so the same
    runs give the same files."""
    sections = build_sections(summaries)
    intro = _intro(summaries, stamp)
    fix = "choose another --out folder"
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise EfficientEQAError(f"cannot write to {out}: {error.strerror or error}",
                                fix=fix) from None
    for section in sections:
        for block in section.blocks:
            if isinstance(block, Figure):
                _write(out / block.name, block.svg + "\n", fix)
    md, page = out / "report.md", out / "report.html"
    _write(md, redact_urls(to_markdown(sections, intro)), fix)  # runs recorded before redaction
    _write(page, redact_urls(to_html(sections, intro)), fix)
    return md, page


def _write(path: Path, text: str, fix: str) -> None:
    """``path`` written, or one line saying why not (a read-only disk, a folder of its name)."""
    try:
        path.write_text(text)
    except OSError as error:
        raise EfficientEQAError(f"cannot write {path}: {error.strerror or error}",
                                fix=fix) from None


def write_folders_report(folders: Sequence[Path], out: Path) -> tuple[Path, Path]:
    """Summarise the runs in ``folders`` and write ``out/report.md`` and ``out/report.html``."""
    return write_run_report(read_summaries(folders), out)


# --- published runs: summary.json and report.html --------------------------------------------------

SUMMARY_FILE = "summary.json"
REPORT_HTML = "report.html"


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
    fix = "make the run folder writable: report writes its summary.json and report.html there"
    _write(path, json.dumps(redacted(summary_record(summary, difference)), indent=1,
                            sort_keys=True, ensure_ascii=False) + "\n", fix)
    _write(Path(folder) / REPORT_HTML, redact_urls(to_html(build_sections([summary]),
                                                           _intro([summary], False))), fix)
    return path


def publish_runs(folders: Sequence[Path], out: Path | None = None,
                 paired_against: Path | None = None, *, markdown: bool = False
                 ) -> tuple[list[RunSummary], list[PairedDifference | None], Path, bool]:
    """``efficienteqa report``'s reading and publishing: each run summarised (and paired
    against the run ``paired_against``), its summary.json and report.html written in its
    folder. Returns the summaries, their differences, the report's folder (``out``, else the
    run folder itself for one run, else FIRST_FOLDER/../report; checked writable first unless
    only ``markdown`` is wanted) and whether its pages are stamped (not for one run's own)."""
    from efficienteqa.records import check_writable

    summaries = read_summaries(folders)
    reference = None if paired_against is None else read_summaries([paired_against])[0]
    differences = paired_differences(summaries, reference)
    single = out is None and len(folders) == 1
    target = out or (folders[0] if len(folders) == 1 else folders[0].resolve().parent / "report")
    if not markdown:
        check_writable(target)  # before any file is written
    for folder, summary, difference in zip(run_folders(folders), summaries, differences):
        publish_run(folder, summary, difference)
    return summaries, differences, target, not single
