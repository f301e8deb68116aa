"""docs/perception.md's table is what `efficienteqa perception table` makes of the published
figures (results/perception/heldout.json), and the figures say what they were measured on."""

from __future__ import annotations

import json
import re
from pathlib import Path

from typer.testing import CliRunner

from efficienteqa import cli
from efficienteqa.datasets.synthetic import parse_seeds
from efficienteqa.perception.pixels.dataset import TRAIN_SEEDS
from efficienteqa.perception.pixels.evaluate import markdown_table

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "results" / "perception" / "heldout.json"


def test_the_docs_table_is_generated_from_the_published_figures():
    figures = json.loads(FIGURES.read_text())
    doc = (ROOT / "docs" / "perception.md").read_text()
    block = re.search(r"<!-- perception: (\S+) -->\n(.*?)\n<!-- /perception -->", doc, re.S)
    assert block is not None and (ROOT / block.group(1)) == FIGURES
    assert block.group(2).strip() == markdown_table(figures).strip()
    printed = CliRunner().invoke(cli.app, ["perception", "table", str(FIGURES)])
    assert printed.exit_code == 0 and printed.output.strip() == markdown_table(figures).strip()


def test_the_figures_come_from_houses_the_network_never_trained_on():
    figures = json.loads(FIGURES.read_text())
    houses = parse_seeds(figures["houses"])
    assert not set(houses) & set(TRAIN_SEEDS)
    assert figures["frames"] == len(houses) * figures["frames_per_house"]
    assert figures["slices"]["all"]["objects"] > 0
