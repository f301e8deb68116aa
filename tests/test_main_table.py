"""The main table's benchmark (results/main-heldout/) on one question: every method runs on the same
episodes, against the test server (tests/vlm_server.py: every prompt of every method answered in
its format, as a real server would), and the report pairs them against white-box ExploreEQA."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from clirun import run_cli
from conftest import needs_egl
from vlm_server import servers

ROOT = Path(__file__).resolve().parents[1]
RUNS = ("default", "pixels", "paper-offline", "paper-offline-pixels", "explore-eqa",
        "explore-eqa-blackbox", "explore-eqa-verbalized-prompt", "explore-eqa-per-token",
        "frontier-only", "random", "blind")


@needs_egl
@pytest.mark.slow
def test_the_main_table_runs_every_method_on_one_question(tmp_path, capfd, monkeypatch):
    """The script runs as users run it, with ``EQA`` a stand-in that records each command; the
    commands it gave then run here, in this process (no interpreter start and model load per
    method), and their output goes where the script's would."""
    calls = tmp_path / "calls.jsonl"
    shim = tmp_path / "efficienteqa"
    shim.write_text(f"#!/bin/sh\nexec {sys.executable} -c 'import json, sys; "
                    f"open(sys.argv[1], \"a\").write(json.dumps(sys.argv[2:]) + chr(10))' "
                    f"{calls} \"$@\"\n")
    shim.chmod(0o755)
    with servers() as start:
        model = f"openai:test-vlm@{start().base_url}"
        env = {**os.environ, "LIMIT": "1", "DATASET": "synthetic:4", "OUT": str(tmp_path / "runs"),
               "EQA": str(shim), "JUDGE": model, "EFFICIENTEQA_CACHE": str(tmp_path / "cache"),
               "ARGS": f"--vlm {model} --assets builtin --max-steps 2 --relevancy overlap "
                       "--grouping rules"}
        script = subprocess.run(["bash", str(ROOT / "experiments" / "main_table.sh")], cwd=ROOT,
                                env=env, capture_output=True, text=True, timeout=60)
        assert script.returncode == 0, script.stdout + script.stderr
        commands = [json.loads(line) for line in calls.read_text().splitlines()]
        assert [c[0] for c in commands] == ["eval"] * len(RUNS) + ["report"]
        results = [run_cli(c, env, capfd, monkeypatch) for c in commands]
    said = "".join(r.said for r in results)
    assert "Traceback" not in said and [r.returncode for r in results] == [0] * len(results), said
    result = results[-1]
    table = [line for line in result.stdout.splitlines()
             if line.startswith("| ") and not line.startswith("| Method")]
    assert len(table) == len(RUNS)
    questions = None
    for name in RUNS:
        run = tmp_path / "runs" / name
        rows = [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()]
        assert [r["status"] for r in rows] == ["done"], name
        assert all(r["rule"] is not None and r["judge"] is not None for r in rows), name
        ids = [r["id"] for r in rows]
        assert questions in (None, ids)  # the same questions for every method
        questions = ids
        assert (run / "summary.json").is_file() and (run / "report.html").is_file()
        if name.startswith("explore-eqa"):  # the lazy best-step answer: at most a call a frame
            assert all(1 <= r["usage"]["calls"] <= r["extra"]["valid_frames"] for r in rows)
    # Every row but the reference is paired with white-box ExploreEQA on the question.
    assert sum(cells.strip() == "1" for line in table for cells in line.split("|")[-2:-1]) == len(RUNS) - 1


def test_every_row_is_a_shipped_configuration():
    """The rows name presets (config/toml/NAME.toml) instead of spelling out flag lists;
    the paper row is the paper's algorithm on the offline stack, and each of the two has a row
    seeing through the pixel network."""
    import re

    from efficienteqa.config.presets import preset_names

    script = (ROOT / "experiments" / "main_table.sh").read_text()
    rows = dict(re.findall(r"^run (\S+) --preset (\S+)$", script, flags=re.M))
    assert set(rows) == set(RUNS)
    assert all(preset == name for name, preset in rows.items())  # a row is named as its preset
    assert set(rows.values()) <= set(preset_names())
    assert not re.search(r"^run .*--(?!preset)", script, flags=re.M)  # no flag lists


def test_the_published_main_table_folders_are_named_as_their_presets():
    """results/main-heldout/NAME holds the run of preset NAME (NAME-vN: an earlier run of it;
    the paraphrase split and the combined report apart)."""
    import re

    from efficienteqa.config.presets import preset_names

    published = ROOT / "results" / "main-heldout"
    names = {re.sub(r"-v\d+$", "", f.name) for f in published.iterdir()
             if (f / "run.json").is_file() and not f.name.startswith("paraphrase")}
    assert names and names <= set(preset_names()), names - set(preset_names())
