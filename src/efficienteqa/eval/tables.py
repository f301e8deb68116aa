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
``report.html`` into its folder; ``markdown_table`` is the README's table of runs (accuracy with
its bootstrap interval, cost, optional paired differences against a reference run), deterministic
(no dates, no absolute paths); ``regenerate_readme`` rewrites every README block
``<!-- results: efficienteqa report FOLDER... --markdown -->`` ... ``<!-- /results -->`` from its
folders, in-process, so a test can check the README against ``results/``; a block
``<!-- demo: results/demo/episode.json -->`` ... ``<!-- /demo -->`` is what ``ask`` printed of
that committed episode (``episode_lines``, the same lines the command prints).
"""

from __future__ import annotations

import html
import json
import math
import re
import shlex
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.ablation_tables import ablation_blocks
from efficienteqa.eval.compare import distinct_labels, paired
from efficienteqa.eval.records import read_run
from efficienteqa.eval.run_labels import AGENTLESS_METHODS
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
from efficienteqa.report.episode import episode_lines

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


# --- published runs: summary.json, the README's table ----------------------------------------------

SUMMARY_FILE = "summary.json"
REPORT_HTML = "report.html"
README_BLOCK = re.compile(r"<!-- results: (?P<command>[^\n]*?) -->\n(?P<body>.*?)<!-- /results -->",
                          re.DOTALL)
MARKDOWN_BACKENDS = (("environment", "environment"), ("perception", "perception"),
                     ("sightings", "sightings"), ("vlm", "VLM"),
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
    fix = "make the run folder writable: report writes its summary.json and report.html there"
    _write(path, json.dumps(redacted(summary_record(summary, difference)), indent=1,
                            sort_keys=True, ensure_ascii=False) + "\n", fix)
    _write(Path(folder) / REPORT_HTML, redact_urls(to_html(build_sections([summary]),
                                                           _intro([summary], False))), fix)
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
        if key == "sightings" and not values:  # runs from before they were recorded
            continue
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
              "Tokens / ep", "$ / ep", "n"]
    paired_columns = any(d is not None for d in differences)
    if paired_columns:
        reference = next(d.reference for d in differences if d is not None)
        header += [f"Δ accuracy vs {reference} [95% CI]", "Δ steps [95% CI]", "Paired n"]
    rows = []
    for i, (s, lab) in enumerate(zip(summaries, labels)):
        row = [lab, _accuracy_cell(s, mixed), num(s.llm_match, 1), num(s.mean_steps, 1),
               num(s.steps_over_oracle, 2), _pct(s.evidence_seen), _pct(s.relevancy_stops),
               num(s.wall_s_median, 1), num(s.calls, 1), num(s.tokens, 0),
               "unknown" if s.cost_per_episode is None else f"{s.cost_per_episode:.4f}", str(s.n)]
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


DEMO_BLOCK = re.compile(r"<!-- demo: (?P<path>[^\n]*?) -->\n(?P<body>.*?)<!-- /demo -->", re.DOTALL)


def demo_block(path: str, root: Path) -> str:
    """The README's demo block from a committed episode (``results/demo/episode.json``, made
    by the README's command): what ``ask`` printed, in a code block."""
    try:
        record = json.loads((root / path).read_text())
    except (OSError, ValueError) as exc:
        raise EfficientEQAError(f"cannot read the demo episode {path}: {exc}") from None
    body = "\n".join([*episode_lines(record), "episode: out/demo/episode.json",
                      "report:  out/demo/report.html"])
    return f"<!-- demo: {path} -->\n```\n{body}\n```\n<!-- /demo -->"


def readme_blocks(text: str) -> list[tuple[str, str]]:
    """The results blocks of a README: (command, body) for each, in order."""
    return [(m["command"], m["body"]) for m in README_BLOCK.finditer(text)]


def regenerate_readme(text: str, root: Path) -> str:
    """``text`` with the body of every results block replaced by what its command generates
    from the run folders under ``root``, and every demo block by its episode's lines (read in
    this process; nothing is written)."""
    def block(m: re.Match[str]) -> str:
        args = parse_report_command(m["command"])
        body = report_markdown(args.folders, args.paired_against, root)
        return f"<!-- results: {m['command']} -->\n{body}<!-- /results -->"

    return DEMO_BLOCK.sub(lambda m: demo_block(m["path"], root), README_BLOCK.sub(block, text))