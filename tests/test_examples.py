"""The examples in examples/ run as users run them, against the test server with real servers'
habits (tests/vlm_server.py): each writes its episode and prints its answer."""

from __future__ import annotations

import json
import runpy
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import needs_egl
from vlm_server import Options, servers

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture
def vlm(tmp_path, monkeypatch):
    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    with servers() as start:
        yield start(Options())


def run_example(name: str, args: list[str], monkeypatch) -> None:
    monkeypatch.setattr(sys, "argv", [name, *args])
    runpy.run_path(str(EXAMPLES / name), run_name="__main__")


@needs_egl
def test_ask_from_python(vlm, tmp_path, monkeypatch, capsys):
    out = tmp_path / "ask"
    run_example("ask_from_python.py", ["--vlm", f"openai:test-vlm@{vlm.base_url}",
                                       "--perception", "rgb", "--max-steps", "3",
                                       "--assets", "builtin", "--out", str(out)], monkeypatch)
    printed = capsys.readouterr().out
    assert printed.startswith("answer: ") and "report: " in printed
    episode = json.loads((out / "episode.json").read_text())
    assert episode["question"] == "What is on the desk in the office?" and episode["steps"] <= 3
    assert (out / "report.html").is_file()


def test_a_custom_environment(vlm, tmp_path, monkeypatch, capsys):
    out = tmp_path / "box"
    run_example("custom_environment.py", ["--vlm", f"openai:test-vlm@{vlm.base_url}",
                                          "--max-steps", "4", "--out", str(out)], monkeypatch)
    assert capsys.readouterr().out.startswith("answer: ")
    episode = json.loads((out / "episode.json").read_text())
    assert episode["scene"] == "box-room" and 1 <= episode["steps"] <= 4
    assert not vlm.image_errors and any(r.images for r in vlm.requests)


def test_the_custom_environment_sees_its_box_where_it_is():
    """The ray caster's depth and pose back-project the red pixels onto the box."""
    from efficienteqa.geometry import Pose2D, backproject

    sys.path.insert(0, str(EXAMPLES))
    try:
        from custom_environment import BOX, BoxRoom
    finally:
        sys.path.remove(str(EXAMPLES))
    env = BoxRoom()
    obs, _ = env.reset(options={"start": Pose2D(1.0, 1.6, 0.0)})
    red = (obs.rgb[..., 0] > 120) & (obs.rgb[..., 1] < 60)
    assert red.sum() > 50
    points = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[red]
    (x0, y0, z0), (x1, y1, z1) = BOX
    assert np.all((points[:, 0] > x0 - 0.02) & (points[:, 0] < x1 + 0.02))
    assert np.all((points[:, 2] > z0 - 0.02) & (points[:, 2] < z1 + 0.02))
    assert not env.is_navigable(4.5, 1.5) and env.is_navigable(1.0, 1.6)


@needs_egl
def test_a_run_built_in_python_is_the_run_the_episode_records(vlm, tmp_path):
    """``ask(..., run=)`` takes the whole tree (``presets.run_config``: checked as the command
    line checks it); the episode records that tree's agent and back-ends."""
    from efficienteqa.ask import ask
    from efficienteqa.config.presets import run_config
    from efficienteqa.errors import EfficientEQAError
    from efficienteqa.records import plain
    from efficienteqa.stack import Stack

    run = run_config("default", {"backends.vlm": f"openai:test-vlm@{vlm.base_url}",
                                 "backends.perception": "rgb", "backends.relevancy": "vlm-match",
                                 "stop.z_gated": 2.0, "explore.max_steps": 3,
                                 "scene.assets": "builtin"})
    assert run.stop.z_gated == 2.0 and run.scene.assets == "builtin"
    done = ask("What is on the desk in the office?", "synthetic:0", tmp_path, run=run,
               report=False)
    episode = json.loads(done.episode_json.read_text())
    assert episode["config"] == plain(run.agent) and episode["steps"] <= 3
    with pytest.raises(ValueError, match="not both"):
        ask("Where is the sofa?", "synthetic:0", tmp_path, run=run, stack=Stack())
    with pytest.raises(EfficientEQAError, match="does not act"):
        run_config("paper-offline", {"stop.z_gated": 2.0})
