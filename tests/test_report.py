"""The episode report: self-contained HTML, and what headless Chromium shows of it."""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest
from PIL import Image

from agent_stubs import MentionScorer, seeking_model
from conftest import needs_egl
from efficienteqa.agent import AgentConfig
from efficienteqa.ask import ask
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.geometry import CameraSpec
from efficienteqa.mapping.visualize import EXPLORED
from efficienteqa.report.html import relevancy_svg
from efficienteqa.scenes import Scene, synthetic_questions
from efficienteqa.stack import Stack

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CURVE_BLUE, THRESHOLD_RED = (0x33, 0x66, 0x99), (0xDD, 0x33, 0x33)


def _steps(sims, thresholds):
    return [{"step": i + 1, "sim": s, "threshold": t} for i, (s, t) in enumerate(zip(sims, thresholds))]


def test_curve_draws_sims_threshold_and_stop():
    svg = relevancy_svg(_steps([0.1, 0.2, 0.15, 0.9], [None, None, 0.4, 0.45]), 3.0, 10, 4, [4])
    assert svg.startswith("<svg") and svg.count("<circle") == 4
    assert "mu + 3 sigma" in svg and 'stroke-dasharray="6 4"' in svg
    assert "step 4: Sim 0.900" in svg and 'stroke="#d33" stroke-width="2"/>' in svg


def test_curve_without_valid_frames_says_so():
    assert "No valid frame" in relevancy_svg(_steps([None], [None]), 3.0, 10, None)


@pytest.fixture(scope="module")
def report(catalog, tmp_path_factory):
    env = SyntheticEnv(generate_house(4, catalog, "builtin"), catalog, CameraSpec().scaled(320, 240))
    questions = synthetic_questions(env)
    q = next(x for x in questions if x.id == "syn-4-10")
    out = tmp_path_factory.mktemp("report")
    try:
        done = ask(q.question, Scene(env, "synthetic:4 (builtin)", questions), out,
                   stack=Stack(grouping="rules", explore_scorer="vlm"), model=seeking_model("desk", "office"),
                   relevancy=MentionScorer("desk", "office"), config=AgentConfig(max_steps=30))
    finally:
        env.close()
    return done


@needs_egl
def test_report_is_self_contained_and_complete(report):
    html = report.report_html.read_text()
    assert "http://" not in html.replace('xmlns="http://www.w3.org/2000/svg"', "")
    assert "https://" not in html and "<script" not in html
    assert html.count('alt="frame ') == report.result.steps + len(report.result.retrieved)
    assert f"Retrieved top-{len(report.result.retrieved)} frames" in html
    assert "What colour is the desk in the office?" in html and "black" in html
    assert "Semantic-sensor perception" in html  # says the model read text, not pixels
    assert html.count("<details>") == report.record["model"]["calls"]


@needs_egl
@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="no chromium (apt-get install chromium)")
def test_chromium_shows_the_map_and_the_relevancy_curve(report, tmp_path):
    shot = tmp_path / "shot.png"
    subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                    "--disable-background-networking", "--disable-component-update",
                    "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}",
                    "--hide-scrollbars", "--window-size=1100,1500", f"--screenshot={shot}",
                    report.report_html.as_uri()],
                   check=True, capture_output=True, timeout=120)
    rgb = np.asarray(Image.open(shot).convert("RGB")).astype(int)

    def rows_with(colour, tol=6):
        hit = (np.abs(rgb - np.array(colour)) <= tol).all(axis=2)
        return np.nonzero(hit.sum(axis=1) > 0)[0], int(hit.sum())

    map_rows, map_px = rows_with(EXPLORED, tol=2)
    curve_rows, curve_px = rows_with(CURVE_BLUE, tol=12)
    red_rows, red_px = rows_with(THRESHOLD_RED, tol=12)
    assert map_px > 2000, "the map's explored floor is not on screen"
    assert curve_px > 150 and red_px > 50, "the relevancy curve or its threshold is not on screen"
    assert np.median(curve_rows) > np.median(map_rows)  # the curve comes after the map
