"""The frozen splits: their manifests, ``scenes verify`` and ``scenes export-walks``."""

from __future__ import annotations

import copy
import json
from collections import Counter

import numpy as np
import pytest

from efficienteqa.datasets import _FROZEN, load_dataset, splits, synthetic
from efficienteqa.datasets.manifest import manifest_sha256, start_view_problems
from efficienteqa.errors import EfficientEQAError

# The committed manifests' sha256. A frozen split never changes: a new generator makes
# synthetic-v2 (a new file, manifest and digest), so these lines are never edited.
COMMITTED = {
    "synthetic-v1": "6d736be434c61bad13791520f8e5f4bf7b03aac6250493ded0a00071b8258161",
    "synthetic-test-v1": "c42625e0e9fd8c870b51eef66a88c415ad25cf154db922de8e3ef192d0e04caf",
}
NEW_VERSION = ("a frozen split changed: build synthetic-v2 / synthetic-test-v2 with "
               "scripts/make_synthetic_split.py --split, and leave -v1 as it is")


@pytest.mark.parametrize("name", sorted(COMMITTED))
def test_the_manifests_are_the_committed_ones(name):
    split = splits.SPLITS[name]
    manifest = splits.packaged_manifest(split)
    assert manifest_sha256(manifest) == manifest["sha256"] == COMMITTED[name], NEW_VERSION
    assert split.sha256 == COMMITTED[name], NEW_VERSION
    assert splits.integrity_problems(split, manifest) == []


def test_the_names_of_the_frozen_splits():
    assert set(_FROZEN) == {*splits.ALIASES, *splits.SPLITS}
    assert load_dataset("synthetic") == load_dataset("synthetic-v1")
    assert load_dataset("synthetic-test") == load_dataset("synthetic-test-v1")


def test_the_test_split_is_held_out_and_balanced():
    qs = load_dataset("synthetic-test")
    seeds = {int(q.source["house_seed"]) for q in qs}
    assert len(qs) >= 120 and len(seeds) >= 30
    assert seeds <= set(range(5000, 5040)) and seeds <= set(synthetic.TEST_SEEDS)
    counts = Counter(q.category for q in qs)
    assert len(counts) == 6 and len(set(counts.values())) == 1, counts
    assert len({q.id for q in qs}) == len(qs)
    assert all(q.id.startswith("synthetic-test-v1/syn-") and q.dataset == "synthetic-test-v1"
               and q.scene == f"synthetic:{q.source['house_seed']}" and q.accepted for q in qs)
    # every question has evidence and oracle steps but the existence "no"s
    assert all((q.oracle_steps is None) == (q.source["no_evidence"]) for q in qs)
    header = synthetic.split_header(synthetic.TEST_FILE)
    assert header["dataset"] == "synthetic-test-v1" and header["questions"] == len(qs)
    # no house of the main split's, nor of any range tuned on (0-20, 100-999, 1000-3999)
    assert not seeds & {int(q.source["house_seed"]) for q in load_dataset("synthetic")}


def test_a_question_edited_in_the_split_file_fails_to_load(monkeypatch):
    real = synthetic.load_split

    def edited(file=synthetic.SPLIT_FILE):
        qs = real(file)
        return [qs[0].__class__(**{**qs[0].__dict__, "answer": "purple"}), *qs[1:]]

    monkeypatch.setattr(synthetic, "load_split", edited)
    with pytest.raises(EfficientEQAError) as err:
        load_dataset("synthetic-test")
    assert "question 1" in str(err.value) and "answer" in str(err.value)
    assert "synthetic-v2" in err.value.fix


def test_an_edited_manifest_is_refused():
    split = splits.SPLITS["synthetic-v1"]
    manifest = copy.deepcopy(splits.packaged_manifest(split))
    manifest["questions"][0]["answer"] = "purple"
    assert any("it was edited" in p for p in splits.integrity_problems(split, manifest))
    manifest["sha256"] = manifest_sha256(manifest)  # edited with care: still not the committed
    assert any("not the committed" in p for p in splits.integrity_problems(split, manifest))


def test_the_start_view_is_compared_within_its_tolerances():
    fixed = {"pose": [1.0, 2.0, 0.5], "size": [640, 480], "pixels": {"3": 5000, "7": 400},
             "depth_median_m": 2.5}
    near = {**fixed, "pixels": {"3": 5000 + 3000, "9": 3000}, "depth_median_m": 2.509}
    assert start_view_problems(1, near, fixed) == []
    far = {**fixed, "pixels": {"3": 5000 + 3100, "7": 400}, "depth_median_m": 2.52}
    problems = start_view_problems(1, far, fixed)
    assert len(problems) == 2 and "instance 3 8100 (manifest 5000)" in problems[0]
    assert "depth" in problems[1]
    moved = {**fixed, "pose": [1.0, 2.001, 0.5]}
    assert "start view at" in start_view_problems(1, moved, fixed)[0]


def test_verify_reproduces_the_first_house_of_the_test_split(cli):
    result = cli("scenes", "verify", "synthetic-test", "--limit", "1")
    assert result.returncode == 0, result.said
    assert "synthetic-test-v1: 1 houses" in result.stdout and "reproduced" in result.stdout


def test_verify_fails_a_tampered_manifest(cli, tmp_path):
    split = splits.SPLITS["synthetic-test-v1"]
    manifest = copy.deepcopy(splits.packaged_manifest(split))
    first = min(manifest["houses"], key=int)
    manifest["houses"][first]["digest"] = "f" * 64
    entry = next(e for e in manifest["questions"] if str(e["house_seed"]) == first)
    entry["oracle_steps"] = (entry["oracle_steps"] or 0) + 1
    manifest["sha256"] = manifest_sha256(manifest)
    path = tmp_path / "tampered.json"
    path.write_text(json.dumps(manifest))
    result = cli("scenes", "verify", "synthetic-test", "--limit", "1", "--manifest", str(path))
    assert result.returncode == 1, result.said
    lines = [line for line in result.stdout.splitlines() if line.startswith("mismatch:")]
    assert any("not the committed" in line for line in lines), lines
    assert any(f"house {first}: generated with digest" in line for line in lines), lines
    assert any(f"{entry['id']}: oracle_steps is" in line for line in lines), lines
    assert any("question" in line and "differ from the manifest" in line for line in lines)
    assert "synthetic-test-v1: 1 houses, 3 questions" in result.stdout


def test_export_walks_reads_back_as_a_recorded_walk(tmp_path, cli):
    from efficienteqa.datasets.walks import export_walks
    from efficienteqa.envs.synthetic.questions import evidence_visible
    from efficienteqa.scenes import open_scene

    out = tmp_path / "em"
    done = export_walks("synthetic", out, limit=1)
    first = load_dataset("synthetic")[0]
    seed = first.source["house_seed"]
    assert (done.questions, done.houses) == (1, 1) and done.frames >= 5
    (q,) = load_dataset(str(out / "questions.jsonl"))
    assert (q.id, q.question, q.answer) == (first.id, first.question, first.answer)
    assert q.accepted == first.accepted and q.category == first.category  # the rule judge's key
    assert q.scene == f"recorded:{out / 'walks' / str(seed)}"
    scene = open_scene(q.scene)
    try:
        frames = list(scene.env.source.frames())
    finally:
        scene.env.close()
    assert len(frames) == done.frames
    # the walk starts with four views at the start pose, and sees the question's evidence
    assert np.allclose([f.pose.x for f in frames[:4]], frames[0].pose.x, atol=1e-6)
    assert any(evidence_visible(f.instance, first.source["evidence"]) for f in frames)
    end = first.source["oracle_pose"]
    assert any(np.allclose([f.pose.x, f.pose.y], end[:2], atol=1e-3) for f in frames)
    again = cli("scenes", "export-walks", "synthetic", str(out), "--limit", "1")
    assert again.returncode == 1 and "never written over" in again.stdout
    assert len(again.stdout.strip().splitlines()) == 1


def test_a_questions_files_accepted_answers_are_read_or_refused_in_one_line(tmp_path):
    from efficienteqa.datasets.questions_file import load_questions_file
    from efficienteqa.errors import EfficientEQAError

    good = tmp_path / "q.jsonl"
    good.write_text('{"question": "How many chairs?", "scene": "synthetic:0", "answer": "4", '
                    '"category": "count", "accepted": ["4", "four"]}\n')
    (q,) = load_questions_file(good)
    assert q.accepted == ("4", "four") and q.category == "count"
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"question": "How many chairs?", "scene": "synthetic:0", "accepted": {}}\n')
    with pytest.raises(EfficientEQAError, match="line 1: accepted is an object"):
        load_questions_file(bad)
