"""The episode in rerun (``report.rerun_log``): a short synthetic episode logged to a .rrd file
and read back through rerun's chunk API, each artefact at the steps it belongs to; a failed
episode's recording; and the one-line refusals, before any work."""

from __future__ import annotations

import importlib.util
import math
import sys
from typing import Any

import numpy as np
import pytest

from agent_stubs import MentionScorer, seeking_model
from conftest import needs_egl
from efficienteqa import cli
from efficienteqa.agent import AgentConfig
from efficienteqa.ask import ask
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import generate_house
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import CameraSpec
from efficienteqa.mapping.visualize import map_image
from efficienteqa.report import rerun_log as rl
from efficienteqa.report import rerun_target
from efficienteqa.scenes import Scene, synthetic_questions
from efficienteqa.stack import Stack
from efficienteqa.vc.parse import clean_answer

needs_rerun = pytest.mark.skipif(importlib.util.find_spec("rerun") is None,
                                 reason="the rerun extra is not installed")
NOT_INSTALLED = "the rerun SDK is not installed (pip install 'efficienteqa[rerun]')"
RDF, RIGHT_HAND_Z_UP = [3, 2, 5], [3, 5, 1]  # rerun's ViewDir: up 1, down 2, right 3, forward 5
W, H = 160, 120
FAST = {"reading": "rules", "matching": "words"}  # the same walk here, without loading MiniLM


class Rrd:
    """A .rrd file read back: the rows of one entity's component as (step, value), in the
    order they were logged (step None: static)."""

    def __init__(self, path: Any) -> None:
        from rerun.chunk import RrdReader

        reader = RrdReader(path)
        self.chunks = reader.stream().to_chunks()
        self.blueprints = reader.blueprints()

    def rows(self, entity: str, component: str) -> list[tuple[int | None, Any]]:
        out: list[tuple[int | None, Any]] = []
        for chunk in self.chunks:
            batch = chunk.to_record_batch()
            if chunk.entity_path != entity or component not in batch.schema.names:
                continue
            steps = (batch.column("step").to_pylist() if "step" in batch.schema.names
                     else [None] * batch.num_rows)
            out += [(s, v) for s, v in zip(steps, batch.column(component).to_pylist()) if v is not None]
        return out

    def by_step(self, entity: str, component: str) -> dict[int | None, Any]:
        """step -> the one value logged there (each step logs an entity at most once)."""
        rows = self.rows(entity, component)
        assert len({s for s, _ in rows}) == len(rows), f"{entity} {component}: a step twice"
        return dict(rows)


def _scene(catalog):
    env = SyntheticEnv(generate_house(4, catalog, "builtin"), catalog, CameraSpec().scaled(W, H))
    questions = synthetic_questions(env)
    return env, questions, next(x for x in questions if x.id == "syn-4-10")


@pytest.fixture(scope="module")
def episode(catalog, tmp_path_factory):
    """Ten steps at most in house 4 with a VLM that points at the desk: the explore module runs
    every step but the last, where relevancy stops the robot (measured: at step 10). Without
    the gate, a threshold acts at every step from the third (with the default gate, only on
    frames it passed); the question read by rules, so no MiniLM loads."""
    env, questions, q = _scene(catalog)
    out = tmp_path_factory.mktemp("rerun")
    seen: list = []
    try:
        done = ask(q.question, Scene(env, "synthetic:4 (builtin)", questions), out,
                   stack=Stack(grouping="rules", explore_scorer="vlm"),
                   model=seeking_model("desk", "office"), relevancy=MentionScorer("desk", "office"),
                   config=AgentConfig.of(max_steps=10, **FAST, gate="none"), report=False,
                   rerun=out / "episode.rrd",
                   on_step=lambda record, obs, step: seen.append((record, obs, step)))
    finally:
        env.close()
    return done, seen, Rrd(out / "episode.rrd")


@needs_egl
@needs_rerun
def test_every_frame_is_logged_under_its_pinhole_camera_at_its_pose(episode):
    done, seen, rrd = episode
    steps = [record.step for record, _, _ in seen]
    assert steps == list(range(1, done.result.steps + 1)) and len(steps) >= 5
    assert rrd.rows("/world", "ViewCoordinates:xyz") == [(None, [RIGHT_HAND_Z_UP])]
    rgb = rrd.by_step("/world/camera/rgb", "EncodedImage:media_type")
    assert list(rgb) == steps and {media for media, in rgb.values()} == {"image/jpeg"}
    depth = rrd.by_step("/world/camera/depth", "DepthImage:buffer")
    meters = rrd.by_step("/world/camera/depth", "DepthImage:meter")
    poses = rrd.by_step("/world/camera", "Transform3D:translation")
    turns = rrd.by_step("/world/camera", "Transform3D:mat3x3")
    pinholes = rrd.by_step("/world/camera", "Pinhole:image_from_camera")
    assert list(depth) == list(meters) == list(poses) == list(turns) == list(pinholes) == steps
    assert all(wh == [[W, H]] for wh in rrd.by_step("/world/camera", "Pinhole:resolution").values())
    assert all(xyz == [RDF] for xyz in rrd.by_step("/world/camera", "Pinhole:camera_xyz").values())
    for record, obs, _ in seen:
        s = record.step
        assert meters[s] == [1.0]
        logged = np.frombuffer(bytes(depth[s][0]), dtype=np.float32).reshape(H, W)
        assert np.array_equal(logged, obs.depth_m)  # metres as the frame has them
        assert np.allclose(poses[s], [obs.cam_to_world[:3, 3]], atol=1e-5)
        assert np.allclose(turns[s], [obs.cam_to_world[:3, :3].flatten(order="F")], atol=1e-6)
        assert np.allclose(pinholes[s], [obs.intrinsics.flatten(order="F")])


@needs_egl
@needs_rerun
def test_the_map_frontiers_prompts_and_target_of_each_explore_step(episode):
    done, seen, rrd = episode
    explored = [(record, step) for record, _, step in seen if step is not None]
    last = done.result.steps
    assert len(explored) == last - 1  # the stop step maps its frame and plans nothing
    maps = rrd.rows("/map", "Image:format")
    assert [s for s, _ in maps] == [record.step for record, _ in explored] + [last]
    # The last picture is the final map as report.html draws it, semantic heat included.
    result, decision = done.result, done.result.last_decision
    final = map_image(result.state, result.values, frontiers=decision.frontiers,
                      trajectory=result.trajectory, target_xy=decision.target_xy)
    (buffer,) = rrd.rows("/map", "Image:buffer")[-1][1]
    assert np.array_equal(np.frombuffer(bytes(buffer), np.uint8).reshape(final.shape), final)
    assert result.values.max() > 0 and not np.array_equal(final, map_image(
        result.state, None, frontiers=decision.frontiers, trajectory=result.trajectory,
        target_xy=decision.target_xy))
    frontiers = rrd.by_step("/world/frontiers", "Points3D:labels")
    cleared = rrd.by_step("/world/frontiers", "Clear:is_recursive")
    prompts = rrd.by_step("/world/prompts", "Points3D:labels")
    targets = rrd.by_step("/world/target", "Points3D:positions")
    assert frontiers and prompts and targets
    for record, step in explored:
        s, d = record.step, step.decision
        if d.frontiers:  # labels: member cells; radii grow with them
            assert frontiers[s] == [str(f.size) for f in d.frontiers] and s not in cleared
        else:
            assert s in cleared and s not in frontiers
        assert [label.split()[0] for label in prompts[s]] == [p.letter for p in step.prompts]
        if d.target_xy is not None:
            assert np.allclose(targets[s], [[*d.target_xy, rl.FLOOR_Z]], atol=1e-5)
    positions = rrd.by_step("/world/frontiers", "Points3D:positions")
    record, step = next((r, e) for r, e in explored if e.decision.frontiers)
    assert np.allclose(np.array(positions[record.step])[:, :2], [f.xy for f in step.decision.frontiers],
                       atol=1e-5)


@needs_egl
@needs_rerun
def test_the_trajectory_so_far_and_the_robots_pose_each_step(episode):
    done, seen, rrd = episode
    strips = rrd.by_step("/world/trajectory", "LineStrips3D:strips")
    robot = rrd.by_step("/world/robot", "Transform3D:translation")
    turns = rrd.by_step("/world/robot", "Transform3D:rotation_axis_angle")
    poses = [record.pose for record, _, _ in seen]
    assert list(strips) == list(robot) == list(turns) == list(range(1, len(poses) + 1))
    for s in strips:
        (strip,) = strips[s]
        assert np.allclose(strip, [[x, y, rl.FLOOR_Z] for x, y, _ in poses[:s]], atol=1e-5)
        x, y, yaw = poses[s - 1]
        assert np.allclose(robot[s], [[x, y, 0.0]], atol=1e-5)
        (turn,) = turns[s]
        assert turn["axis"] == [0.0, 0.0, 1.0] and math.isclose(turn["angle"], yaw, abs_tol=1e-6)


@needs_egl
@needs_rerun
def test_the_relevancy_curve_draws_the_threshold_that_acted_as_the_report_does(episode):
    done, seen, rrd = episode
    per_step = done.record["per_step"]  # what report.html draws its curve from
    scalar = {path: {s: v[0] for s, v in rrd.by_step(path, "Scalars:scalars").items()}
              for path in ("/relevancy/sim", "/relevancy/threshold", "/relevancy/tested",
                           "/relevancy/sim_abs", "/zscore/z", "/zscore/z_applied")}
    assert scalar["/relevancy/sim"] == pytest.approx(
        {s["step"]: s["sim"] for s in per_step if s["sim"] is not None})
    thresholds = {s["step"]: s["threshold"] for s in per_step if s["threshold"] is not None}
    assert len(thresholds) >= len(per_step) - 2  # from the third step on
    assert scalar["/relevancy/threshold"] == pytest.approx(thresholds)
    sims = {s["step"]: s["sim"] for s in per_step}
    assert any(s["tested_step"] != s["step"] for s in per_step)  # lookback: the best so far
    assert scalar["/relevancy/tested"] == pytest.approx(
        {s["step"]: sims[s["tested_step"]] for s in per_step if s["threshold"] is not None})
    assert scalar["/zscore/z"] == pytest.approx({s["step"]: s["z"] for s in per_step if s["z"] is not None})
    assert scalar["/zscore/z_applied"] == pytest.approx(
        {s["step"]: s["z_applied"] for s in per_step if s["z_applied"] is not None})
    # The default rule has "absolute": the Sim that stops whatever the baseline, every step.
    assert scalar["/relevancy/sim_abs"] == {s: AgentConfig().stop.sim_abs for s in scalar["/relevancy/sim"]}
    # The stop: the last step's tested frame is above the threshold that acted there.
    last = per_step[-1]
    assert done.result.stop_reason == "relevancy" and sims[last["tested_step"]] > last["threshold"]
    assert rrd.by_step("/relevancy/retrieved", "Scalars:scalars") == {
        step: [sim] for step, sim in done.result.retrieved}


@needs_egl
@needs_rerun
def test_the_end_holds_the_answer_the_stop_and_the_top_k_frames(episode):
    done, seen, rrd = episode
    result = done.result
    assert rrd.rows("/episode/question", "TextDocument:text") == [(None, [result.question])]
    ((at, (text,)),) = rrd.rows("/episode/answer", "TextDocument:text")
    assert at == result.steps and clean_answer(result.answer) == "black"
    assert f"**Answer:** black (confidence {result.confidence:.2f})" in text
    assert f"**Stop:** relevancy at step {result.steps} of {result.budget}" in text
    for rank, (step, sim) in enumerate(result.retrieved, 1):
        assert f"| {rank} | {step} | {sim:.3f} |" in text
        entity = f"/episode/retrieved/{rank}"
        assert rrd.rows(entity, "frame_step") == [(result.steps, [step])]
        assert rrd.rows(entity, "sim") == [(result.steps, [pytest.approx(sim)])]
        frame = rrd.rows(entity, "EncodedImage:blob")[0][1]
        assert frame == rrd.by_step("/world/camera/rgb", "EncodedImage:blob")[step]  # as captured
    assert len(result.retrieved) == AgentConfig().answer.top_k
    assert len(rrd.blueprints) == 1  # the viewer's default layout travels with the file
    lines = rrd.by_step("/episode/steps", "TextLog:text")
    assert list(lines) == list(range(1, result.steps + 1))
    (stop,) = lines[result.steps]
    assert stop.startswith(f"step {result.steps}  Sim 1.000") and "STOP" in stop


class _FailingScorer(MentionScorer):
    """Scores two frames, then fails as a relevancy server might."""

    def __init__(self) -> None:
        super().__init__("desk", "office")
        self.calls = 0

    def score(self, question, *, image=None, text=None):  # noqa: ANN001, ANN201
        self.calls += 1
        if self.calls > 2:
            raise RuntimeError("scripted failure")
        return super().score(question, image=image, text=text)


@needs_egl
@needs_rerun
def test_a_failed_episode_leaves_a_complete_recording_of_its_steps(catalog, tmp_path):
    """ask closes the log it was given (here the caller's, still referenced) when the episode
    fails: the file is complete, with the steps done and no answer."""
    from rerun.chunk import RrdReader

    env, questions, q = _scene(catalog)
    log = rl.RerunLog(tmp_path / "e.rrd", q.question)
    try:
        with pytest.raises(RuntimeError, match="scripted failure"):
            ask(q.question, Scene(env, "synthetic:4 (builtin)", questions), tmp_path,
                stack=Stack(grouping="rules", explore_scorer="vlm"),
                model=seeking_model("desk", "office"), relevancy=_FailingScorer(),
                config=AgentConfig.of(max_steps=6, **FAST), report=False, rerun=log)
    finally:
        env.close()
    assert log.closed and len(RrdReader(tmp_path / "e.rrd").store()) > 0  # the footer is written
    rrd = Rrd(tmp_path / "e.rrd")
    assert list(rrd.by_step("/world/camera/rgb", "EncodedImage:blob")) == [1, 2]
    assert list(rrd.by_step("/relevancy/sim", "Scalars:scalars")) == [1, 2]
    assert rrd.rows("/episode/answer", "TextDocument:text") == []


def test_without_rerun_ask_fails_in_one_line_before_any_work(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun raises ImportError
    with pytest.raises(EfficientEQAError) as error:  # the scene is never opened (it cannot be)
        ask("What colour is the sofa?", "hm3d:nowhere", tmp_path / "out", rerun=tmp_path / "e.rrd")
    assert str(error.value) == NOT_INSTALLED
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("target, said", [
    ("e.rrd", NOT_INSTALLED),
    ("live", "no rerun viewer can start here: no screen"),
    ("episode.txt", "--rerun takes a .rrd file or live, not '"),
])
def test_ask_command_refuses_in_one_line_before_the_scene_opens(target, said, monkeypatch, tmp_path,
                                                                capsys):
    if target == "e.rrd":
        monkeypatch.setitem(sys.modules, "rerun", None)
    elif importlib.util.find_spec("rerun") is None:
        pytest.skip("the rerun extra is not installed")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(rerun_target, "viewer_executable", lambda: "/usr/bin/rerun")  # found, no screen
    monkeypatch.setattr(sys, "argv", ["efficienteqa", "ask", "What colour is the sofa?",
                                      "--scene", "hm3d:nowhere", "--out", str(tmp_path / "out"),
                                      "--rerun", str(tmp_path / target) if target != "live" else target])
    with pytest.raises(SystemExit) as exited:
        cli.main()
    assert exited.value.code == 1
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 1 and said in lines[0], lines
