"""Every agent method end to end against an OpenAI-compatible server (tests/vlm_server.py) in the
configurations real servers have (DESIGN 9): logprobs returned (GPT-4o, vLLM), ignored or
rejected (servers without logprobs), one image per request (vLLM's --limit-mm-per-prompt
image=1). RGB perception, the VLM as relevancy scorer (vlm-match), a synthetic house with the
built-in furniture, 4 steps. Each run either finishes with its episode written, or fails in one
line before exploring (white-box ExploreEQA refuses a server without logprobs)."""

from __future__ import annotations

import json
from collections import Counter

import pytest

from conftest import needs_egl
from efficienteqa.config.presets import build_config, build_stack
from efficienteqa.datasets import load_dataset
from efficienteqa.errors import EfficientEQAError
from efficienteqa.eval.methods import RunSpec
from efficienteqa.eval.runner import run_eval
from vlm_server import Options

pytestmark = needs_egl

# experiments/main_table.sh's paper row: the paper's configuration by flags, no preset.
PAPER = {"explore_scorer": "vlm", "stop_rule": "paper", "answer": "paper", "prompts": "paper",
         "exploration": "paper", "refusal_retries": 0, "stop_clearance_m": 0.0,
         "distinct_views": False, "gate": "none", "steering": "none", "min_stop_step": 10}
SERVERS = {"logprobs": Options(), "no-logprobs": Options(logprobs="ignore"),
           "rejects-logprobs": Options(logprobs="reject"), "one-image": Options(max_images=1)}
EXPLORING = {"explore", "explore-letters", "explore-token", "explore-choice", "worth",
             "worth-token", "match"}


@pytest.fixture(scope="module")
def question():
    return load_dataset("synthetic:0", limit=1, assets="builtin")


def run(vlm, tmp_path, question, method: str, server: str | Options,
        flags: dict | None = None):
    """One ``efficienteqa eval --dataset synthetic:0 --limit 1`` as the CLI builds it."""
    s = vlm(SERVERS[server] if isinstance(server, str) else server)
    options = {"vlm": f"openai:test-vlm@{s.base_url}", "perception": "rgb",
               "relevancy": "vlm-match", "max_steps": 4, "cache": False, **(flags or {})}
    spec = RunSpec.of(method=method, dataset="synthetic:0", stack=build_stack(options),
                   config=build_config(options), judge=None, assets="builtin")
    out = tmp_path / "run"
    result = run_eval(spec, question, out)
    rows = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    return s, result, rows, out


CASES = [("efficienteqa", "logprobs", None), ("efficienteqa", "no-logprobs", None),
         ("efficienteqa", "rejects-logprobs", None), ("efficienteqa", "one-image", None),
         ("efficienteqa", "logprobs", PAPER), ("explore-eqa", "logprobs", None),
         ("explore-eqa-blackbox", "one-image", None), ("blind", "rejects-logprobs", None)]


@pytest.mark.parametrize(("method", "server", "flags"), CASES,
                         ids=[f"{m}-{s}" + ("-paper" if f else "") for m, s, f in CASES])
def test_a_method_runs_to_its_episode(vlm, tmp_path, question, method, server, flags):
    s, result, rows, out = run(vlm, tmp_path, question, method, server, flags)
    [row] = rows
    assert row["status"] == "done", row.get("error")
    assert result.failed == 0 and row["answer"] and row["confidence"] > 0
    if method != "blind":
        assert row["steps"] >= 1
        assert (out / "episodes" / row["id"].replace("/", "__") / "episode.json").is_file()
    assert not s.image_errors
    kinds = Counter(s.kinds())
    assert kinds["probe"] >= 2 and sum(kinds.values()) > kinds["probe"]
    cap = SERVERS[server].max_images
    refused = [(r.kind, r.images) for r in s.requests if r.status != 200]
    # only the probe meets the server's limits: every request of the episode is accepted
    assert all(kind.startswith("probe") for kind, _ in refused), refused
    if cap is not None:
        assert max(r.images for r in s.requests if not r.kind.startswith("probe")) <= cap
    if SERVERS[server].logprobs != "return":  # never asked for what the server lacks
        assert not any(r.body.get("logprobs") for r in s.requests
                       if not r.kind.startswith("probe"))


@pytest.mark.parametrize("server", ["no-logprobs", "rejects-logprobs"])
def test_white_box_explore_eqa_refuses_a_server_without_logprobs(vlm, tmp_path, question, server):
    """Refused once, in one line, before the first episode (not failed per episode)."""
    started = []

    def keep(options):  # noqa: ANN001, ANN202 - the server, to read its requests afterwards
        started.append(vlm(options))
        return started[-1]

    with pytest.raises(EfficientEQAError, match="does not return token log-probabilities") as err:
        run(keep, tmp_path, question, "explore-eqa", server)
    assert "\n" not in str(err.value)
    assert not (tmp_path / "run" / "episodes.jsonl").exists()  # no episode was run
    assert not EXPLORING & set(started[0].kinds())  # refused before exploring


# What the server's answers can be (vlm_server.plausible_answer): a clean answer is one of them.
ANSWERS = {"1", "2", "3", "white", "brown", "blue", "yes", "no", "in the kitchen",
           "in the living room", "in the bedroom", "the kitchen", "the living room",
           "the bedroom", "a lamp", "a book", "a plant"}


@pytest.mark.parametrize("style", ["markdown", "preamble", "json", "reasoning"])
def test_a_chatty_server_still_gives_a_clean_answer(vlm, tmp_path, question, style):
    s, _, rows, _ = run(vlm, tmp_path, question, "efficienteqa", Options(style=style, cut=True))
    [row] = rows
    assert row["status"] == "done", row.get("error")
    assert not s.image_errors
    assert row["answer"] in ANSWERS, (style, row["answer"], row["extra"]["answer_problems"])


STEERED = ("to the", "into the", "look around", "inspect", "search the")


@pytest.mark.parametrize(("perception", "relevancy", "reading"),
                         [("rgb", "vlm-match", "the image"),
                          ("semantic", "overlap", "the description")])
def test_the_vlms_sightings_steer_an_image_user_as_labels_do(vlm, tmp_path, perception, relevancy,
                                                             reading):
    """With --perception rgb the sightings come from one call per step to the VLM (boxes over
    the image); the same call reads a description with --sightings model. The steering goes to
    the named room and looks around in it, and the sightings gate stops on the target."""
    questions = load_dataset("synthetic:0", limit=3, assets="builtin")
    s = vlm(Options())
    options = {"vlm": f"openai:test-vlm@{s.base_url}", "perception": perception,
               "relevancy": relevancy, "max_steps": 8, "cache": False, "sightings": "model"}
    spec = RunSpec.of(method="efficienteqa", dataset="synthetic:0", stack=build_stack(options),
                   config=build_config(options), judge=None, assets="builtin")
    out = tmp_path / "run"
    run_eval(spec, questions, out)
    rows = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    assert [r["status"] for r in rows] == ["done"] * 3
    episodes = [json.loads((out / "episodes" / r["id"].replace("/", "__") / "episode.json")
                           .read_text()) for r in rows]
    decisions, verdicts = [], []
    for e in episodes:
        assert e["backends"]["sightings"] == f"model (one call per step to test-vlm, reading {reading})"
        assert e["backends"]["gate"].startswith("sightings" if perception == "rgb" else "rules")
        decisions += [r["decision"] for r in e["per_step"]]
        verdicts += [(r.get("gate") or {}).get("ok") for r in e["per_step"]]
    sighting_calls = [r for r in s.requests if r.kind == "sightings"]
    steps = sum(r["steps"] for r in rows)  # one per step at most (the last step does not move)
    assert steps - len(rows) <= len(sighting_calls) <= steps
    assert all(r.images == (perception == "rgb") for r in sighting_calls)
    assert any(d.startswith(STEERED) for d in decisions)
    if perception == "rgb":
        assert True in verdicts and any(r["stop_reason"] == "relevancy" for r in rows)


@pytest.mark.parametrize("method", ["explore-eqa", "explore-eqa-blackbox"])
def test_explore_eqa_weighs_each_step_by_the_vlms_own_confidence(vlm, tmp_path, question, method):
    """--step-weight confident (the paper preset's): one "are you confident?" call per valid
    frame, white-box read from its tokens, black-box verbalized; the answer is the step with
    the highest weight x answer confidence, and each step records its weight."""
    s, result, rows, out = run(vlm, tmp_path, question, method, "logprobs",
                               {"step_weight": "confident"})
    [row] = rows
    assert row["status"] == "done", row.get("error")
    kind = "confident-token" if method == "explore-eqa" else "confident"
    asked = [r for r in s.requests if r.kind == kind]
    episode = json.loads((out / "episodes" / row["id"].replace("/", "__") / "episode.json")
                         .read_text())
    valid = [p for p in episode["per_step"] if p["sim"] is not None]
    assert len(asked) == len(valid) >= 1 and all(r.images == 1 for r in asked)
    weights = {p["step"]: p["step_answer"]["weight"] for p in valid}
    assert all(0.0 <= w <= 1.0 for w in weights.values())
    values = [p["step_answer"]["value"] for p in valid if "value" in (p["step_answer"] or {})]
    assert values and max(values) <= max(weights.values()) + 1e-9
