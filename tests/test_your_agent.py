"""A user's agent (examples/your_agent.py) scored through `efficienteqa eval`, as the docs say:
the runner, the rule judge, the record of the agent's name and code, a paired report."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from clirun import run_cli
from conftest import needs_egl
from efficienteqa.eval.runner import episode_folder
from vlm_server import Options, servers

ROOT = Path(__file__).resolve().parents[1]
METHOD = "your_agent:OpenSpaceWalker"


@pytest.fixture
def vlm(monkeypatch):
    # the user's cache: its converted furniture (a private one would convert it, ~50 s); the
    # test server's replies are not found there again, its port differs every time
    monkeypatch.syspath_prepend(str(ROOT / "examples"))
    with servers() as start:
        yield start(Options())


def _env(tmp_path: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "OPENAI_API_KEY"}
    return {**env, "COLUMNS": "200"}


@needs_egl
def test_the_example_agent_is_scored_by_eval_and_paired_with_the_default(vlm, tmp_path, capfd,
                                                                         monkeypatch):
    import your_agent

    monkeypatch.setattr(your_agent.OpenSpaceWalker, "steps", 2)  # three frames: a short walk
    out = tmp_path / "walker"
    done = run_cli(["eval", "--eval.method", METHOD, "--eval.limit", "1",
                    "--backends.vlm", f"openai:test-vlm@{vlm.base_url}", "--out", str(out)],
                   _env(tmp_path), capfd, monkeypatch)
    assert done.returncode == 0, done.said
    run = json.loads((out / "run.json").read_text())
    assert run["method"] == METHOD and run["agent"]["name"] == "open-space-walker"
    assert run["agent"]["module"] == "your_agent" and len(run["agent"]["code_version"]) == 12
    (row,) = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    assert row["status"] == "done" and row["steps"] == 3 and row["answer"]  # start + 2 moves
    assert row["rule"]["score"] in (1, 5)  # graded by the rule judge
    assert row["evidence_first_seen_step"] is None  # three views from the start: not yet
    prompts = [json.dumps(r.body) for r in vlm.requests if "What you saw" in json.dumps(r.body)]
    assert len(prompts) == 1 and row["question"] in prompts[0]
    episode = json.loads((episode_folder(out, row["id"]) / "episode.json").read_text())
    assert episode["answer"] == row["answer"] and len(episode["poses"]) == row["steps"]
    paired = run_cli(["report", str(out), "--paired-against",
                      str(ROOT / "results" / "main-heldout" / "default")],
                     _env(tmp_path), capfd, monkeypatch)
    assert paired.returncode == 0, paired.said
    difference = json.loads((out / "summary.json").read_text())["paired"]
    assert difference["n"] == 1 and difference["reference"] == "efficienteqa"  # the default row


def test_an_agent_class_refuses_the_built_in_agents_settings(tmp_path, capfd, monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "examples"))
    done = run_cli(["eval", "--eval.method", METHOD, "--explore.max-steps", "3", "--out",
                    str(tmp_path / "x")], _env(tmp_path), capfd, monkeypatch)
    assert done.returncode != 0 and "Traceback" not in done.said
    assert "your own agent" in done.said and not (tmp_path / "x" / "run.json").exists()


def test_an_unknown_agent_name_fails_in_one_line(tmp_path, capfd, monkeypatch):
    done = run_cli(["eval", "--eval.method", "no-such-agent", "--out", str(tmp_path / "x")],
                   _env(tmp_path), capfd, monkeypatch)
    assert done.returncode != 0 and "unknown method 'no-such-agent'" in done.said
    assert "Traceback" not in done.said


def test_an_installed_agent_is_found_by_its_entry_point_name(monkeypatch):
    """A package that names its agent in the entry points `efficienteqa.agents` runs as
    `--eval.method NAME`."""
    from importlib.metadata import EntryPoint

    from efficienteqa.eval import agents
    from efficienteqa.eval.methods import resolve

    monkeypatch.syspath_prepend(str(ROOT / "examples"))
    point = EntryPoint("walker", "your_agent:OpenSpaceWalker", agents.ENTRY_POINTS)
    monkeypatch.setattr(agents, "entry_points", lambda group: [point] if group == point.group
                        else [])
    assert agents.load_method("walker").__name__ == "OpenSpaceWalker"
    assert resolve("walker").__name__ == "OpenSpaceWalker"
    assert agents.agent_identity("walker")["name"] == "open-space-walker"


class _ToTheOracle:
    """Goes where the oracle sees the evidence (the test gives it the pose), then answers."""

    goal: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def reset(self, question, info):
        self.moved = False

    def act(self, observation):
        from efficienteqa.envs.episode import answer, move

        if self.moved:
            return answer("a coffee maker")
        self.moved = True
        return move(*self.goal)


@needs_egl
def test_a_user_agents_record_says_when_the_evidence_came_into_view(tmp_path):
    """The method reads the question's evidence from the ground truth, as for the built-in
    agent; the agent itself is given only the words."""
    from efficienteqa.datasets import load_dataset
    from efficienteqa.eval.agents import run_agent
    from efficienteqa.eval.spec import RunSpec

    q = load_dataset("synthetic")[0]
    assert q.oracle_steps == 2  # the start view, then one move of at most 3 m
    agent = _ToTheOracle()
    agent.goal = tuple(q.source["oracle_pose"])
    done = run_agent(agent, q, RunSpec.of("tests:_ToTheOracle", "synthetic"), tmp_path)
    assert (done.steps, done.evidence_first_seen_step, done.answer) == (2, 2, "a coffee maker")
