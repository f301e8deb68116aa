"""The README's tables of published runs, and the blocks of README.md and docs/RESULTS.md
that hold them.

``markdown_table`` is the table of runs (accuracy with its bootstrap interval, cost, optional
paired differences against a reference run), deterministic (no dates, no absolute paths);
``regenerate_readme`` rewrites every block ``<!-- results: efficienteqa report FOLDER...
--markdown -->`` ... ``<!-- /results -->`` from its folders, in-process, so a test can check the
README against ``results/``; a block ``<!-- demo: results/demo/episode.json -->`` ...
``<!-- /demo -->`` is what ``ask`` printed of that committed episode (``episode_lines``, the
same lines the command prints). Kept apart from the report (``eval.tables``), whose pages are
dated and hold every table: these few columns are what a page of documentation shows, and they
must come out byte for byte the same from the same runs.
"""

from __future__ import annotations

import json
import math
import re
import shlex
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.compare import distinct_labels
from efficienteqa.eval.run_labels import AGENTLESS_METHODS
from efficienteqa.eval.run_tables import Table, num
from efficienteqa.eval.stats import PairedDifference
from efficienteqa.eval.summary import RunSummary
from efficienteqa.eval.tables import md_cell, numeric_columns, paired_differences, read_summaries
from efficienteqa.report.episode import episode_lines

README_BLOCK = re.compile(r"<!-- results: (?P<command>[^\n]*?) -->\n(?P<body>.*?)<!-- /results -->",
                          re.DOTALL)
MARKDOWN_BACKENDS = (("environment", "environment"), ("perception", "perception"),
                     ("sightings", "sightings"), ("vlm", "VLM"),
                     ("relevancy", "relevancy"), ("explore_scorer", "explore scorer"),
                     ("answer", "answer"), ("judge", "judge"))


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
    """The README's table: one row per run (its label, and the preset it started from: ``--preset
    NAME``, or ``--config FILE``), then the back-ends and code versions. Accuracy is
    the rule judge's where a run has it, else LLM-Match, with its 95% bootstrap interval; shares
    are %, costs per episode. With ``differences`` (``paired_differences``): accuracy and steps
    against the reference run, paired over the same questions. No dates, no absolute paths."""
    labels = distinct_labels(summaries)
    kinds = {s.accuracy_judge for s in summaries if s.accuracy_judge}
    mixed = len(kinds) > 1
    names = {"rule": "rule judge", "choice": "chosen letter", "llm-match": "LLM-Match"}
    judge = " or ".join(names[k] for k in names if k in kinds) or "rule judge"
    header = ["Method", "Preset", f"Accuracy, {judge} (%) [95% CI]", "LLM-Match", "Steps", "Steps / oracle",
              "Evidence seen (%)", "Relevancy stops (%)", "Median wall s", "Calls / ep",
              "Tokens / ep", "$ / ep", "n"]
    paired_columns = any(d is not None for d in differences)
    if paired_columns:
        reference = next(d.reference for d in differences if d is not None)
        header += [f"Δ accuracy vs {reference} [95% CI]", "Δ steps [95% CI]", "Paired n"]
    rows = []
    for i, (s, lab) in enumerate(zip(summaries, labels)):
        row = [lab, s.preset or "-", _accuracy_cell(s, mixed), num(s.llm_match, 1), num(s.mean_steps, 1),
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
    align = ["---:" if numeric else ":---" for numeric in numeric_columns(table)]
    lines = ["| " + " | ".join(md_cell(h) for h in header) + " |", "|" + "|".join(align) + "|",
             *("| " + " | ".join(md_cell(c) for c in row) + " |" for row in rows), "",
             md_cell(markdown_backends(summaries))]
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