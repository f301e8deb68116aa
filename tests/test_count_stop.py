"""Count questions stop at the frame that shows the whole group (DESIGN 9, defect 4 of the walks): the gate's
final verdict, not a relevancy outlier that such frames never make. Training house 1."""

from __future__ import annotations

from pathlib import Path

import pytest

from conftest import needs_egl


def _walk(scene, gate_final: bool, max_steps: int | None = None):
    from efficienteqa.agent import AgentConfig
    from efficienteqa.envs.synthetic.questions import evidence_visible
    from efficienteqa.models.stub import StubChatModel
    from efficienteqa.stack import Stack, build_agent

    q = next(q for q in scene.questions if q.id == "syn-1-02")
    built = build_agent(scene.env, Stack(), AgentConfig.of(gate_final=gate_final,
                                                           max_steps=max_steps),
                        scene.backend, model=StubChatModel(lambda messages: "2"))
    seen: list[bool] = []
    result = built.agent.run(scene.env, q.question, on_step=lambda r, obs, _: seen.append(
        evidence_visible(obs.instance, q.evidence)))
    return q, result, seen.index(True) + 1


@needs_egl
def test_a_count_question_stops_within_two_steps_of_first_sight():
    from efficienteqa.envs.synthetic.catalog import DEFAULT_SOURCE
    from efficienteqa.scenes import open_scene

    if not Path(DEFAULT_SOURCE).exists():
        pytest.skip("apt-get install sweethome3d-furniture")
    scene = open_scene("synthetic:1")
    try:
        q, result, first = _walk(scene, gate_final=True)
        assert q.question == "How many chairs are around the table in the dining room?"
        assert result.stop_reason == "relevancy" and len(result.records) - first <= 2
        assert result.records[-1].gate == {"ok": True, "why": "2 chair around the whole table",
                                           "final": True}
        # the relevancy outlier alone: not within two steps (the walk is the same up to the
        # sight; a budget of three steps past it says so without walking on)
        _, waited, first_then = _walk(scene, gate_final=False, max_steps=first + 3)
        assert first_then == first and len(waited.records) - first_then > 2
    finally:
        scene.env.close()
