"""Datasets: HM-EQA parsing and download, the fixed synthetic split, live synthetic seeds."""

from __future__ import annotations

import hashlib
import logging
import os
from collections import Counter
from pathlib import Path

import httpx
import pytest

from conftest import HM_EQA as HM
from conftest import needs_egl
from conftest import needs_hm_eqa as needs_hm
from efficienteqa.datasets import DATASETS, EvalQuestion, hm_eqa, load_dataset, synthetic
from efficienteqa.envs.synthetic.catalog import DEFAULT_SOURCE
from efficienteqa.envs.synthetic.questions import CATEGORIES, Question
from efficienteqa.errors import EfficientEQAError

HEADER = "scene,floor,question,choices,question_formatted,answer,label\n"
POSES = "scene_floor,init_x,init_y,init_z,init_angle\n"


USER_CACHE = os.environ.get("EFFICIENTEQA_CACHE")


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """No test reads or writes the user's cache or relies on $EFFICIENTEQA_HM_EQA."""
    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv(hm_eqa.ENV_VAR, raising=False)


# -- HM-EQA, the published files -----------------------------------------------------------------
@needs_hm
def test_hm_eqa_open_vocabulary():
    qs = load_dataset("hm-eqa", path=HM)
    ids = [q.id for q in qs]
    assert len(qs) == 499 and len(set(ids)) == 499
    assert "hm-eqa/161" not in ids  # the filler answer; its id is not reused
    assert ids[160:162] == ["hm-eqa/160", "hm-eqa/162"] and ids[-1] == "hm-eqa/499"
    assert all(hm_eqa.FILLER not in q.answer for q in qs)
    assert Counter(q.category for q in qs) == {"location": 130, "existence": 108, "state": 101,
                                               "identification": 81, "count": 79}
    first = qs[0]
    assert first.scene == "hm3d:00004-VqCaAuuoeWk" and first.answer == "Yes, it is on"
    assert first.choices == () and first.start is None and first.dataset == "hm-eqa"
    assert first.source["letter"] == "B" and first.source["floor"] == 1
    assert first.source["scene_floor"] == "00004-VqCaAuuoeWk_1"


@needs_hm
def test_hm_eqa_start_poses_join_every_row():
    qs = load_dataset("hm-eqa", path=HM)
    joined = [q for q in qs if q.source["habitat_position"] is not None]
    assert len(joined) == 499
    assert all(len(q.source["habitat_position"]) == 3 for q in joined)
    assert qs[0].source["habitat_position"] == pytest.approx([1.551065, 0.13908827, -3.0018978])
    assert qs[0].source["habitat_yaw"] == pytest.approx(0.0953831335597118)


@needs_hm
def test_hm_eqa_closed_set_and_apostrophes():
    qs = load_dataset("hm-eqa", path=HM, closed_set=True)
    assert len(qs) == 500 and all(len(q.choices) == 4 for q in qs)
    assert all(q.answer == q.choices["ABCD".index(q.source["letter"])] for q in qs)
    filler = [q for q in qs if q.source["filler_answer"]]
    assert [q.id for q in filler] == ["hm-eqa/161"] and filler[0].answer == hm_eqa.FILLER
    with_apostrophe = [q for q in qs if any("'" in c for c in q.choices)]
    assert len(with_apostrophe) == 13
    assert "It's closed" in {q.answer for q in with_apostrophe}


@needs_hm
def test_hm_eqa_from_env_var_and_limit(monkeypatch):
    monkeypatch.setenv(hm_eqa.ENV_VAR, str(HM))
    qs = load_dataset("hm-eqa", limit=5)
    assert [q.id for q in qs] == [f"hm-eqa/{i:03d}" for i in range(5)]


@needs_hm
def test_hm_eqa_missing_pose_is_counted_not_fatal(tmp_path, caplog):
    lines = (HM / "scene_init_poses.csv").read_text().splitlines(keepends=True)
    (tmp_path / "scene_init_poses.csv").write_text(
        "".join(line for line in lines if not line.startswith("00004-VqCaAuuoeWk_1")))
    (tmp_path / "questions.csv").write_bytes((HM / "questions.csv").read_bytes())
    with caplog.at_level(logging.WARNING):
        qs = load_dataset("hm-eqa", path=tmp_path)
    missing = [q for q in qs if q.source["habitat_position"] is None]
    assert len(qs) == 499 and len(missing) >= 1 and missing[0].id == "hm-eqa/000"
    assert missing[0].source["habitat_yaw"] is None
    assert f"{len(missing)} of 499 HM-EQA questions have no start pose" in caplog.text


# -- HM-EQA, malformed files -----------------------------------------------------------------------
def _write(folder: Path, rows: list[str], header: str = HEADER, more_poses: str = "") -> Path:
    (folder / "questions.csv").write_text(header + "".join(rows))
    (folder / "scene_init_poses.csv").write_text(POSES + "s1_0,1.0,0.1,2.0,0.5\n" + more_poses)
    return folder


GOOD = "s1,0,Is it on?,\"['Yes', 'No']\",q,A,state\n"


@pytest.mark.parametrize(("row", "words"), [
    ("s1,0,Where?,\"['a', 'b'\",q,A,location\n", "row 2 (line 5): choices is not a Python list"),
    ("s1,0,Where?,\"'a'\",q,A,location\n", "row 2 (line 5): choices must be a list"),
    ("s1,0,Where?,\"['a', 'b']\",q,C,location\n", "row 2 (line 5): answer 'C' is not one of A, B"),
    ("s1,0,,\"['a', 'b']\",q,A,location\n", "row 2 (line 5): empty scene or question"),
])
def test_hm_eqa_malformed_rows_name_file_and_row(tmp_path, row, words):
    _write(tmp_path, [GOOD, "s1,0,\"Multi\nline\",\"['a', 'b']\",q,A,state\n", row])
    with pytest.raises(EfficientEQAError) as err:
        load_dataset("hm-eqa", path=tmp_path)
    assert words in str(err.value) and "questions.csv" in str(err.value)


def test_hm_eqa_missing_column_and_bad_pose(tmp_path):
    _write(tmp_path, [GOOD], header=HEADER.replace(",label", ""))
    with pytest.raises(EfficientEQAError, match=r"questions.csv: missing column\(s\) label"):
        load_dataset("hm-eqa", path=tmp_path)
    _write(tmp_path, [GOOD], more_poses="s2_0,x,0,0,0\n")
    with pytest.raises(EfficientEQAError, match=r"scene_init_poses.csv: row 1 \(line 3\)"):
        load_dataset("hm-eqa", path=tmp_path)


def test_hm_eqa_bad_bytes_and_huge_fields_are_one_line(tmp_path):
    """Invalid UTF-8 and a field over csv's 131,072-character limit."""
    _write(tmp_path, [GOOD])
    path = tmp_path / "questions.csv"
    path.write_bytes(path.read_bytes() + b"s1,0,Is it \xff on?,\"['a', 'b']\",q,A,state\n")
    with pytest.raises(EfficientEQAError, match="questions.csv: not UTF-8 text"):
        load_dataset("hm-eqa", path=tmp_path)
    _write(tmp_path, [GOOD, "s1,0,\"" + "x" * 140_000 + "\",\"['a', 'b']\",q,A,state\n"])
    with pytest.raises(EfficientEQAError, match="questions.csv: line .*field larger than"):
        load_dataset("hm-eqa", path=tmp_path)


def test_hm_eqa_small_file_parses(tmp_path):
    _write(tmp_path, [GOOD, "s2,1,Is the oven open?,\"['(Do not choose this option)', 'No']\",q,A,state\n"])
    open_qs = load_dataset("hm-eqa", path=tmp_path)
    closed = load_dataset("hm-eqa", path=tmp_path, closed_set=True)
    assert [q.id for q in open_qs] == ["hm-eqa/000"] and open_qs[0].answer == "Yes"
    assert open_qs[0].source["habitat_position"] == [1.0, 0.1, 2.0]
    assert [q.id for q in closed] == ["hm-eqa/000", "hm-eqa/001"]
    assert closed[1].source["filler_answer"] and closed[1].source["habitat_position"] is None


def test_hm_eqa_folder_without_files(tmp_path):
    with pytest.raises(EfficientEQAError, match="lacks questions.csv, scene_init_poses.csv"):
        load_dataset("hm-eqa", path=tmp_path)


# -- HM-EQA download (fake transport, no network) --------------------------------------------------
FAKE = {"questions.csv": (HEADER + GOOD).encode(),
        "scene_init_poses.csv": (POSES + "s1_0,1,2,3,0\n").encode()}


def _fake_client(monkeypatch, handler) -> list[str]:
    seen: list[str] = []

    def record(request: httpx.Request) -> httpx.Response:
        seen.append(str(request.url))
        return handler(request)

    monkeypatch.setattr(hm_eqa, "_http_client", lambda: httpx.Client(transport=httpx.MockTransport(record)))
    monkeypatch.setattr(hm_eqa, "DIGESTS", {k: hashlib.sha256(v).hexdigest() for k, v in FAKE.items()})
    return seen


def test_hm_eqa_download_writes_cache_atomically(monkeypatch, tmp_path):
    seen = _fake_client(monkeypatch,
                        lambda r: httpx.Response(200, content=FAKE[r.url.path.rsplit("/", 1)[1]]))
    qs = load_dataset("hm-eqa")
    folder = tmp_path / "cache" / "datasets" / "hm-eqa"
    assert [q.answer for q in qs] == ["Yes"]
    assert sorted(p.name for p in folder.iterdir()) == ["questions.csv", "scene_init_poses.csv"]
    assert all(hm_eqa.COMMIT in url and "Stanford-ILIAD/explore-eqa" in url for url in seen)
    assert len(seen) == 2
    load_dataset("hm-eqa")  # cached: no second download
    assert len(seen) == 2


def test_hm_eqa_download_failure_leaves_no_partial_file(monkeypatch, tmp_path):
    def handler(request: httpx.Request) -> httpx.Response:
        if request.url.path.endswith("scene_init_poses.csv"):
            return httpx.Response(200, content=b"not the published file")
        return httpx.Response(200, content=FAKE["questions.csv"])

    _fake_client(monkeypatch, handler)
    with pytest.raises(EfficientEQAError, match="is not the published file"):
        load_dataset("hm-eqa")
    folder = tmp_path / "cache" / "datasets" / "hm-eqa"
    assert sorted(p.name for p in folder.iterdir()) == ["questions.csv"]  # complete or absent


def test_hm_eqa_offline_is_one_clear_line(monkeypatch):
    def offline(request: httpx.Request) -> httpx.Response:
        raise httpx.ConnectError("[Errno -2] Name or service not known\nmore detail", request=request)

    _fake_client(monkeypatch, offline)
    with pytest.raises(EfficientEQAError) as err:
        load_dataset("hm-eqa")
    text = str(err.value)
    assert "\n" not in text and "download failed" in text and "--eval.hm-eqa-path FOLDER" in text


# -- dataset names --------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["synthetic:x", "synthetic:", "synthetic:3-1", "synthetic:-3",
                                  "hm-eqa:1", "habitat", "", "synthetic-paraphrase:1"])
def test_bad_names_name_the_valid_forms(name):
    with pytest.raises(EfficientEQAError) as err:
        load_dataset(name)
    assert "synthetic:0-9" in str(err.value) and "hm-eqa" in str(err.value)


def test_names_and_flags():
    assert set(DATASETS) == {"synthetic", "synthetic-test", "synthetic-paraphrase",
                             "synthetic:SEEDS", "hm-eqa", "FILE.jsonl"}
    assert synthetic.parse_seeds("3") == [3]
    assert synthetic.parse_seeds("0-9") == list(range(10))
    assert synthetic.parse_seeds("1,4,7") == [1, 4, 7]
    assert synthetic.parse_seeds("7, 0-2") == [0, 1, 2, 7]
    with pytest.raises(EfficientEQAError, match="names more than 5000 houses"):
        load_dataset("synthetic:0-100000000", limit=2)  # at once, not after generating them
    with pytest.raises(EfficientEQAError, match="names more than 5000 houses"):
        load_dataset("synthetic:0-2999,5000-7999", limit=2)
    with pytest.raises(EfficientEQAError, match="no closed-set mode"):
        load_dataset("synthetic", closed_set=True)
    with pytest.raises(EfficientEQAError, match="defined for assets 'sh3d'"):
        load_dataset("synthetic", assets="builtin")


# -- the fixed synthetic split ------------------------------------------------------------------
def test_split_statistics():
    qs, header = load_dataset("synthetic"), synthetic.split_header()
    seeds = {q.source["house_seed"] for q in qs}
    counts = Counter(q.category for q in qs)
    assert header["version"] == synthetic.SPLIT_VERSION and header["questions"] == len(qs)
    assert len(seeds) >= 20 and sorted(seeds) == header["seeds"]
    assert 90 <= len(qs) <= 110
    assert set(counts) == set(CATEGORIES) and max(counts.values()) - min(counts.values()) <= 2
    assert counts == header["category_counts"]
    assert min(seeds) >= 100 and max(seeds) < 1000  # 0-20 development, >= 1000 calibration
    assert len({q.id for q in qs}) == len(qs) and all(q.id.startswith("synthetic-v1/syn-") for q in qs)
    for q in qs:
        assert q.scene == f"synthetic:{q.source['house_seed']}" and q.dataset == "synthetic-v1"
        assert (q.oracle_steps is None) == q.source["no_evidence"]
        assert q.oracle_steps is None or q.oracle_steps >= 1
    no_evidence = [q for q in qs if q.source["no_evidence"]]
    assert 1 <= len(no_evidence) <= 10
    assert all(q.category == "existence" and q.answer == "no" for q in no_evidence)


@pytest.mark.parametrize("limit", [12, 20])
def test_split_prefix_is_balanced(limit):
    qs = load_dataset("synthetic", limit=limit)
    counts = Counter(q.category for q in qs)
    assert len(qs) == limit and set(counts) == set(CATEGORIES)
    assert max(counts.values()) - min(counts.values()) <= 1
    assert len({q.source["house_seed"] for q in qs}) >= limit // 2


@needs_egl
@pytest.mark.skipif(not Path(DEFAULT_SOURCE).exists(), reason="apt-get install sweethome3d-furniture")
def test_split_still_generated_by_the_smallest_house(monkeypatch):
    from efficienteqa.scenes import open_scene

    if USER_CACHE is None:  # the converted furniture lives in the user's cache
        monkeypatch.delenv("EFFICIENTEQA_CACHE")
    else:
        monkeypatch.setenv("EFFICIENTEQA_CACHE", USER_CACHE)
    sizes = synthetic.split_header()["house_sizes"]
    seed = int(min(sizes, key=lambda s: (sizes[s]["floor_area_m2"], int(s))))
    qs = [q for q in load_dataset("synthetic") if q.source["house_seed"] == seed]
    scene = open_scene(f"synthetic:{seed}")
    try:
        for q in qs:
            synthetic.check_question(scene, q)
        changed = EvalQuestion.from_dict({**qs[0].to_dict(), "answer": "a unicorn"})
        with pytest.raises(EfficientEQAError, match="generator changed"):
            synthetic.check_question(scene, changed)
        other = EvalQuestion.from_dict({**qs[0].to_dict(), "source": {"house_seed": seed + 1}})
        with pytest.raises(EfficientEQAError, match="belongs to house"):
            synthetic.check_question(scene, other)
    finally:
        scene.env.close()
    # Evaluation opens houses without the oracle (the split has its steps): same questions.
    fast = open_scene(f"synthetic:{seed}", oracle=False)
    try:
        assert all(q.oracle_steps is None for q in fast.questions)
        assert {(q.question, q.answer) for q in scene.questions} <= \
            {(q.question, q.answer) for q in fast.questions}
        for q in qs:
            synthetic.check_question(fast, q)
    finally:
        fast.env.close()


# -- live synthetic seeds ------------------------------------------------------------------------
def _fake_house(seed: int, assets: str) -> list[Question]:
    """Two questions per category; existence "no" has no evidence (the generator's shape)."""
    out = []
    for c in CATEGORIES:
        for k in range(2):
            no = c == "existence" and k == 1
            out.append(Question(f"syn-{seed}-{len(out):02d}", seed, c, f"{c} {k} of {seed}?",
                                "no" if no else "yes", [], [] if no else [1], None if no else 2 + k))
    return out


def test_live_seeds_are_cached_and_interleaved(monkeypatch, tmp_path):
    calls: list[int] = []

    def fake(seed: int, assets: str) -> list[Question]:
        calls.append(seed)
        return _fake_house(seed, assets)

    monkeypatch.setattr(synthetic, "_house_questions", fake)
    qs = load_dataset("synthetic:3", assets="builtin")
    assert calls == [3] and len(qs) == 12 and qs[0].scene == "synthetic:3"
    assert qs[0].id == "synthetic/syn-3-00" and qs[0].source["assets"] == "builtin"
    assert [q.category for q in qs[:6]] == list(CATEGORIES)
    many = load_dataset("synthetic:1-3", assets="builtin", limit=6)
    assert calls == [3, 1, 2]  # house 3 came from the cache
    assert {q.source["house_seed"] for q in many} == {1, 2, 3}
    assert [q.category for q in many] == list(CATEGORIES)
    again = load_dataset("synthetic:3", assets="builtin")
    assert calls == [3, 1, 2] and again == qs
    assert [q.oracle_steps for q in again if q.source["no_evidence"]] == [None]
    folder = tmp_path / "cache" / "datasets" / "synthetic" / "builtin"
    assert sorted(p.name for p in folder.iterdir()) == [
        f"{s}-{synthetic.generator_version()}.jsonl" for s in (1, 2, 3)]
