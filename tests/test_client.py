"""OpenAI-compatible client against an in-process fake server (httpx.MockTransport), and once
against a real llama.cpp server on loopback when llama_cpp and the SmolLM2 gguf are present."""

from __future__ import annotations

import base64
import importlib.util
import io
import json
import logging
import math
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx
import numpy as np
import pytest
from PIL import Image

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import Capabilities, Message
from efficienteqa.models.cache import ResponseCache, request_key
from efficienteqa.models.client import ClientConfig, OpenAIChatClient, RequestRejected

SECRET = "sk-test-0123456789abcdef-SECRET"


def completion(text: str = "B", prompt_tokens: int = 12, completion_tokens: int = 1,
               logprobs: bool = False) -> dict:
    choice: dict = {"index": 0, "message": {"role": "assistant", "content": text},
                    "finish_reason": "stop"}
    if logprobs:
        choice["logprobs"] = {"content": [
            {"token": text, "logprob": -0.1, "top_logprobs": [
                {"token": text, "logprob": -0.1}, {"token": "A", "logprob": -2.5}]}]}
    return {"id": "x", "object": "chat.completion", "model": "fake-4o", "choices": [choice],
            "usage": {"prompt_tokens": prompt_tokens, "completion_tokens": completion_tokens}}


class FakeServer:
    """Answers with ``replies`` in order (the last one repeats); records every request."""

    def __init__(self, *replies: httpx.Response | Exception) -> None:
        self.replies = list(replies) or [httpx.Response(200, json=completion())]
        self.requests: list[httpx.Request] = []

    def __call__(self, request: httpx.Request) -> httpx.Response:
        self.requests.append(request)
        reply = self.replies[min(len(self.requests), len(self.replies)) - 1]
        if isinstance(reply, Exception):
            raise reply
        return reply

    def body(self, i: int = -1) -> dict:
        return json.loads(self.requests[i].content)


def make_client(server: FakeServer, tmp_path: Path, **overrides) -> tuple[OpenAIChatClient, list[float]]:
    sleeps: list[float] = []
    fields = {"base_url": "http://fake.test/v1", "model": "fake-4o", "cache": False,
              "cache_path": str(tmp_path / "responses.sqlite"), **overrides}
    http = httpx.Client(transport=httpx.MockTransport(server))
    client = OpenAIChatClient(ClientConfig(**fields), http=http, sleep=sleeps.append)
    return client, sleeps


def ask(text: str = "Which door, A or B?", *images: np.ndarray) -> list[Message]:
    return [Message("system", "You explore houses."), Message("user", text, tuple(images))]


def test_request_shape_with_images(tmp_path):
    server = FakeServer()
    client, _ = make_client(server, tmp_path, capabilities=Capabilities(images=True), image_max_side=64)
    image = np.zeros((100, 200, 3), np.uint8)
    image[:, 100:] = (255, 0, 0)
    response = client.chat(ask("What is here?", image), max_tokens=5, logprobs=3, seed=7)

    assert response.text == "B" and response.model == "fake-4o" and not response.cached
    request = server.requests[0]
    assert request.url == "http://fake.test/v1/chat/completions" and request.method == "POST"
    assert "authorization" not in request.headers
    body = server.body()
    assert body["model"] == "fake-4o" and body["max_tokens"] == 5 and body["seed"] == 7
    assert "logprobs" not in body and "top_logprobs" not in body  # no capability
    assert body["messages"][0] == {"role": "system", "content": "You explore houses."}
    text_part, image_part = body["messages"][1]["content"]
    assert text_part == {"type": "text", "text": "What is here?"}
    url = image_part["image_url"]["url"]
    assert image_part["type"] == "image_url" and url.startswith("data:image/png;base64,")
    decoded = Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1])))
    assert decoded.size == (64, 32)  # longer side to 64 px, aspect kept
    assert np.asarray(decoded.convert("RGB"))[16, 48].tolist() == [255, 0, 0]


def test_a_configured_temperature_replaces_the_one_each_call_asks_for(tmp_path):
    server = FakeServer()
    client, _ = make_client(server, tmp_path, temperature=1.0)
    client.chat(ask(), temperature=0.0)
    assert server.body()["temperature"] == 1.0
    plain, _ = make_client(server, tmp_path)
    plain.chat(ask(), temperature=0.0)
    assert server.body()["temperature"] == 0.0


def test_jpeg_images_and_small_images_kept(tmp_path):
    server = FakeServer()
    client, _ = make_client(server, tmp_path, capabilities=Capabilities(images=True), image_format="jpeg")
    client.chat(ask("x", np.full((40, 30, 3), 128, np.uint8)))
    url = server.body()["messages"][1]["content"][1]["image_url"]["url"]
    assert url.startswith("data:image/jpeg;base64,")
    assert Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).size == (30, 40)


def test_images_without_capability_fail_clearly(tmp_path):
    server = FakeServer()
    client, _ = make_client(server, tmp_path)
    with pytest.raises(EfficientEQAError, match="does not accept images"):
        client.chat(ask("x", np.zeros((4, 4, 3), np.uint8)))
    assert server.requests == []


def test_logprobs_parsed_when_capable(tmp_path):
    server = FakeServer(httpx.Response(200, json=completion(logprobs=True)))
    client, _ = make_client(server, tmp_path, capabilities=Capabilities(logprobs=True))
    response = client.chat(ask(), logprobs=2)
    assert server.body()["logprobs"] is True and server.body()["top_logprobs"] == 2
    (token,) = response.logprobs
    assert token.token == "B" and token.logprob == pytest.approx(-0.1)
    assert token.top == (("B", -0.1), ("A", -2.5))


def test_completion_style_logprobs_parsed(tmp_path):
    data = completion()
    data["choices"][0]["logprobs"] = {"tokens": ["B", "."], "token_logprobs": [-0.2, -0.01],
                                      "top_logprobs": [{"B": -0.2, "A": -1.9}, {".": -0.01}]}
    client, _ = make_client(FakeServer(httpx.Response(200, json=data)), tmp_path,
                            capabilities=Capabilities(logprobs=True))
    tokens = client.chat(ask(), logprobs=2).logprobs
    assert [t.token for t in tokens] == ["B", "."] and tokens[0].top == (("B", -0.2), ("A", -1.9))


@pytest.mark.parametrize(("caps", "expected"), [
    (Capabilities(json_schema=True), {"type": "json_schema", "json_schema": {
        "name": "reply", "schema": {"type": "object"}}}),
    (Capabilities(grammar=True), {"type": "json_object", "schema": {"type": "object"}}),
    (Capabilities(), None),
])
def test_json_schema_routing(tmp_path, caps, expected):
    server = FakeServer()
    client, _ = make_client(server, tmp_path, capabilities=caps)
    client.chat(ask(), json_schema={"type": "object"})
    assert server.body().get("response_format") == expected


def test_retries_500_and_429_then_succeeds(tmp_path):
    server = FakeServer(httpx.Response(500, text="boom"), httpx.Response(429, headers={"Retry-After": "2"}),
                        httpx.ConnectError("refused"), httpx.ReadTimeout("slow"),
                        httpx.Response(200, json=completion("A")))
    client, sleeps = make_client(server, tmp_path, backoff_base_s=1.0)
    assert client.chat(ask()).text == "A"
    assert len(server.requests) == 5
    assert len(sleeps) == 4 and sleeps[1] == 2.0  # Retry-After respected
    assert 0.5 <= sleeps[0] <= 1.0 and 2.0 <= sleeps[2] <= 4.0 and 4.0 <= sleeps[3] <= 8.0
    # seeded jitter: a second client with the same seed sleeps the same
    again, sleeps_again = make_client(FakeServer(*server.replies), tmp_path, backoff_base_s=1.0)
    again.chat(ask())
    assert sleeps_again == sleeps


def test_dead_server_is_one_line_error(tmp_path):
    server = FakeServer(httpx.ConnectError("[Errno 111] Connection refused\nmore detail"))
    client, sleeps = make_client(server, tmp_path, max_retries=3)
    with pytest.raises(EfficientEQAError) as raised:
        client.chat(ask())
    message = str(raised.value)
    assert len(server.requests) == 4 and len(sleeps) == 3
    assert "\n" not in message and "Traceback" not in message
    assert message.startswith("model server at http://fake.test/v1/chat/completions "
                              "unreachable after 4 tries")
    assert "Connection refused" in message and "efficienteqa models serve" in message


def test_real_closed_port_is_unreachable(tmp_path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    client = OpenAIChatClient(ClientConfig(base_url=f"http://127.0.0.1:{port}/v1", cache=False,
                                           max_retries=1, timeout_s=2), sleep=lambda s: None)
    with pytest.raises(EfficientEQAError, match="unreachable after 2 tries"):
        client.chat(ask())


def test_400_not_retried(tmp_path):
    server = FakeServer(httpx.Response(400, json={"error": {"message": "bad top_logprobs"}}))
    client, sleeps = make_client(server, tmp_path)
    with pytest.raises(RequestRejected, match="HTTP 400.*bad top_logprobs") as raised:
        client.chat(ask())
    assert raised.value.status == 400 and len(server.requests) == 1 and sleeps == []


def test_api_key_only_in_authorization_header(tmp_path, monkeypatch, caplog):
    monkeypatch.setenv("FAKE_OPENAI_KEY", SECRET)
    caplog.set_level(logging.DEBUG)
    server = FakeServer(httpx.Response(503, text=f"upstream said {SECRET}"),
                        httpx.Response(200, json=completion()))
    client, _ = make_client(server, tmp_path, api_key_env="FAKE_OPENAI_KEY", cache=True)
    response = client.chat(ask())
    client.chat(ask())  # cache hit

    assert server.requests[-1].headers["authorization"] == f"Bearer {SECRET}"
    assert SECRET not in repr(client.config) and SECRET not in repr(client)
    assert SECRET not in caplog.text and "upstream said ***" in caplog.text
    assert SECRET not in json.dumps(response.raw)
    files = list(tmp_path.glob("responses.sqlite*"))
    assert files and all(SECRET.encode() not in f.read_bytes() for f in files)


def test_api_key_redacted_from_errors(tmp_path, monkeypatch):
    monkeypatch.setenv("FAKE_OPENAI_KEY", SECRET)
    server = FakeServer(httpx.Response(401, json={"error": f"Incorrect API key provided: {SECRET}"}))
    client, _ = make_client(server, tmp_path, api_key_env="FAKE_OPENAI_KEY")
    with pytest.raises(RequestRejected) as raised:
        client.chat(ask())
    assert SECRET not in str(raised.value) and "FAKE_OPENAI_KEY" in str(raised.value)


def test_missing_api_key_env(tmp_path, monkeypatch):
    monkeypatch.delenv("FAKE_OPENAI_KEY", raising=False)
    client, _ = make_client(FakeServer(), tmp_path, api_key_env="FAKE_OPENAI_KEY")
    with pytest.raises(EfficientEQAError, match="FAKE_OPENAI_KEY is not set"):
        client.chat(ask())


def test_usage_and_cost(tmp_path):
    server = FakeServer(httpx.Response(200, json=completion(prompt_tokens=1000, completion_tokens=200)),
                        httpx.Response(200, json={"choices": [{"message": {"content": None}}]}))
    client, _ = make_client(server, tmp_path, price_prompt_per_1k=0.0025, price_completion_per_1k=0.01)
    client.chat(ask("one"))
    empty = client.chat(ask("two"))
    assert empty.text == "" and empty.prompt_tokens == 0 and empty.model == "fake-4o"
    usage = client.usage
    assert (usage.calls, usage.cached_calls) == (2, 0)
    assert (usage.prompt_tokens, usage.completion_tokens) == (1000, 200)
    assert usage.cost_usd == pytest.approx(0.0025 + 0.002)
    assert usage.latency_s > 0


def test_malformed_reply_is_clear(tmp_path):
    client, _ = make_client(FakeServer(httpx.Response(200, text="<html>hi</html>")), tmp_path)
    with pytest.raises(EfficientEQAError, match="not JSON"):
        client.chat(ask())
    client, _ = make_client(FakeServer(httpx.Response(200, json={"error": "x"})), tmp_path)
    with pytest.raises(EfficientEQAError, match="no choices"):
        client.chat(ask())


def test_cache_hit_without_http_call(tmp_path):
    server = FakeServer(httpx.Response(200, json=completion("C", logprobs=True)))
    client, _ = make_client(server, tmp_path, cache=True, capabilities=Capabilities(logprobs=True),
                            price_prompt_per_1k=1.0)
    first = client.chat(ask(), logprobs=2, temperature=0.7, seed=3)
    second = client.chat(ask(), logprobs=2, temperature=0.7, seed=3)
    assert len(server.requests) == 1
    assert second.cached and not first.cached and second.text == first.text == "C"
    assert second.logprobs == first.logprobs and second.latency_s < 0.05
    assert client.usage.calls == 2 and client.usage.cached_calls == 1
    assert client.usage.cost_usd == pytest.approx(12 / 1000)  # the hit costs nothing
    client.chat(ask(), logprobs=2, temperature=0.7, seed=4)  # seed is part of the key
    assert len(server.requests) == 2


def test_cache_shared_across_base_urls_but_keyed_on_images(tmp_path):
    caps = Capabilities(images=True)
    server_a, server_b = FakeServer(), FakeServer()
    client_a, _ = make_client(server_a, tmp_path, cache=True, capabilities=caps)
    client_b, _ = make_client(server_b, tmp_path, cache=True, capabilities=caps,
                              base_url="http://other-gateway.test/v1")
    image = np.zeros((8, 8, 3), np.uint8)
    client_a.chat(ask("q", image))
    assert client_b.chat(ask("q", image.copy())).cached and server_b.requests == []
    other = image.copy()
    other[0, 0] = 1
    assert not client_b.chat(ask("q", other)).cached and len(server_b.requests) == 1


def test_cache_key_components():
    base = {"max_tokens": 8, "temperature": 0.0, "logprobs": None, "json_schema": None, "seed": None}
    key = request_key("m", ask(), **base)
    assert key == request_key("m", ask(), **base)
    assert key != request_key("m2", ask(), **base)
    assert key != request_key("m", ask("other"), **base)
    for name, value in [("max_tokens", 9), ("temperature", 0.5), ("logprobs", 3),
                        ("json_schema", {"type": "object"}), ("seed", 1)]:
        assert key != request_key("m", ask(), **{**base, name: value}), name
    image = np.zeros((2, 6, 3), np.uint8)
    assert request_key("m", ask("q", image), **base) != request_key("m", ask("q", image.reshape(6, 2, 3)),
                                                                     **base)


def test_cache_clear_stats_and_processes(tmp_path):
    server = FakeServer()
    client, _ = make_client(server, tmp_path, cache=True)
    client.chat(ask())
    cache = ResponseCache(tmp_path / "responses.sqlite")
    stats = cache.stats()
    assert stats["entries"] == 1 and stats["bytes"] > 0
    # another process sees the entry
    code = ("from efficienteqa.models.cache import ResponseCache; import sys; "
            "print(ResponseCache(sys.argv[1]).stats()['entries'])")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "responses.sqlite")],
                         capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "1"
    cache.clear()
    assert cache.stats()["entries"] == 0
    assert not client.chat(ask()).cached and len(server.requests) == 2


def test_cache_threads(tmp_path):
    from concurrent.futures import ThreadPoolExecutor

    server = FakeServer()
    client, _ = make_client(server, tmp_path, cache=True)
    with ThreadPoolExecutor(4) as pool:
        texts = list(pool.map(lambda i: client.chat(ask(f"q{i % 5}")).text, range(40)))
    assert texts == ["B"] * 40 and client.usage.calls == 40
    assert ResponseCache(tmp_path / "responses.sqlite").stats()["entries"] == 5


def test_broken_cache_does_not_fail_the_call(tmp_path, caplog):
    (tmp_path / "responses.sqlite").write_bytes(b"this is not a database" * 100)
    server = FakeServer()
    client, _ = make_client(server, tmp_path, cache=True)
    assert client.chat(ask()).text == "B" and len(server.requests) == 1
    assert "response cache unavailable" in caplog.text


def test_probe_capabilities(tmp_path):
    client, _ = make_client(FakeServer(httpx.Response(200, json=completion(logprobs=True))), tmp_path)
    assert client.probe_capabilities().logprobs and client.capabilities.logprobs
    client, _ = make_client(FakeServer(httpx.Response(400, text="logprobs unsupported")), tmp_path,
                            capabilities=Capabilities(logprobs=True, images=True))
    caps = client.probe_capabilities()
    assert not caps.logprobs and caps.images


# ------------------------------------------------------------------ real llama.cpp server

def _smollm2_gguf() -> Path | None:
    try:
        from efficienteqa.models.local import model_path

        return model_path("smollm2-135m")
    except Exception:  # any failure means "not available here"
        pass
    found = sorted(Path.home().glob(".cache/efficienteqa/models/SmolLM2-135M*.gguf"))
    return found[0] if found else None


@pytest.fixture(scope="module")
def llama_server(tmp_path_factory):
    if importlib.util.find_spec("llama_cpp") is None:
        pytest.skip("llama_cpp is not importable (see PLATFORM.md: build llama-cpp-python portable)")
    gguf = _smollm2_gguf()
    if gguf is None:
        pytest.skip("SmolLM2 gguf not installed (run: efficienteqa models install smollm2-135m)")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    # our own process, stopped by its id: a shared server managed by name might be in use elsewhere
    log = tmp_path_factory.mktemp("llama") / "server.log"
    with log.open("wb") as out:  # a file, not a pipe: the server logs enough to fill a pipe and block
        proc = subprocess.Popen([sys.executable, "-m", "llama_cpp.server", "--model", str(gguf),
                                 "--n_threads", "2", "--n_ctx", "2048", "--host", "127.0.0.1",
                                 "--port", str(port)],
                                stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT)
    base_url = f"http://127.0.0.1:{port}/v1"
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if proc.poll() is not None:
                pytest.skip(f"llama.cpp server exited: {log.read_text(errors='replace')[-300:]}")
            try:
                if httpx.get(f"{base_url}/models", timeout=1).status_code == 200:
                    break
            except httpx.TransportError:
                time.sleep(0.3)
        else:
            tail = log.read_text(errors="replace")[-300:]
            pytest.fail(f"llama.cpp server did not answer within 120 s: {tail}")
        yield base_url
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    assert proc.poll() is not None


@pytest.mark.slow
def test_llama_cpp_server(llama_server, tmp_path):
    config = ClientConfig(base_url=llama_server, model="smollm2-135m", timeout_s=60,
                          capabilities=Capabilities(logprobs=True, grammar=True),
                          cache_path=str(tmp_path / "responses.sqlite"))
    with OpenAIChatClient(config) as client:
        messages = [Message("user", "Answer with one letter. Is the sky blue? A: yes, B: no.")]
        first = client.chat(messages, max_tokens=8, logprobs=3)
        assert first.prompt_tokens > 0 and 0 < first.completion_tokens <= 8 and not first.cached
        assert first.logprobs and len(first.logprobs) == first.completion_tokens
        assert all(1 <= len(t.top) <= 3 and math.isfinite(t.logprob) and t.logprob <= 0
                   for t in first.logprobs)
        second = client.chat(messages, max_tokens=8, logprobs=3)
        assert second.cached and second.text == first.text and second.logprobs == first.logprobs
        assert client.usage.calls == 2 and client.usage.cached_calls == 1
        plain = client.chat([Message("user", "Say hello.")], max_tokens=6)
        assert plain.text.strip() and plain.logprobs is None
        print(f"\nSmolLM2: first {first.latency_s * 1000:.0f} ms, cached {second.latency_s * 1000:.2f} ms, "
              f"plain {plain.latency_s * 1000:.0f} ms; reply {first.text!r}")
