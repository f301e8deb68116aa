"""Published runs: summary.json, the results tables of the README and of docs/RESULTS.md, paired
differences.

Every results block of README.md and docs/RESULTS.md must equal what its folders under
``results/`` generate; the block machinery is checked on a tmp README with run folders written
here (no model).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from efficienteqa import cli
from efficienteqa.eval.compare import paired
from efficienteqa.eval.readme_tables import (
    parse_report_command,
    readme_blocks,
    regenerate_readme,
    report_markdown,
)
from efficienteqa.eval.records import EPISODES_FILE, RUN_FILE, append_episode
from efficienteqa.eval.runner import machine, scene_seeds
from efficienteqa.eval.stats import mean_interval
from efficienteqa.eval.summary import summarise
from efficienteqa.records import write_json
from test_eval_report import episode, manifest

ROOT = Path(__file__).resolve().parents[1]


def ruled(i: int, right: bool, *, steps: int = 12, stop: str = "relevancy", seen: int | None = 3,
          wall: float = 2.0) -> dict:
    """A synthetic episode with a rule grade, evidence ground truth and a set wall time."""
    row = episode(i, None, steps=steps, stop=stop, judged=False)
    row.update(rule={"score": 5 if right else 1, "value": 100.0 if right else 0.0, "judge": "rule",
                     "raw": "", "problems": [], "cached": False},
               evidence_first_seen_step=seen, evidence_in_top_k=seen is not None, wall_s=wall)
    return row


def write_run(folder: Path, man: dict, rows: list[dict]) -> Path:
    write_json(folder / RUN_FILE, man)
    for row in rows:
        append_episode(folder / EPISODES_FILE, row)
    return folder


def two_runs(root: Path) -> tuple[Path, Path]:
    """``ref``: 4 of 8 right in 20 steps; ``new``: 7 of 8 right (the same 4 and 3 more) in 10."""
    ref = write_run(root / "results" / "ref", manifest(z_th=2.0, questions=8),
                    [ruled(i, i < 4, steps=20, stop="budget", seen=None if i >= 6 else 5, wall=4.0)
                     for i in range(8)])
    new = write_run(root / "results" / "new", manifest(questions=8),
                    [ruled(i, i < 7, steps=10, wall=1.0 + i) for i in range(8)])
    return ref, new


# The pages whose results tables are generated: the README's short main table, every run table
# in docs/RESULTS.md, and the benchmark's leaderboard. Each must hold at least one block.
GENERATED_PAGES = ("README.md", "docs/RESULTS.md", "docs/benchmark.md")


@pytest.mark.parametrize("page", GENERATED_PAGES)
def test_the_published_results_tables_are_what_their_results_folders_generate(page):
    text = (ROOT / page).read_text()
    blocks = readme_blocks(text)
    assert blocks, f"{page} has no <!-- results: ... --> block"
    for command, _ in blocks:
        args = parse_report_command(command)
        assert args.markdown and all((ROOT / f / RUN_FILE).exists() for f in args.folders), command
        assert args.paired_against is None or args.paired_against in args.folders, command
    assert regenerate_readme(text, ROOT) == text, (
        f"a results table in {page} differs from its results/ folders: regenerate it with the "
        "command in its <!-- results: ... --> line")


def test_the_readme_main_table_is_a_short_form_of_the_full_one():
    """The README shows some rows of docs/RESULTS.md's main table, from the same folders and
    against the same reference: the two cannot tell different stories."""
    def main_block(page: str) -> tuple[list[Path], Path | None]:
        blocks = [parse_report_command(c) for c, _ in readme_blocks((ROOT / page).read_text())]
        # the main table: the first block over main-heldout (RESULTS has a partial one after it)
        args = next(a for a in blocks if any("main-heldout" in str(f) for f in a.folders))
        return args.folders, args.paired_against

    short, short_ref = main_block("README.md")
    full, full_ref = main_block("docs/RESULTS.md")
    assert set(short) <= set(full) and short_ref == full_ref


def test_a_run_on_a_server_without_a_listed_price_costs_unknown_not_zero():
    from efficienteqa.eval.summary import has_price

    assert has_price("local:qwen2.5-coder-1.5b") and has_price(None) and has_price("openai:gpt-4o")
    assert not has_price("openai:qwen2.5-vl-7b@http://127.0.0.1:8000/v1")


def test_a_stale_readme_block_is_regenerated_and_other_text_kept(tmp_path):
    ref, new = two_runs(tmp_path)
    command = "efficienteqa report results/new results/ref --paired-against results/ref --markdown"
    readme = (f"# Title\n\nText before.\n\n<!-- results: {command} -->\n| old | table |\n"
              "<!-- /results -->\n\nText after.\n")
    fresh = regenerate_readme(readme, tmp_path)
    assert fresh != readme and fresh.startswith("# Title\n\nText before.\n\n")
    assert fresh.endswith("<!-- /results -->\n\nText after.\n") and "| old | table |" not in fresh
    assert regenerate_readme(fresh, tmp_path) == fresh  # a current README is left as it is
    ((_, body),) = readme_blocks(fresh)
    assert body == report_markdown([Path("results/new"), Path("results/ref")], Path("results/ref"),
                                   tmp_path)
    lines = body.splitlines()
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    rows = {r.split("|")[1].strip(): [c.strip() for c in r.strip("|").split("|")] for r in lines[2:4]}
    assert header[:13] == ["Method", "Preset", "Accuracy, rule judge (%) [95% CI]", "LLM-Match",
                           "Steps", "Steps / oracle", "Evidence seen (%)", "Relevancy stops (%)",
                           "Median wall s", "Calls / ep", "Tokens / ep", "$ / ep", "n"]
    assert header[13].startswith("Δ accuracy vs efficienteqa Z_th=2")
    new_row, ref_row = rows["efficienteqa"], rows["efficienteqa Z_th=2"]
    assert new_row[1] == ref_row[1] == "-"  # made without a preset
    new_row, ref_row = new_row[:1] + new_row[2:], ref_row[:1] + ref_row[2:]
    assert new_row[1].startswith("87.5 [") and ref_row[1].startswith("50.0 [")
    assert new_row[3:12] == ["10.0", "1.67", "100", "100", "4.5", "10.0", "1000", "0.0000", "8"]
    assert ref_row[3:8] == ["20.0", "3.33", "75", "0", "4.0"]
    assert new_row[12].startswith("+37.5 [") and new_row[13] == "-10.0 [-10.0, -10.0]"
    assert new_row[14] == "8" and ref_row[12:] == ["reference", "reference", "-"]
    assert lines[-1].startswith("Back-ends: environment synthetic-builtin; perception "
                                "semantic-sensor; VLM qwen2.5-coder-1.5b; relevancy all-MiniLM-L6-v2")
    assert lines[-1].endswith("; judge local:qwen2.5-coder-1.5b, rule. Code: 0.1.0+test.")
    assert str(tmp_path) not in fresh and "UTC" not in fresh


def test_a_bad_readme_command_is_refused():
    with pytest.raises(Exception, match="not an `efficienteqa report`"):
        parse_report_command("rm -rf results")
    with pytest.raises(Exception, match="unknown option"):
        parse_report_command("efficienteqa report results/a --out x --markdown")
    args = parse_report_command("efficienteqa report results/a results/b --paired-against=results/a")
    assert args.folders == [Path("results/a"), Path("results/b")] and args.paired_against == Path("results/a")


def test_the_accuracy_interval_is_scipys_bootstrap_and_deterministic():
    values = [100.0] * 7 + [0.0] * 5
    low, high = mean_interval(values)
    assert (low, high) == mean_interval(values)  # a fixed seed
    assert (low, high) == mean_interval(values[::-1]) == mean_interval(values[3:] + values[:3])
    assert 20 < low < 100 * 7 / 12 < high < 90
    assert mean_interval([100.0]) == pytest.approx((math.nan, math.nan), nan_ok=True)
    assert mean_interval([0.0, 0.0, 0.0]) == (0.0, 0.0)
    # Wider for fewer episodes with the same share.
    few = mean_interval([100.0] * 7 + [0.0] * 5)
    many = mean_interval([100.0] * 70 + [0.0] * 50)
    assert many[1] - many[0] < few[1] - few[0]


def test_paired_differences_match_episodes_by_id_and_skip_the_unshared(tmp_path):
    ref, new = two_runs(tmp_path)
    extra = ruled(99, True, steps=1)  # only in one run: not paired
    s_ref = summarise(json.loads((ref / RUN_FILE).read_text()),
                      [json.loads(line) for line in (ref / EPISODES_FILE).read_text().splitlines()])
    rows = [json.loads(line) for line in (new / EPISODES_FILE).read_text().splitlines()]
    s_new = summarise(json.loads((new / RUN_FILE).read_text()), [*rows[::-1], extra])
    d = paired(s_new, s_ref)
    assert (d.n, d.n_steps, d.judge) == (8, 8, "rule")
    assert d.accuracy == pytest.approx(37.5) and d.steps == pytest.approx(-10.0)
    assert d.accuracy_ci[0] > 0  # 3 questions gained, none lost
    assert d.steps_ci == (-10.0, -10.0)
    assert s_new.accuracy == pytest.approx(100 * 8 / 9) and s_new.accuracy_judge == "rule"


def test_cli_report_publishes_summary_json_and_report_html_in_each_run_folder(tmp_path, monkeypatch):
    ref, new = two_runs(tmp_path)
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(cli.app, ["report", "results/new", "results/ref",
                                          "--paired-against", "results/ref", "--markdown"])
    assert result.exit_code == 0, result.output
    assert result.output == report_markdown([Path("results/new"), Path("results/ref")],
                                            Path("results/ref"), tmp_path)
    for folder in (ref, new):
        summary = json.loads((folder / "summary.json").read_text())
        page = (folder / "report.html").read_text()
        assert summary["n"] == 8 and "<table>" in page and str(tmp_path) not in page + json.dumps(summary)
    summary = json.loads((new / "summary.json").read_text())
    assert summary["accuracy"] == 87.5 and summary["accuracy_judge"] == "rule"
    assert summary["accuracy_ci"][0] < 87.5 < summary["accuracy_ci"][1] <= 100
    assert summary["paired"]["accuracy"] == 37.5 and summary["paired"]["steps"] == -10.0
    assert summary["evidence_seen"] == 1.0 and summary["relevancy_stops"] == 1.0
    assert summary["wall_s_median"] == 4.5 and summary["tokens"] == 1000
    assert "paired" not in json.loads((ref / "summary.json").read_text())
    before = (new / "summary.json").read_text(), (new / "report.html").read_text()
    assert CliRunner().invoke(cli.app, ["report", "results/new"]).exit_code == 0
    assert ((new / "report.html").read_text(), ) == before[1:]  # one run: the same, undated page
    assert json.loads((new / "summary.json").read_text())["accuracy"] == 87.5


def test_run_json_records_the_machine_and_the_houses():
    assert machine()["cpus"] >= 1 and machine()["platform"]
    assert scene_seeds(["synthetic:7", "synthetic:3", "synthetic:7", "hm3d:abc"]) == {
        "scenes": ["hm3d:abc", "synthetic:3", "synthetic:7"], "seeds": [3, 7]}
    assert scene_seeds(["hm3d:abc"]) == {"scenes": ["hm3d:abc"]}


def test_published_runs_keep_their_heavy_episode_folders_out_of_git():
    ignore = (ROOT / ".gitignore").read_text().splitlines()
    assert "results/**/episodes/" in ignore


def test_published_runs_come_from_clean_commits():
    """No published evaluation run comes from a tree with uncommitted changes (the last ones
    left results/ for git history)."""
    runs = {str(run.parent.relative_to(ROOT / "results")): json.loads(run.read_text())
            for run in (ROOT / "results").rglob(RUN_FILE)}
    assert runs
    dirty = sorted(name for name, run in runs.items()
                   if "dirty" in str(run.get("code_version", "dirty")))
    assert not dirty, dirty


def test_the_readme_demo_block_is_what_ask_printed_of_its_committed_episode(tmp_path):
    """The README's demo block is generated from ``results/demo/episode.json`` (a clean commit's
    run of the README's command), in the lines ``ask`` prints, so it cannot go stale."""
    from efficienteqa.report.episode import episode_lines

    text = (ROOT / "README.md").read_text()
    assert "<!-- demo: results/demo/episode.json -->" in text
    record = json.loads((ROOT / "results/demo/episode.json").read_text())
    assert not record["code_version"].endswith("-dirty")
    assert record["question"] == "What is on the desk in the office?"  # the Makefile's
    assert record["scene"].startswith("synthetic:0")
    assert "\n".join(episode_lines(record)) in text
    # the machinery: a stale block is rewritten from its episode, the text around it kept
    (tmp_path / "results/demo").mkdir(parents=True)
    (tmp_path / "results/demo/episode.json").write_text(json.dumps(
        {**record, "answer": "a lamp", "steps": 7, "timing": {"wall_s": 9.4}}))
    stale = "Before.\n<!-- demo: results/demo/episode.json -->\n```\nold\n```\n<!-- /demo -->\nAfter.\n"
    fresh = regenerate_readme(stale, tmp_path)
    assert fresh.startswith("Before.\n") and fresh.endswith("<!-- /demo -->\nAfter.\n")
    assert "answer: a lamp  (confidence" in fresh and f"steps: 7 of {record['budget']}" in fresh
    assert "time: 9 s" in fresh and "old" not in fresh
    assert regenerate_readme(fresh, tmp_path) == fresh


def test_no_published_file_names_a_machine_path():
    """A run's pages and records name their folder as published (``results/...``), never where
    the run happened to be made (a report written before the copy keeps that path)."""
    import re

    machine = re.compile(r"(?<![\w.])/(?:home|root|work|tmp|Users|mnt|scratch)/")
    found = [f"{p.relative_to(ROOT)}:{n}" for p in sorted((ROOT / "results").rglob("*"))
             if p.is_file() and p.suffix in (".html", ".json", ".jsonl", ".md", ".txt", ".log")
             for n, line in enumerate(p.read_text(errors="replace").splitlines(), start=1)
             if machine.search(line)]
    assert found == []
