"""The test VLM server (tests/vlm_server.py) and the model layer's fixes for real servers' habits against it:
the probe (logprobs returned / ignored / rejected, the image cap), finish_reason, timeouts and
retries, image encoding, the API key per host, the cache key per server, the cost."""

from __future__ import annotations

import base64
import io
import json
import time

import numpy as np
import pytest
from PIL import Image

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.backends import ChatBackend, build_chat_model
from efficienteqa.models.base import Message
from efficienteqa.models.client_errors import RequestRejected
from efficienteqa.models.images import encode_image
from efficienteqa.vc.parse import parse_candidates, parse_letters
from efficienteqa.vc.prompts import load_prompt
from efficienteqa.vc.yes_no import parse_worth_exploring
from vlm_server import BROKEN, STYLES, check_image, classify, servers, tokens_of

SECRET = "sk-test-vlm-server-SECRET-0123"
QUESTION = "What colour is the sofa in the living room?"


@pytest.fixture
def vlm():
    with servers() as start:
        yield start


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    """Probes and replies under tmp_path, never in the user's cache; no key in the
    environment unless a test sets one."""
    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    return tmp_path / "cache"


def backend(server, **overrides) -> ChatBackend:
    return ChatBackend(**{"kind": "openai", "model": "test-vlm", "base_url": server.base_url,
                          "timeout_s": 5.0, "retries": 0, "cache": False, **overrides})


def frame(seed: int = 0, shape: tuple[int, int] = (384, 512)) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 255, (*shape, 3), np.uint8)


def prompts() -> dict[str, str]:
    """Each prompt of the project, filled in, by the kind the server must see in it."""
    directions = "A, B, C (the lettered circles in the image)"
    fill = {"question": QUESTION, "view": "the image", "directions": directions, "m": 3,
            "evidence": "the 5 attached images", "example": "white; 80", "hint": "",
            "direction": "a door", "first": "sofa", "second": "couch", "answers":
            "Correct answer: blue", "response": "navy", "choices": "A. blue\nB. red",
            "answer": "blue", "extra": ""}
    names = {"explore": ("efficienteqa.explore", "explore"),
             "explore-letters": ("efficienteqa.explore", "explore_letters"),
             "explore-token": ("efficienteqa.explore", "explore_token"),
             "explore-choice": ("efficienteqa.explore", "explore_choice"),
             "explore-direction": ("efficienteqa.explore", "explore_direction"),
             "worth": ("efficienteqa.explore", "explore_worth"),
             "worth-token": ("efficienteqa.explore", "explore_worth_token"),
             "match": ("efficienteqa.relevancy", "match"),
             "group": ("efficienteqa.vc", "group"),
             "answer": ("efficienteqa.answer", "answer"),
             "answer-short": ("efficienteqa.answer", "answer_direct"),
             "blind-choice": ("efficienteqa.answer", "blind_choices"),
             "judge": ("efficienteqa.eval", "judge"),
             "judge-same": ("efficienteqa.eval", "judge_same"),
             "judge-openeqa": ("efficienteqa.eval", "judge_openeqa")}
    return {kind: load_prompt(name, package).format(**fill)
            for kind, (package, name) in names.items()}


# ---------------------------------------------------------------- the server itself

def test_the_server_knows_every_prompt_of_the_project():
    for kind, text in prompts().items():
        assert classify(text) == kind, kind
    blind = load_prompt("blind", "efficienteqa.answer").format(question=QUESTION, m=3, example="")
    token = load_prompt("answer_token", "efficienteqa.answer").format(question=QUESTION,
                                                                       evidence="x")
    assert (classify(blind), classify(token)) == ("answer", "answer-short")


def test_exact_replies_are_what_the_project_parses(vlm):
    server = vlm()
    client = build_chat_model(backend(server, images=True))
    texts = prompts()
    letters = parse_letters(client.chat([Message("user", texts["explore"])]).text, ["A", "B", "C"])
    assert letters.candidates and not letters.problems
    worth = client.chat([Message("user", texts["worth"], (frame(),))]).text
    assert parse_worth_exploring(worth)[1] == []
    match = client.chat([Message("user", texts["match"], (frame(),))]).text
    assert match.split()[0] in ("yes", "no") and match.split()[1].isdigit()
    answer = client.chat([Message("user", texts["answer"], (frame(1), frame(2)))]).text
    parsed = parse_candidates(answer, 3)
    assert parsed.candidates and not parsed.problems
    assert parsed.candidates[0].text in ("white", "brown", "blue")
    assert client.chat([Message("user", texts["group"])]).text == "no"  # sofa vs couch: words
    assert client.chat([Message("user", texts["judge"])]).text in "12345"
    again = client.chat([Message("user", texts["answer"], (frame(1), frame(2)))]).text
    assert again == answer  # deterministic
    assert [r.kind for r in server.requests][-7:] == ["explore", "worth", "match", "answer",
                                                      "group", "judge", "answer"]


@pytest.mark.parametrize("style", STYLES)
def test_each_style_writes_the_same_reply_its_own_way(vlm, style):
    server = vlm(style=style)
    client = build_chat_model(backend(server))
    reply = client.chat([Message("user", prompts()["match"])]).text
    exact = vlm(style="exact")
    plain = build_chat_model(backend(exact)).chat([Message("user", prompts()["match"])]).text
    if style == "exact":
        assert reply == plain
    elif style == "markdown":
        assert "%" in reply and "**" in reply
    elif style == "preamble":
        assert reply.startswith("Sure!") and reply.endswith(plain)
    elif style == "json":
        body = reply.removeprefix("```json\n").removesuffix("\n```")
        assert json.loads(body)["answer"] in ("yes", "no")
    elif style == "refuse":  # a refusal, whatever was asked
        assert reply == "I'm sorry, but I can't help with that." and reply != plain
    else:
        assert reply.endswith(plain) and len(reply.splitlines()) > 1


def test_the_server_checks_every_image(vlm):
    png = encode_image(frame(), 512, "png")
    assert check_image({"image_url": {"url": png, "detail": "low"}}, 512) == ("png", 512, 384,
                                                                               "low")
    for url, message in [("https://example.org/a.png", "not a base64"),
                         ("data:image/png;base64,AAAA", "undecodable"),
                         (png.replace("image/png", "image/jpeg"), "says jpeg"),
                         (encode_image(frame(0, (480, 640)), 640, "png"), "exceeds 512")]:
        with pytest.raises(ValueError, match=message):
            check_image({"image_url": {"url": url}}, 512)
    server = vlm()
    client = build_chat_model(backend(server, images=True, image_max_side=600))
    with pytest.raises(RequestRejected, match="exceeds 512 px"):
        client.chat([Message("user", "What is here?", (frame(0, (480, 640)),))])
    assert server.image_errors == ["image 600x450 exceeds 512 px"]


def test_logprobs_look_real(vlm):
    server = vlm()
    client = build_chat_model(backend(server, images=True))
    texts = prompts()
    reply = client.chat([Message("user", texts["explore-token"], (frame(),))], logprobs=10)
    first = reply.logprobs[0]
    assert first.token in "ABC" and len(first.top) == 4 and first.top[0][0] == first.token
    assert {t for t, _ in first.top} == {"A", "B", "C", "D"}
    assert all(lp < 0 for _, lp in first.top) and first.logprob == max(lp for _, lp in first.top)
    assert "".join(t.token for t in reply.logprobs) == reply.text
    yes_no = reply.logprobs[-1]
    assert yes_no.token in ("yes", "no") and {"yes", "no"} <= {t for t, _ in yes_no.top}
    assert tokens_of("worth exploring: yes 80") == ["worth", " exploring", ":", " yes", " 80"]


def test_the_server_records_headers_parameters_and_images(vlm):
    server = vlm()
    client = build_chat_model(backend(server, images=True, image_detail="high"))
    client.chat([Message("user", "What is here?", (frame(0), frame(1), frame(2)))],
                max_tokens=7, seed=3)
    seen = server.requests[-1]
    assert seen.images == 3 and seen.body["max_tokens"] == 7 and seen.body["seed"] == 3
    assert seen.image_info == [("jpeg", 512, 384, "high")] * 3
    assert seen.authorization == "Bearer no-key" and "user-agent" in seen.headers


# ---------------------------------------------------------------------------------- the probe

def test_a_gpt4o_like_server_is_probed_with_logprobs(vlm, private_cache):
    server = vlm()
    caps = build_chat_model(backend(server, images=True)).capabilities
    assert caps.logprobs and caps.images and caps.max_images is None and caps.json_schema
    assert caps.source == "probed" and caps.probed == {
        "logprobs": "returned", "json_schema": "accepted", "images": "5 accepted"}
    assert server.kinds() == ["probe", "probe", "probe-images"]
    assert [r.images for r in server.requests] == [0, 0, 5]
    assert build_chat_model(backend(server, images=True)).capabilities.source == "probe cache"
    assert len(server.requests) == 3  # the second run did not probe


def test_a_server_that_ignores_logprobs(vlm):
    caps = build_chat_model(backend(vlm(logprobs="ignore"))).capabilities
    assert not caps.logprobs and caps.probed["logprobs"] == "ignored"


def test_a_server_that_rejects_logprobs(vlm):
    server = vlm(logprobs="reject")
    client = build_chat_model(backend(server))
    assert not client.capabilities.logprobs
    assert client.capabilities.probed["logprobs"] == "rejected: HTTP 400"
    client.chat([Message("user", prompts()["match"])], logprobs=10)  # not sent: no HTTP 400
    assert "logprobs" not in server.requests[-1].body and server.requests[-1].status == 200


def test_a_server_without_json_schema(vlm):
    caps = build_chat_model(backend(vlm(json_schema="reject"))).capabilities
    assert not caps.json_schema and caps.probed["json_schema"] == "rejected: HTTP 400"


def test_a_dead_or_hung_server_fails_the_probe_in_one_line(vlm):
    server = vlm(hang_s=3.0)
    start = time.monotonic()
    with pytest.raises(EfficientEQAError) as raised:
        build_chat_model(backend(server, timeout_s=0.3, retries=0))
    assert time.monotonic() - start < 2.5
    assert "\n" not in str(raised.value) and "raise --backends.timeout-s" in str(raised.value)
    unknown = vlm(models=("other-model",))
    with pytest.raises(RequestRejected, match="does not exist"):
        build_chat_model(backend(unknown))


WHAT_CAME = {"garbage": r"not UTF-8 \(byte 0\): b'\\xfe\\xff", "empty200": "an empty reply",
             "html200json": "not JSON: <!DOCTYPE html><html><body><h1>Sign in"}


@pytest.mark.parametrize("broken", sorted(BROKEN))
def test_a_200_that_is_not_the_json_it_says_is_one_line_naming_the_server(vlm, broken):
    """Fault trials 2.19 and N.13: the SDK's own ``JSONDecodeError`` for a body labelled JSON
    that is not (a proxy's login page, nothing, bytes read as UTF-16) was a traceback at the
    probe; it is one line saying what came. After the probe it fails the call (the episode)."""
    server = vlm(misbehave=broken)
    with pytest.raises(EfficientEQAError, match=WHAT_CAME[broken]) as raised:
        build_chat_model(backend(server))
    assert f"model server at {server.base_url}/chat/completions sent" in str(raised.value)
    assert "\n" not in str(raised.value) and "check base_url" in str(raised.value)
    later = vlm(misbehave=broken, misbehave_after=2)
    client = build_chat_model(backend(later))  # the probe's two requests are answered
    with pytest.raises(EfficientEQAError, match=WHAT_CAME[broken]):
        client.chat([Message("user", prompts()["match"])])


# ---------------------------------------------------------------- (4) the image cap

def test_the_probe_finds_vllms_image_cap(vlm):
    server = vlm(max_images=1)
    caps = build_chat_model(backend(server, images=True)).capabilities
    assert caps.images and caps.max_images == 1
    assert [(r.images, r.status) for r in server.requests[-2:]] == [(5, 400), (1, 200)]
    three = vlm(max_images=3)
    assert build_chat_model(backend(three, images=True)).capabilities.max_images == 3
    assert [r.images for r in three.requests[-2:]] == [5, 3]  # the count vLLM's message names


def test_a_text_only_server_is_probed_without_images(vlm):
    caps = build_chat_model(backend(vlm(images=False), images=True)).capabilities
    assert not caps.images and "not a multimodal model" in caps.probed["images"]


def test_more_images_than_the_cap_is_a_rejected_request(vlm):
    server = vlm(max_images=1)
    client = build_chat_model(backend(server, images=True))
    with pytest.raises(RequestRejected, match=r"At most 1 image\(s\)"):
        client.chat([Message("user", prompts()["answer"], (frame(0), frame(1)))])


# ---------------------------------------------------------------- (5) finish_reason

def test_a_reply_cut_at_max_tokens_is_flagged(vlm):
    server = vlm(style="reasoning", cut=True)
    client = build_chat_model(backend(server))
    reply = client.chat([Message("user", prompts()["match"])], max_tokens=6)
    assert reply.finish_reason == "length" and len(tokens_of(reply.text)) == 6
    whole = client.chat([Message("user", prompts()["match"])], max_tokens=200)
    assert whole.finish_reason == "stop"


# ---------------------------------------------------------------- (8) timeouts and retries

def test_429_with_retry_after_then_success(vlm):
    server = vlm(fail=1, fail_status=429, retry_after=0.05)
    client = build_chat_model(backend(server, retries=2))  # the probe retries once
    assert client.capabilities.logprobs
    assert [r.status for r in server.requests][:2] == [429, 200]
    server.options.fail = len(server.requests) + 2  # the next two requests
    start = time.monotonic()
    client.chat([Message("user", prompts()["match"])])
    assert [r.status for r in server.requests][-3:] == [429, 429, 200]
    assert time.monotonic() - start < 2.0  # Retry-After: 0.05 s, not the SDK's backoff


def test_500s_exhaust_the_retries_in_one_line(vlm):
    server = vlm(fail=10, fail_status=500)
    with pytest.raises(EfficientEQAError) as raised:
        build_chat_model(backend(server, retries=1))
    assert "HTTP 500 after 2 tries" in str(raised.value) and "\n" not in str(raised.value)


def test_a_server_that_hangs_after_the_probe_times_out_per_call(vlm):
    server = vlm(hang_s=2.0, hang_after=2)
    client = build_chat_model(backend(server, timeout_s=0.3, retries=1))
    with pytest.raises(EfficientEQAError, match=r"within 0.3 s \(2 tries\).*--backends.timeout-s"):
        client.chat([Message("user", prompts()["match"])])


# ---------------------------------------------------------------- (10) image encoding

def test_jpeg_is_the_default_and_about_six_times_smaller(vlm):
    server = vlm()
    client = build_chat_model(backend(server, images=True))
    assert client.config.image_format == "jpeg" and client.config.image_detail is None
    # a room-like frame: shaded walls, a piece of furniture, the sensor's grain
    shade = np.linspace(60, 200, 512)[None, :, None] + np.zeros((384, 1, 3))
    shade[150:300, 100:400] = (150, 90, 40)
    grain = np.random.default_rng(0).normal(0, 3, shade.shape)
    sky = np.clip(shade + grain, 0, 255).astype(np.uint8)
    client.chat([Message("user", "What is here?", (sky,))])
    assert server.requests[-1].image_info == [("jpeg", 512, 384, None)]
    png, jpeg = (len(base64.b64decode(encode_image(sky, 512, f).split(",", 1)[1]))
                 for f in ("png", "jpeg"))
    assert 4 * jpeg < png  # measured on rendered houses: about 6 times (ChatBackend)


def test_format_side_and_detail_reach_the_server(vlm):
    server = vlm()
    client = build_chat_model(backend(server, images=True, image_format="png",
                                      image_max_side=256, image_detail="low"))
    client.chat([Message("user", "What is here?", (frame(),))])
    assert server.requests[-1].image_info == [("png", 256, 192, "low")]
    url = server.requests[-1].body["messages"][0]["content"][1]["image_url"]["url"]
    assert Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).format == "PNG"


# ---------------------------------------------------------------- (13) the API key

def test_the_openai_key_never_reaches_the_test_server(vlm, monkeypatch):
    monkeypatch.setenv("OPENAI_API_KEY", SECRET)
    server = vlm()
    client = build_chat_model(backend(server, images=True))
    client.chat([Message("user", prompts()["match"], (frame(),))])
    assert server.requests and all(SECRET not in (r.authorization or "") for r in server.requests)


def test_a_server_with_its_own_key(vlm, monkeypatch):
    monkeypatch.setenv("VLLM_API_KEY", "vllm-key-1")
    server = vlm(api_key="vllm-key-1")
    with pytest.raises(RequestRejected, match=r"HTTP 401.*no key was sent.*--backends.api-key-env"):
        build_chat_model(backend(server, api_key_env="none"))
    client = build_chat_model(backend(server, api_key_env="VLLM_API_KEY"))
    assert client.capabilities.logprobs
    assert server.requests[-1].authorization == "Bearer vllm-key-1"


# ---------------------------------------------------------------- (14) the cache per server

def test_two_servers_of_one_model_name_do_not_share_replies(vlm):
    first, second = vlm(), vlm(style="preamble")
    one = build_chat_model(backend(first, cache=True)).chat([Message("user", prompts()["match"])])
    two = build_chat_model(backend(second, cache=True)).chat([Message("user", prompts()["match"])])
    assert not two.cached and two.text != one.text and two.text.startswith("Sure!")
    assert build_chat_model(backend(first, cache=True)).chat(
        [Message("user", prompts()["match"])]).cached


# ---------------------------------------------------------------- (15) the cost

def test_gpt4o_calls_are_priced_and_serialised(vlm):
    from dataclasses import asdict

    server = vlm()
    client = build_chat_model(backend(server, model="gpt-4o"))
    reply = client.chat([Message("user", prompts()["match"])])
    usage = asdict(client.usage)
    expected = (reply.prompt_tokens * 0.0025 + reply.completion_tokens * 0.01) / 1000
    assert usage["cost_usd"] == pytest.approx(expected) and usage["cost_usd"] > 0
    assert usage["calls"] == 1
