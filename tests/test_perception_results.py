"""docs/perception.md's tables are what `efficienteqa perception table` makes of the published
figures (results/perception/heldout.json, training-style poses, and walks.json, the agent's
walks), and the figures say what they were measured on."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from efficienteqa import cli
from efficienteqa.datasets.synthetic import parse_seeds
from efficienteqa.perception.pixels.evaluate import markdown_table
from efficienteqa.perception.pixels.houses import TRAIN_SEEDS

ROOT = Path(__file__).resolve().parents[1]
PUBLISHED = [ROOT / "results" / "perception" / name for name in ("heldout.json", "walks.json")]
# close reads on and off, on the same frames (docs/perception.md, "Close reads")
CLOSE_READS = [ROOT / "results" / "perception" / f"{name}-close-reads{off}.json"
               for name in ("heldout", "walks") for off in ("", "-off")]


def test_the_docs_tables_are_generated_from_the_published_figures():
    doc = (ROOT / "docs" / "perception.md").read_text()
    blocks = re.findall(r"<!-- perception: (\S+) -->\n(.*?)\n<!-- /perception -->", doc, re.S)
    assert sorted(ROOT / path for path, _ in blocks) == sorted(PUBLISHED)
    for path, table in blocks:
        figures = json.loads((ROOT / path).read_text())
        assert table.strip() == markdown_table(figures).strip(), path
        printed = CliRunner().invoke(cli.app, ["perception", "table", str(ROOT / path)])
        assert printed.exit_code == 0 and printed.output.strip() == markdown_table(figures).strip()


@pytest.mark.parametrize("path", PUBLISHED + CLOSE_READS, ids=lambda p: p.name)
def test_the_figures_come_from_houses_the_network_never_trained_on(path):
    figures = json.loads(path.read_text())
    houses = parse_seeds(figures["houses"])
    assert not set(houses) & set(TRAIN_SEEDS)
    if figures["poses"] == "training-style":
        assert figures["frames"] == len(houses) * figures["frames_per_house"]
    else:  # a walk shorter than frames_per_house gives all its frames
        assert len(houses) <= figures["frames"] <= len(houses) * figures["frames_per_house"]
    assert figures["slices"]["all"]["objects"] > 0
    assert "dirty" not in figures["code_version"]  # published from a clean commit


def test_the_close_reads_figures_are_on_and_off_on_the_same_frames():
    def about(path: Path) -> dict[str, object]:
        return {k: v for k, v in json.loads(path.read_text()).items()
                if k not in ("slices", "median_ms", "close_reads")}

    for on, off in (CLOSE_READS[:2], CLOSE_READS[2:]):
        assert about(on) == about(off)
    assert [json.loads(p.read_text())["close_reads"] for p in CLOSE_READS] == [2, 0, 2, 0]
