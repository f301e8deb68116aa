"""`efficienteqa report`: run summaries (LLM-Match, steps, cost), the Table I-III reports, the CLI.

Run folders are written by hand here, line by line, exactly as the evaluation runner writes them.
"""

from __future__ import annotations

import math
import sys
from dataclasses import asdict, replace
from html.parser import HTMLParser
from pathlib import Path

import pytest
from typer.testing import CliRunner

from efficienteqa import cli
from efficienteqa.agent import AgentConfig
from efficienteqa.config.knobs import with_leaves
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.compare import ablations, distinct_labels
from efficienteqa.eval.records import EPISODES_FILE, RUN_FILE, append_episode
from efficienteqa.eval.summary import RunSummary, summarise
from efficienteqa.eval.tables import (
    SEMANTIC_WARNING,
    read_summaries,
    write_folders_report,
    write_run_report,
)
from efficienteqa.records import write_json
from efficienteqa.stop.rules import StopConfig

BACKENDS = {"environment": "synthetic-builtin", "perception": "semantic-sensor",
            "vlm": "qwen2.5-coder-1.5b", "vlm_backend": "local:qwen2.5-coder-1.5b",
            "relevancy": "all-MiniLM-L6-v2", "grouping": "llm", "judge": None}


def manifest(method: str = "efficienteqa", dataset: str = "synthetic", *, z_th: float = 3.0,
             top_k: int = 5, questions: int = 5) -> dict:
    return {"method": method, "dataset": dataset, "closed_set": False,
            "config": asdict(AgentConfig.of(top_k=top_k,
                                         stop=replace(AgentConfig().stop, z_th=z_th))),
            "stack": {"vlm": "local:qwen2.5-coder-1.5b", "perception": "semantic", "relevancy": "minilm",
                      "grouping": "llm", "cache": True},
            "judge": "local:qwen2.5-coder-1.5b", "assets": "builtin", "questions": questions,
            "code_version": "0.1.0+test", "created": 1.7e9}


def episode(i: int, score: int | None = 5, *, status: str = "done", category: str = "location",
            steps: int = 12, oracle: int | None = 6, stop: str | None = "relevancy",
            judged: bool = True, backends: dict | None = None) -> dict:
    row = {"id": f"q{i}", "dataset": "synthetic", "method": "efficienteqa", "scene": "synthetic:0",
           "question": f"Where is thing {i}?", "reference": "kitchen", "alternatives": [],
           "category": category, "oracle_steps": oracle, "worker": "host:1", "status": status}
    if status == "done":
        value = 0.0 if score is None else 25.0 * (score - 1)
        row.update(answer="kitchen", confidence=0.8, steps=steps, budget=30, stop_reason=stop,
                   usage={"calls": 10, "cached_calls": 5, "prompt_tokens": 900, "completion_tokens": 100,
                          "latency_s": 4.0},
                   backends=backends or BACKENDS, extra={},
                   judge={"score": score, "value": value, "judge": "qwen2.5-coder-1.5b", "raw": str(score),
                          "problems": [], "cached": False} if judged else None)
    else:
        row.update(error="RuntimeError: the scene would not load", traceback="...")
    row.update(wall_s=2.0 + i, finished=1.7e9 + 60 * i)
    return row


def write_run(folder: Path, man: dict, rows: list[dict]) -> Path:
    write_json(folder / RUN_FILE, man)
    for row in rows:
        append_episode(folder / EPISODES_FILE, row)
    return folder


MIXED = [episode(0, 5), episode(1, 3), episode(2, 1, category="counting"),
         episode(3, None, category="counting"), episode(4, status="failed", category="counting")]


def test_llm_match_counts_missing_failed_and_ungraded_answers_as_zero():
    s = summarise(manifest(), MIXED)
    assert s.llm_match == pytest.approx((100 + 50 + 0 + 0 + 0) / 5)
    assert (s.n, s.n_done, s.n_failed, s.n_judged) == (5, 4, 1, 4)
    ungraded = summarise(manifest(), [*MIXED, episode(5, judged=False)])
    assert ungraded.llm_match == pytest.approx(150 / 6) and ungraded.n_judged == 4
    assert math.isnan(summarise(manifest(), [episode(0, judged=False)]).llm_match)  # never judged


def test_per_category_llm_match_and_counts():
    s = summarise(manifest(), MIXED)
    assert s.by_category == pytest.approx({"counting": 0.0, "location": 75.0})
    assert s.n_by_category == {"counting": 3, "location": 2}


def test_steps_over_oracle_leaves_out_episodes_without_an_oracle():
    rows = [episode(0, steps=12, oracle=6), episode(1, steps=10, oracle=None), episode(2, steps=9, oracle=3),
            episode(3, status="failed", oracle=4)]
    s = summarise(manifest(), rows)
    assert s.steps_over_oracle == pytest.approx(2.5) and s.n_oracle == 2
    assert s.mean_steps == pytest.approx(31 / 3)


def test_stop_reasons_failures_usage_and_time():
    rows = [episode(0, stop="relevancy"), episode(1, stop="budget"), episode(2, stop="relevancy"),
            episode(3, stop="explored"), episode(4, status="failed")]
    s = summarise(manifest(), rows)
    assert s.stop_reasons == {"relevancy": 2, "budget": 1, "explored": 1}
    assert s.n_failed == 1 and s.errors == {"RuntimeError: the scene would not load": 1}
    assert (s.calls, s.tokens, s.model_latency_s, s.cached_fraction) == (10, 1000, 4.0, 0.5)
    assert s.wall_s_mean == pytest.approx(4.0) and s.wall_s_median == pytest.approx(4.0)
    assert s.backends["perception"] == ["semantic-sensor"] and s.backends["judge"] == ["qwen2.5-coder-1.5b"]
    assert s.newest == pytest.approx(1.7e9 + 240)


def test_empty_run_and_blind_run_have_no_steps_rather_than_zero(tmp_path):
    empty = summarise(manifest(), [])
    assert empty.n == 0 and math.isnan(empty.llm_match) and math.isnan(empty.mean_steps)
    assert empty.newest is None and empty.stop_reasons == {}
    blind = [{**episode(i, score, steps=0, stop=None, oracle=None), "method": "blind"}
             for i, score in ((0, 5), (1, 1))]
    s = summarise(manifest("blind"), blind)
    assert math.isnan(s.mean_steps) and s.llm_match == 50 and s.stop_reasons == {"none": 2}
    md, page = write_folders_report([write_run(tmp_path / "blind", manifest("blind"), blind),
                                     write_run(tmp_path / "empty", manifest(), [])], tmp_path / "out")
    assert "| blind | 50.00 | - | - |" in md.read_text()
    assert "blind (no steps): 50.0" in page.read_text()


def test_labels_name_the_ablation_values_and_stay_distinct():
    runs = [summarise(manifest(z_th=2.0), []), summarise(manifest(top_k=10), []), summarise(manifest(), [])]
    assert [r.label for r in runs] == ["efficienteqa Z_th=2", "efficienteqa K=10", "efficienteqa"]
    twins = [summarise(manifest(), [], source="a"), summarise(manifest(), [], source="b")]
    assert distinct_labels(twins) == ["efficienteqa (a)", "efficienteqa (b)"]


def test_the_papers_configuration_is_named_so_and_a_change_to_it_is_named_on_top():
    from efficienteqa.agent import PAPER_CONFIG

    def run(config: AgentConfig, scorer: str = "vlm") -> str:
        m = manifest()
        m["config"] = asdict(config)
        m["stack"] = {**m["stack"], "explore_scorer": scorer}
        return summarise(m, []).label

    assert run(PAPER_CONFIG) == "efficienteqa paper configuration"
    assert run(with_leaves(PAPER_CONFIG, top_k=10)) == "efficienteqa paper configuration K=10"
    # Without the VLM's semantic values it is not the paper's configuration: every setting shown.
    assert run(PAPER_CONFIG, "direction-logit").startswith(
        "efficienteqa refusal_retries=0 stop_clearance_m=0 prompts=paper")
    assert "rule=robust" in run(with_leaves(PAPER_CONFIG, stop=StopConfig(rule="robust")))
    assert run(AgentConfig()) == "efficienteqa"


def _runs(tmp_path: Path) -> list[Path]:
    rows = MIXED
    return [write_run(tmp_path / "z3", manifest(z_th=3.0), rows),
            write_run(tmp_path / "z1", manifest(z_th=1.0), rows[:2]),
            write_run(tmp_path / "z2", manifest(z_th=2.0), rows[1:]),
            write_run(tmp_path / "k10", manifest(top_k=10), rows[:3]),
            write_run(tmp_path / "eqa", manifest("explore-eqa"), [episode(0, 2, steps=30, stop="budget")]),
            write_run(tmp_path / "hm", manifest(dataset="hm-eqa"), rows[:1])]


def test_ablations_group_runs_that_differ_in_one_setting_only(tmp_path):
    summaries = read_summaries(_runs(tmp_path))
    (z_group,) = ablations(summaries, "z_th")
    assert [s.settings["z_th"] for s in z_group] == [1.0, 2.0, 3.0]
    (k_group,) = ablations(summaries, "top_k")
    assert [s.settings["top_k"] for s in k_group] == [5, 10] and {s.dataset for s in k_group} == {"synthetic"}


class StrictParser(HTMLParser):
    """Every element closed, in order (html.parser itself forgives everything)."""

    VOID = {"meta", "br", "img", "hr", "input", "link"}

    def __init__(self) -> None:
        super().__init__()
        self.open: list[str] = []
        self.errors: list[str] = []
        self.tags: set[str] = set()

    def handle_starttag(self, tag: str, attrs: list) -> None:
        self.tags.add(tag)
        if tag not in self.VOID:
            self.open.append(tag)

    def handle_startendtag(self, tag: str, attrs: list) -> None:
        self.tags.add(tag)

    def handle_endtag(self, tag: str) -> None:
        if not self.open or self.open.pop() != tag:
            self.errors.append(tag)


def test_report_markdown_html_and_plots(tmp_path):
    folders = _runs(tmp_path)
    odd = episode(9, 4, category="<b>odd|cat</b>")
    folders.append(write_run(tmp_path / "odd", manifest(top_k=3), [odd]))
    md_path, html_path = write_folders_report(folders, tmp_path / "out")
    md = md_path.read_text()
    assert "| Method | LLM-Match (%) ↑ | Avg steps ↓ | Steps / oracle ↓ | Episodes |" in md
    assert "| efficienteqa | 30.00 | 12.00 | 2.00 | 5 (4 judged, 1 failed) |" in md
    assert ("Back-ends: environment synthetic-builtin; perception semantic-sensor (reads the simulator's "
            "object labels, not pixels: not image-model numbers); VLM qwen2.5-coder-1.5b; relevancy "
            "all-MiniLM-L6-v2; judge qwen2.5-coder-1.5b. Newest episode: 2023-11-14 22:17 UTC.") in md
    assert SEMANTIC_WARNING in md and md.count("## Dataset: ") == 2
    assert md.count("Back-ends: ") == md.count("\n| Method |") + md.count("\n| Z_th |") + md.count("\n| K |")
    z_table = md[md.index("### Ablation over Z_th"):]
    assert "| Z_th | LLM-Match (%) ↑ | Avg steps ↓ | Episodes |" in z_table
    assert z_table.index("| 1 | 75.00") < z_table.index("| 2 | 12.50") < z_table.index("| 3 | 30.00")
    assert "### Ablation over K: efficienteqa" in md and "| 10 | 50.00 |" in md
    assert "&lt;b&gt;odd\\|cat&lt;/b&gt;" in md and "<b>" not in md
    for name in ("synthetic-accuracy-steps.svg", "synthetic-z-th-llm-match.svg", "synthetic-z-th-steps.svg",
                 "synthetic-top-k-llm-match.svg", "hm-eqa-accuracy-steps.svg"):
        assert f"]({name})" in md and (tmp_path / "out" / name).read_text().startswith("<svg")
    page = html_path.read_text()
    parser = StrictParser()
    parser.feed(page)
    parser.close()
    assert parser.errors == [] and parser.open == [] and {"svg", "table", "circle"} <= parser.tags
    assert "&lt;b&gt;odd|cat&lt;/b&gt;" in page and "<b>" not in page
    assert "<script" not in page and "src=" not in page and "href=" not in page
    assert SEMANTIC_WARNING.replace("'", "&#x27;") in page


def test_a_torn_last_line_is_skipped_and_reported(tmp_path):
    folder = write_run(tmp_path / "run", manifest(), MIXED[:2])
    with (folder / EPISODES_FILE).open("ab") as f:
        f.write(b'{"id": "q9", "status": "do')
    (s,) = read_summaries([folder])
    assert isinstance(s, RunSummary) and s.torn == 1 and s.n == 2
    md = write_folders_report([folder], folder)[0].read_text()
    assert "1 line(s) in episodes.jsonl were skipped: unreadable" in md and "| 1 skipped |" in md


def test_cli_report_prints_table_one_and_the_paths(tmp_path):
    one = write_run(tmp_path / "a", manifest(z_th=2.0), MIXED)
    two = write_run(tmp_path / "b", manifest("blind"), [episode(0, 5, steps=0, stop=None)])
    result = CliRunner().invoke(cli.app, ["report", str(one)])
    assert result.exit_code == 0, result.output
    assert "Z_th=2" in result.output and "30.00" in result.output and (one / "report.md").exists()
    result = CliRunner().invoke(cli.app, ["report", str(one), str(two)])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "report" / "report.html").exists() and "blind" in result.output


def test_cli_report_on_a_folder_that_is_not_a_run_is_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["efficienteqa", "report", str(tmp_path)])
    with pytest.raises(SystemExit) as exited:
        cli.main()
    assert exited.value.code == 1
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 1 and "is not an evaluation run" in lines[0]


def test_rule_judge_accuracy_is_reported_beside_llm_match(tmp_path):
    """Synthetic runs carry the rule judge's grade: its accuracy (a failed episode is wrong)
    stands beside LLM-Match in Table I, per category and on the console; a run without a judge
    model has rule accuracy and no LLM-Match."""
    def ruled(i: int, right: bool, **kwargs) -> dict:
        row = episode(i, **kwargs)
        if row["status"] == "done":
            row["rule"] = {"score": 5 if right else 1, "value": 100.0 if right else 0.0, "judge": "rule",
                           "raw": "rule: ...", "problems": [], "cached": False}
        return row

    rows = [ruled(0, True, category="count"), ruled(1, False, score=4, category="count"),
            ruled(2, True, category="colour"), ruled(3, True, status="failed", category="colour")]
    with_model = write_run(tmp_path / "a", manifest(), rows)
    no_model = write_run(tmp_path / "b", {**manifest(top_k=3), "judge": None},
                         [ruled(0, True, judged=False), ruled(1, True, judged=False)])
    a, b = read_summaries([with_model, no_model])
    assert (a.rule_accuracy, a.n_rule, a.rule_by_category) == (50.0, 3, {"colour": 50.0, "count": 50.0})
    assert a.llm_match == pytest.approx((100 + 75 + 100 + 0) / 4) and "rule" in a.backends["judge"]
    assert b.rule_accuracy == 100.0 and math.isnan(b.llm_match)
    md = write_folders_report([with_model, no_model], tmp_path / "out")[0].read_text()
    assert "| Method | Rule-judge accuracy (%) ↑ | LLM-Match (%) ↑ | Avg steps ↓ |" in md
    assert "| efficienteqa | 50.00 | 68.75 | 12.00 | 2.00 | 4 (3 rule-graded, 3 judged, 1 failed) |" in md
    assert "| efficienteqa K=3 | 100.00 | - |" in md
    assert "### Rule-judge accuracy (%) per question category" in md
    result = CliRunner().invoke(cli.app, ["report", str(with_model)])
    assert result.exit_code == 0 and "Rule %" in result.output and "50.00" in result.output


def test_evidence_in_view_and_refused_moves_are_summarised_and_tabled(tmp_path):
    """First-seen step and first-seen / oracle over the episodes that saw the evidence, the
    never-seen and in-top-K shares over those with ground truth, refused moves per step taken;
    rows without ground truth (None) or from older runs (no key) count in none of them."""
    def seen(i: int, first: int | None, top_k: bool | None, oracle: int | None = 4,
             refused: int | None = 0, **kwargs) -> dict:
        row = episode(i, oracle=oracle, **kwargs)
        if row["status"] == "done":
            row.update(evidence_first_seen_step=first, evidence_in_top_k=top_k, refused_moves=refused)
        return row

    rows = [seen(0, 6, True, oracle=3, refused=1), seen(1, 12, False, oracle=4),
            seen(2, None, False, refused=2), seen(3, None, None), episode(4),
            seen(5, 2, True, status="failed")]
    s = summarise(manifest(), rows)
    assert s.n_evidence == 3 and s.first_seen_mean == 9.0
    assert s.first_seen_over_oracle == pytest.approx((6 / 3 + 12 / 4) / 2)
    assert s.never_seen == pytest.approx(1 / 3) and s.evidence_in_top_k == pytest.approx(1 / 3)
    assert s.refused_per_step == pytest.approx(3 / 48)  # 4 episodes record it, 12 steps each
    old = summarise(manifest(), [episode(0), episode(1)])
    assert old.n_evidence == 0 and math.isnan(old.never_seen) and math.isnan(old.refused_per_step)
    md = write_folders_report([write_run(tmp_path / "run", manifest(), rows)],
                              tmp_path / "out")[0].read_text()
    assert "| Method | First seen, step ↓ | First seen / oracle ↓ | Never seen ↓ |" in md
    assert "| efficienteqa | 9.00 | 2.50 | 33% | 33% | 6% | 3 |" in md
    bare = write_folders_report([write_run(tmp_path / "old", manifest(), [episode(0)])], tmp_path / "o2")
    assert "First seen" not in bare[0].read_text()


def test_parse_problems_are_summed_per_kind_of_call_and_tabled(tmp_path):
    """The explore, relevancy and answer calls' unread replies reach the run's
    summary and report; runs recorded before the counts existed show no table."""
    rows = [episode(0), episode(1), episode(2, status="failed")]
    rows[0]["extra"] = {"problems": {"explore": 3, "relevancy": 1, "answer": 0}}
    rows[1]["extra"] = {"problems": {"explore": 2, "relevancy": 0, "answer": 1}}
    s = summarise(manifest(), rows)
    assert s.problems == {"explore": 5, "relevancy": 1, "answer": 1}
    md = write_folders_report([write_run(tmp_path / "run", manifest(), rows)],
                              tmp_path / "out")[0].read_text()
    assert "| efficienteqa | 5 | 1 | 1 | 2 |" in md
    assert summarise(manifest(), [episode(0)]).problems == {}
    bare = write_folders_report([write_run(tmp_path / "old", manifest(), [episode(0)])], tmp_path / "o2")
    assert "Replies not read plainly" not in bare[0].read_text()


def test_a_recorded_label_reads_as_todays():
    """Runs recorded the paper answer's label citing the old specification; tables show it as
    today's label, so one back-end is not split in two."""
    from efficienteqa.stack import ANSWER_LABELS

    old = {**BACKENDS, "answer": "paper (M verbalized guesses, grouped; SPEC 3.5)"}
    new = {**BACKENDS, "answer": ANSWER_LABELS["paper"]}
    s = summarise(manifest(), [episode(0, backends=old), episode(1, backends=new)])
    assert s.backends["answer"] == [ANSWER_LABELS["paper"]]


def test_a_report_that_cannot_be_written_is_one_line(tmp_path):
    """Fault trial 2.16: ``report --out`` on a read-only disk ended in an ``OSError``
    traceback. Root writes past permissions, so files and folders in the way stand in for the
    read-only disk: each write that fails is one line naming the file."""
    from efficienteqa.eval.tables import publish_run, read_summaries

    folder = write_run(tmp_path / "run", manifest(), MIXED[:2])
    (summary,) = read_summaries([folder])
    (tmp_path / "file").write_text("x")
    with pytest.raises(EfficientEQAError, match="cannot write to .*file/rep: Not a directory"):
        write_run_report([summary], tmp_path / "file" / "rep")
    (tmp_path / "rep" / "report.md").mkdir(parents=True)
    with pytest.raises(EfficientEQAError, match="cannot write .*report.md: Is a directory "
                                                r"\(choose another --out folder\)"):
        write_run_report([summary], tmp_path / "rep")
    (folder / "summary.json").mkdir()
    with pytest.raises(EfficientEQAError, match="summary.json: Is a directory .make the run "
                                                "folder writable"):
        publish_run(folder, summary)
    (folder / "summary.json").rmdir()
    result = CliRunner().invoke(cli.app, ["report", str(folder), "--out",
                                          str(tmp_path / "file" / "rep")])
    assert isinstance(result.exception, EfficientEQAError)  # main() prints it as one line
    assert "cannot write to" in str(result.exception) and not (folder / "summary.json").exists()

