"""Ablations replayed from one episode explored to its budget (DESIGN 3.6): a replayed
stop and retrieval equal the live ones; the replayed stop follows DESIGN 3.4 for every Z_th."""

from __future__ import annotations

import json

import numpy as np
import pytest

from agent_stubs import MentionScorer, seeking_model
from conftest import needs_egl
from efficienteqa.agent import AgentConfig
from efficienteqa.ask import ask
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.eval.replay import (
    Frame,
    answer_prompt_matches,
    recorded_frames,
    reobserve,
    replay_episode_stop,
    replay_stop,
    retrieve,
    stop_config_for,
)
from efficienteqa.geometry import CameraSpec
from efficienteqa.perception.semantic import SemanticPerception
from efficienteqa.scenes import Scene, synthetic_questions
from efficienteqa.stack import Stack
from efficienteqa.stop import StopConfig

CAMERA = CameraSpec().scaled(320, 240)


def _paper_stop(sims: list[float], z_th: float, min_step: int = 10) -> int | None:
    """DESIGN 3.4 written out: the first step t >= min_step whose z against the mean and sample
    std of the frames before it exceeds z_th (steps from 1)."""
    for t in range(min_step, len(sims) + 1):
        history = np.array(sims[:t - 1])
        sigma = history.std(ddof=1) if len(history) >= 2 else 0.0
        if sigma > 0 and (sims[t - 1] - history.mean()) / sigma > z_th:
            return t
    return None


# Noise, then spikes of growing height: a lower Z_th stops at an earlier spike.
HAND_SIMS = ([0.10, 0.14, 0.12, 0.16, 0.11, 0.13, 0.15, 0.12, 0.14, 0.13]
             + [0.16, 0.13, 0.18, 0.12, 0.14, 0.21, 0.13, 0.12, 0.30, 0.14])


@pytest.mark.parametrize(("z_th", "expected"), [(1, 11), (2, 13), (3, 16), (4, 19)])
def test_replayed_paper_stop_is_spec_3_4_for_each_z_th(z_th, expected):
    sims = list(enumerate(HAND_SIMS, start=1))
    config = StopConfig(rule="paper", z_th=z_th)
    assert replay_stop(sims, config) == expected == _paper_stop(HAND_SIMS, z_th)


def test_the_replayed_stop_never_fires_before_min_step_nor_when_disabled():
    sims = [0.1, 0.12, 0.11, 0.9] + [0.1, 0.12] * 8  # a spike at step 4
    pairs = list(enumerate(sims, start=1))
    assert replay_stop(pairs, StopConfig(rule="paper", z_th=1)) is None
    assert replay_stop(pairs, StopConfig(rule="paper", z_th=1, min_step=4)) == 4
    assert replay_stop(pairs, StopConfig(rule="paper", z_th=1, min_step=4, enabled=False)) is None
    # The look-back rule finds the step-4 spike at the minimum step.
    assert replay_stop(pairs, StopConfig(rule="lookback", z_th=1)) == 10


def test_invalid_steps_are_skipped_and_the_recorded_end_kept():
    per_step = [{"step": s, "pose": [0.0, 0.0, 0.0], "valid": s != 12,
                 "sim": None if s == 12 else v} for s, v in enumerate(HAND_SIMS, start=1)]
    frames = recorded_frames(per_step)
    assert [f.step for f in frames] == [s for s in range(1, 21) if s != 12]
    # Step 13's spike is tested against 11 earlier frames, step 12 not among them.
    paper = stop_config_for({"rule": "paper", "enabled": False}, z_th=2)
    assert paper.enabled and paper.z_th == 2.0
    stopped = replay_episode_stop(per_step, "budget", paper)
    assert (stopped.step, stopped.steps, stopped.reason) == (13, 13, "relevancy")
    never = replay_episode_stop(per_step, "explored", stop_config_for(paper, z_th=50))
    assert (never.step, never.steps, never.reason) == (None, 20, "explored")
    with pytest.raises(ValueError, match="no-early-stop"):
        replay_episode_stop(per_step, "relevancy", paper)


def test_retrieval_keeps_distinct_views_as_the_agent_does():
    frames = [Frame(1, 0.5, (0.0, 0.0, 0.0), "a sofa"), Frame(2, 0.9, (0.0, 0.0, 0.0), "a sofa"),
              Frame(3, 0.7, (3.0, 0.0, 0.0), "a desk"), Frame(4, 0.8, (6.0, 0.0, 0.0), "a bed")]
    assert [r.step for r in retrieve(frames, 3)] == [2, 4, 3]
    assert [r.step for r in retrieve(frames, 3, distinct_views=False)] == [2, 4, 3]
    assert [r.step for r in retrieve(frames, 4, distinct_views=False)] == [2, 4, 3, 1]
    assert [r.step for r in retrieve(frames, 4, upto=3)] == [2, 3]


@pytest.fixture(scope="module")
def house4(catalog):
    env = SyntheticEnv(generate_house(4, catalog, "builtin"), catalog, CAMERA)
    questions = synthetic_questions(env)
    yield Scene(env, "synthetic:4 (builtin)", questions), next(q for q in questions if q.id == "syn-4-10")
    env.close()


def _live(scene, q, tmp_path, stop: StopConfig, top_k: int = 5, max_steps: int = 30):
    desk = scene.env.house.object(q.evidence[0])
    room = scene.env.house.room(desk.room_id).name
    return ask(q.question, scene, tmp_path, stack=Stack(grouping="rules", explore_scorer="vlm"),
               model=seeking_model(desk.category, room), relevancy=MentionScorer(desk.category, room),
               config=AgentConfig.of(max_steps=max_steps, seed=1, stop=stop, top_k=top_k),
               report=False)


@needs_egl
@pytest.mark.parametrize(("stop", "top_k"), [(StopConfig(), 5), (StopConfig(rule="paper", z_th=2), 3)])
def test_a_replayed_stop_equals_the_live_one(house4, tmp_path, stop, top_k):
    """The same episode live with early stop, and explored to its budget: replaying the
    second's recorded Sims with the first's stop gives the first's stop step, and retrieval up
    to it the first's K frames and answer prompt."""
    scene, q = house4
    live = _live(scene, q, tmp_path / "live", stop, top_k).record
    # explored on past the live stop (three steps do: the replay reads up to the stop)
    full = _live(scene, q, tmp_path / "full", StopConfig(enabled=False), top_k,
                 max_steps=live["steps"] + 3).record
    assert live["stop_reason"] == "relevancy" and full["stop_reason"] != "relevancy"
    assert full["steps"] > live["steps"]
    def path(record):  # the same exploration up to the stop
        return [(s["step"], s["pose"], s["valid"], s["sim"]) for s in record["per_step"]]

    assert path(full)[:live["steps"]] == path(live)

    replayed = replay_episode_stop(full["per_step"], full["stop_reason"],
                                   stop_config_for(full["config"]["stop"], z_th=stop.z_th,
                                                   rule=stop.rule))
    assert (replayed.step, replayed.steps, replayed.reason) == (live["steps"], live["steps"], "relevancy")

    # Re-observed at the recorded poses, described by the stack's perception as the agent's.
    perception = SemanticPerception(scene.env.scene_labels())
    frames = reobserve(scene.env.observe, perception.frame, recorded_frames(full["per_step"]))
    best = retrieve(frames, top_k, upto=replayed.step)
    assert [(r.step, r.sim) for r in best] == [(d["step"], d["sim"]) for d in live["retrieved"]]
    answer = next(e for e in live["model"]["exchanges"] if e["phase"] == "answer")
    assert answer_prompt_matches(frames, live["retrieved"], answer["prompt"], q.question)
    assert not answer_prompt_matches(frames, live["retrieved"], answer["prompt"])  # focused


def _fake_run(root, episodes: dict[str, list[float]]):
    """A run folder as `efficienteqa eval --no-early-stop` writes it, without the scenes."""
    from efficienteqa.eval.records import append_episode
    from efficienteqa.eval.runner import episode_folder
    from efficienteqa.records import plain, write_json

    write_json(root / "run.json", {"method": "frontier-only", "dataset": "synthetic",
                                   "stack": {"vlm": "local:none"}, "assets": "builtin"})
    for eid, sims in episodes.items():
        append_episode(root / "episodes.jsonl", {"id": eid, "status": "done", "scene": "synthetic:0"})
        per_step = [{"step": s, "pose": [float(s), 0.0, 0.0], "valid": True, "sim": v}
                    for s, v in enumerate(sims, start=1)]
        config = AgentConfig.of(stop=StopConfig(rule="paper", enabled=False))
        write_json(episode_folder(root, eid) / "episode.json",
                   plain({"per_step": per_step, "stop_reason": "budget", "budget": len(sims),
                          "config": config, "question": "q?", "model": {"exchanges": []},
                          "retrieved": []}))


def test_the_benchmark_replays_stops_without_a_model_and_resumes(tmp_path, capsys):
    from experiments import ablation_replay as bench

    flat = [0.1] * 20  # sigma 0: the guard never stops it
    _fake_run(tmp_path, {"d/a": HAND_SIMS, "d/b": flat})
    argv = [str(tmp_path), "--no-answer", "--z-th", "1,2,3,4", "--k", "1,3"]
    bench.main(argv)
    summary = __import__("json").loads((tmp_path / "ablation_replay.json").read_text())
    z = {r["stop"]: r for r in summary["z_th"]}
    assert z["budget"]["mean_steps"] == 20 and z["budget"]["relevancy_stop_share"] == 0
    # Episode a stops at 11/13/16/19 (DESIGN 3.4 above); the flat episode b never stops.
    assert z["paper@z=1"]["mean_steps"] == (11 + 20) / 2
    assert z["paper@z=4"]["mean_steps"] == (19 + 20) / 2 and z["paper@z=4"]["relevancy_stop_share"] == 50
    assert summary["k"] == [{"k": k, **{name: None for name in z}} for k in (1, 3, 5)]
    lines = (tmp_path / "ablation_replay.jsonl").read_text().splitlines()
    assert len(lines) == 2 * 5 * 3  # episodes x (budget + 4 Z_th) x K (1, 3 and the run's 5)
    bench.main(argv)  # resumed: nothing left to do
    assert (tmp_path / "ablation_replay.jsonl").read_text().splitlines() == lines
    assert "paper@z=3" in capsys.readouterr().out


def test_a_rules_gates_recorded_verdicts_are_replayed_with_the_sims():
    """A gated stop (the default) is replayed as live: a frame the gate refused never stops the
    robot, one it passed stops at the lower ``z_gated``."""
    sims = [0.1, 0.2, 0.15, 0.2, 0.1, 0.9, 0.3, 0.7]  # step 8: z 1.49
    ok = [False, False, False, False, False, False, False, True]
    per_step = [{"step": s, "pose": [0.0, 0.0, 0.0], "valid": True, "sim": v,
                 "gate": {"ok": g, "why": ""}} for s, (v, g) in enumerate(zip(sims, ok), start=1)]
    config = StopConfig(rule="paper", z_th=3, min_step=2)
    stopped = replay_episode_stop(per_step, "budget", config)
    assert (stopped.step, stopped.reason) == (8, "relevancy")  # not at the refused spike (6)
    ungated = [{k: v for k, v in s.items() if k != "gate"} for s in per_step]
    assert replay_episode_stop(ungated, "budget", config).step == 6


def test_the_z_th_rows_of_a_gated_run_vary_the_threshold_that_acts():
    """A run whose gate judged every frame (the default) stops a passed frame at z_gated: its
    Z_th rows vary that one, so they differ; a run without a gate varies Z_th."""
    from experiments.ablation_replay import acting_threshold

    sims = [0.30, 0.31, 0.29, 0.30, 0.32, 0.36, 0.30, 0.30]
    per_step = [{"step": s, "pose": [0.0, 0.0, 0.0], "valid": True, "sim": v,
                 "gate": {"ok": True, "why": ""}} for s, v in enumerate(sims, start=1)]
    recorded = {"rule": "paper", "z_th": 3.0, "min_step": 2, "enabled": False}
    assert acting_threshold(per_step) == "z_gated"
    ungated = [{k: v for k, v in s.items() if k != "gate"} for s in per_step]
    assert acting_threshold(ungated) == "z_th"
    stops = {z: replay_episode_stop(per_step, "budget",
                                    stop_config_for(recorded, z_th=z, gated=True)).step
             for z in (1.0, 2.0, 3.0, 4.0)}
    assert len(set(stops.values())) > 1, stops  # the rows differ
    untouched = {z: replay_episode_stop(per_step, "budget",
                                        stop_config_for(recorded, z_th=z)).step
                 for z in (1.0, 4.0)}
    assert len(set(untouched.values())) == 1  # varying Z_th under the gate changes nothing


def test_the_published_ablation_tables_are_generated_from_their_files():
    """docs/RESULTS.md's Z_th and K tables are what ``--markdown`` makes of the committed
    ablation_replay.json files, every one of which comes from a clean commit."""
    import re
    from pathlib import Path

    from experiments.ablation_replay import markdown_tables

    root = Path(__file__).resolve().parents[1]
    text = (root / "docs" / "RESULTS.md").read_text()
    blocks = re.findall(r"<!-- ablation: (\S+) -->\n(.*?)<!-- /ablation -->", text, re.S)
    assert {path for path, _ in blocks} >= {"results/ablation-heldout/default/ablation_replay.json",
                                            "results/ablation-heldout/default-v1/ablation_replay.json"}
    for path, body in blocks:
        result = json.loads((root / path).read_text())
        assert body == markdown_tables(result), path
        assert "dirty" not in result["code_version"], path
    current = json.loads((root / "results/ablation-heldout/default/ablation_replay.json").read_text())
    assert current["threshold"] == "z_gated"  # the default's gate: the threshold that acts
    steps = [r["mean_steps"] for r in current["z_th"] if r["rule"] is not None]
    assert steps == sorted(steps) and len(set(steps)) == len(steps)  # the knob acts
