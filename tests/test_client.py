"""OpenAI-compatible client against a fake OpenAI-compatible HTTP server on loopback (real
sockets, so the SDK's retries, ``Retry-After`` and timeouts run for real), and once against a real
llama.cpp server when llama_cpp and the SmolLM2 gguf are present."""

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
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import httpx
import numpy as np
import pytest
from PIL import Image

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.backends import ChatBackend, build_chat_model
from efficienteqa.models.base import Capabilities, Message
from efficienteqa.models.cache import ResponseCache, request_key
from efficienteqa.models.client import OpenAIChatClient
from efficienteqa.models.client_config import ClientConfig
from efficienteqa.models.client_errors import RequestRejected

SECRET = "sk-test-0123456789abcdef-SECRET"
# A short server-directed wait, so that retry tests do not sleep the SDK's 0.5-8 s backoff.
FAST_RETRY = {"retry-after-ms": "20"}


def completion(text: str = "B", prompt_tokens: int = 12, completion_tokens: int = 1,
               logprobs: bool = False) -> dict:
    choice: dict = {"index": 0, "message": {"role": "assistant", "content": text},
                    "finish_reason": "stop"}
    if logprobs:
        choice["logprobs"] = {"content": [
            {"token": text, "logprob": -0.1, "bytes": None, "top_logprobs": [
                {"token": text, "logprob": -0.1, "bytes": None},
                {"token": "A", "logprob": -2.5, "bytes": None}]}]}
    return {"id": "x", "object": "chat.completion", "created": 0, "model": "fake-4o",
            "choices": [choice],
            "usage": {"prompt_tokens": prompt_tokens, "completion_tokens": completion_tokens,
                      "total_tokens": prompt_tokens + completion_tokens}}


@dataclass
class Reply:
    """What the fake server answers: a JSON body (dict) or raw text, after ``delay_s``."""

    status: int = 200
    body: dict | str | bytes = field(default_factory=completion)
    headers: dict[str, str] = field(default_factory=dict)
    delay_s: float = 0.0


@dataclass
class Seen:
    path: str
    headers: dict[str, str]  # lower-case names
    body: dict
    at: float  # time.monotonic() on arrival


class FakeServer:
    """An OpenAI-compatible server on 127.0.0.1: answers ``replies`` in order (the last one
    repeats) and records every request."""

    def __init__(self, *replies: Reply) -> None:
        self.replies = list(replies) or [Reply()]
        self.requests: list[Seen] = []
        self._lock = threading.Lock()
        fake = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def do_POST(self) -> None:
                length = int(self.headers.get("content-length") or 0)
                body = json.loads(self.rfile.read(length) or b"{}")
                with fake._lock:
                    fake.requests.append(Seen(self.path, {k.lower(): v for k, v in self.headers.items()},
                                              body, time.monotonic()))
                    reply = fake.replies[min(len(fake.requests), len(fake.replies)) - 1]
                time.sleep(reply.delay_s)
                is_json = isinstance(reply.body, (dict, bytes))
                data = (reply.body if isinstance(reply.body, bytes) else
                        (json.dumps(reply.body) if is_json else str(reply.body)).encode())
                try:
                    self.send_response(reply.status)
                    self.send_header("content-type", "application/json" if is_json else "text/html")
                    self.send_header("content-length", str(len(data)))
                    for name, value in reply.headers.items():
                        self.send_header(name, value)
                    self.end_headers()
                    self.wfile.write(data)
                except OSError:  # the client gave up (a timeout test)
                    pass

            def log_message(self, *args: object) -> None:
                pass

        self._server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self._thread = threading.Thread(target=self._server.serve_forever, args=(0.02,), daemon=True)
        self._thread.start()

    @property
    def base_url(self) -> str:
        return f"http://127.0.0.1:{self._server.server_port}/v1"

    def body(self, i: int = -1) -> dict:
        return self.requests[i].body

    def close(self) -> None:
        self._server.shutdown()
        self._server.server_close()


@pytest.fixture
def serve() -> Iterator:
    """``serve(*replies)`` starts a fake server, stopped after the test."""
    servers: list[FakeServer] = []

    def start(*replies: Reply) -> FakeServer:
        servers.append(FakeServer(*replies))
        return servers[-1]

    yield start
    for server in servers:
        server.close()


def make_client(server: FakeServer, tmp_path: Path, **overrides) -> OpenAIChatClient:
    fields = {"base_url": server.base_url, "model": "fake-4o", "cache": False, "timeout_s": 10.0,
              "cache_path": str(tmp_path / "responses.sqlite"), **overrides}
    return OpenAIChatClient(ClientConfig(**fields))


def ask(text: str = "Which door, A or B?", *images: np.ndarray) -> list[Message]:
    return [Message("system", "You explore houses."), Message("user", text, tuple(images))]


def closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_request_shape_with_images(serve, tmp_path, monkeypatch):
    monkeypatch.setenv("OPENAI_API_KEY", SECRET)  # no key configured: this one must not be sent
    server = serve()
    client = make_client(server, tmp_path, capabilities=Capabilities(images=True), image_max_side=64)
    image = np.zeros((100, 200, 3), np.uint8)
    image[:, 100:] = (255, 0, 0)
    response = client.chat(ask("What is here?", image), max_tokens=5, logprobs=3, seed=7)

    assert response.text == "B" and response.model == "fake-4o" and not response.cached
    (request,) = server.requests
    assert request.path == "/v1/chat/completions"
    assert SECRET not in json.dumps(request.headers)
    body = server.body()
    assert body["model"] == "fake-4o" and body["max_tokens"] == 5 and body["seed"] == 7
    assert "logprobs" not in body and "top_logprobs" not in body  # no capability
    assert "response_format" not in body
    assert body["messages"][0] == {"role": "system", "content": "You explore houses."}
    text_part, image_part = body["messages"][1]["content"]
    assert text_part == {"type": "text", "text": "What is here?"}
    url = image_part["image_url"]["url"]
    assert image_part["type"] == "image_url" and url.startswith("data:image/png;base64,")
    decoded = Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1])))
    assert decoded.size == (64, 32)  # longer side to 64 px, aspect kept
    assert np.asarray(decoded.convert("RGB"))[16, 48].tolist() == [255, 0, 0]


def test_a_base_url_with_a_trailing_slash_reaches_the_same_path(serve, tmp_path):
    server = serve()
    make_client(server, tmp_path, base_url=server.base_url + "/").chat(ask())
    assert server.requests[0].path == "/v1/chat/completions"


def test_a_configured_temperature_replaces_the_one_each_call_asks_for(serve, tmp_path):
    server = serve()
    make_client(server, tmp_path, temperature=1.0).chat(ask(), temperature=0.0)
    assert server.body()["temperature"] == 1.0
    make_client(server, tmp_path).chat(ask(), temperature=0.0)
    assert server.body()["temperature"] == 0.0


def test_jpeg_images_and_small_images_kept(serve, tmp_path):
    server = serve()
    client = make_client(server, tmp_path, capabilities=Capabilities(images=True), image_format="jpeg")
    client.chat(ask("x", np.full((40, 30, 3), 128, np.uint8)))
    url = server.body()["messages"][1]["content"][1]["image_url"]["url"]
    assert url.startswith("data:image/jpeg;base64,")
    assert Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).size == (30, 40)


def test_images_without_capability_fail_clearly(serve, tmp_path):
    server = serve()
    client = make_client(server, tmp_path)
    with pytest.raises(EfficientEQAError, match="does not accept images"):
        client.chat(ask("x", np.zeros((4, 4, 3), np.uint8)))
    assert server.requests == []


def test_logprobs_parsed_when_capable(serve, tmp_path):
    server = serve(Reply(body=completion(logprobs=True)))
    client = make_client(server, tmp_path, capabilities=Capabilities(logprobs=True))
    response = client.chat(ask(), logprobs=2)
    assert server.body()["logprobs"] is True and server.body()["top_logprobs"] == 2
    (token,) = response.logprobs
    assert token.token == "B" and token.logprob == pytest.approx(-0.1)
    assert token.top == (("B", -0.1), ("A", -2.5))


def test_completion_style_logprobs_parsed(serve, tmp_path):
    data = completion()
    data["choices"][0]["logprobs"] = {"tokens": ["B", "."], "token_logprobs": [-0.2, -0.01],
                                      "top_logprobs": [{"B": -0.2, "A": -1.9}, {".": -0.01}]}
    client = make_client(serve(Reply(body=data)), tmp_path, capabilities=Capabilities(logprobs=True))
    tokens = client.chat(ask(), logprobs=2).logprobs
    assert [t.token for t in tokens] == ["B", "."] and [t.logprob for t in tokens] == [-0.2, -0.01]
    assert tokens[0].top == (("B", -0.2), ("A", -1.9)) and tokens[1].top == ((".", -0.01),)


@pytest.mark.parametrize(("caps", "expected"), [
    (Capabilities(json_schema=True), {"type": "json_schema", "json_schema": {
        "name": "reply", "schema": {"type": "object"}}}),
    (Capabilities(grammar=True), {"type": "json_object", "schema": {"type": "object"}}),
    (Capabilities(), None),
])
def test_json_schema_routing(serve, tmp_path, caps, expected):
    server = serve()
    make_client(server, tmp_path, capabilities=caps).chat(ask(), json_schema={"type": "object"})
    assert server.body().get("response_format") == expected


def test_a_wrapped_schema_is_sent_as_given(serve, tmp_path):
    server = serve()
    wrapped = {"name": "step", "schema": {"type": "object"}, "strict": True}
    make_client(server, tmp_path, capabilities=Capabilities(json_schema=True)).chat(
        ask(), json_schema=wrapped)
    assert server.body()["response_format"] == {"type": "json_schema", "json_schema": wrapped}
    make_client(server, tmp_path, capabilities=Capabilities(grammar=True)).chat(ask(), json_schema=wrapped)
    assert server.body()["response_format"] == {"type": "json_object", "schema": {"type": "object"}}


def test_retries_5xx_and_429_then_succeeds(serve, tmp_path):
    server = serve(Reply(500, "boom", FAST_RETRY), Reply(503, "busy", FAST_RETRY),
                   Reply(429, {"error": {"message": "slow down"}}, FAST_RETRY),
                   Reply(body=completion("A")))
    client = make_client(server, tmp_path, max_retries=3)
    assert client.chat(ask()).text == "A"
    assert [r.headers["x-stainless-retry-count"] for r in server.requests] == ["0", "1", "2", "3"]
    assert client.usage.calls == 1


def test_retry_after_is_waited_for(serve, tmp_path):
    server = serve(Reply(429, {"error": {"message": "rate limited"}}, {"Retry-After": "1"}),
                   Reply(body=completion("A")))
    assert make_client(server, tmp_path).chat(ask()).text == "A"
    first, second = server.requests
    # The SDK's own first backoff is at most 0.5 s: a longer gap is the header's.
    assert second.at - first.at >= 0.95


def test_retries_stop_after_max_retries_with_one_line(serve, tmp_path):
    server = serve(Reply(429, {"error": {"message": "quota\nexceeded"}}, FAST_RETRY))
    client = make_client(server, tmp_path, max_retries=2)
    with pytest.raises(EfficientEQAError) as raised:
        client.chat(ask())
    message = str(raised.value)
    assert len(server.requests) == 3 and not isinstance(raised.value, RequestRejected)
    assert "\n" not in message and "HTTP 429 after 3 tries" in message and "quota exceeded" in message


def test_a_slow_server_times_out_per_try(serve, tmp_path):
    server = serve(Reply(delay_s=3.0))
    client = make_client(server, tmp_path, timeout_s=0.3, max_retries=1)
    start = time.monotonic()
    with pytest.raises(EfficientEQAError) as raised:
        client.chat(ask())
    assert time.monotonic() - start < 2.5 and len(server.requests) == 2
    assert str(raised.value).startswith(f"model server at {server.base_url}/chat/completions did not "
                                        "answer within 0.3 s (2 tries)")


def test_dead_server_is_one_line_error(tmp_path):
    base_url = f"http://127.0.0.1:{closed_port()}/v1"
    client = OpenAIChatClient(ClientConfig(base_url=base_url, cache=False, max_retries=1, timeout_s=2))
    with pytest.raises(EfficientEQAError) as raised:
        client.chat(ask())
    message = str(raised.value)
    assert "\n" not in message and "Traceback" not in message
    assert message.startswith(f"model server at {base_url}/chat/completions unreachable after 2 tries")
    assert "Connection refused" in message and "efficienteqa models serve" in message
    assert raised.value.__cause__ is None  # the one line is all there is


def test_400_not_retried(serve, tmp_path):
    server = serve(Reply(400, {"error": {"message": "bad top_logprobs"}}, FAST_RETRY))
    with pytest.raises(RequestRejected, match="HTTP 400 bad top_logprobs") as raised:
        make_client(server, tmp_path).chat(ask())
    assert raised.value.status == 400 and len(server.requests) == 1


def test_api_key_only_in_authorization_header(serve, tmp_path, monkeypatch, caplog):
    monkeypatch.setenv("FAKE_OPENAI_KEY", SECRET)
    caplog.set_level(logging.DEBUG)
    server = serve(Reply(503, f"upstream said {SECRET}", FAST_RETRY), Reply())
    client = make_client(server, tmp_path, api_key_env="FAKE_OPENAI_KEY", cache=True)
    response = client.chat(ask())
    client.chat(ask())  # cache hit

    assert len(server.requests) == 2
    assert all(r.headers["authorization"] == f"Bearer {SECRET}" for r in server.requests)
    assert all(SECRET not in json.dumps(r.body) for r in server.requests)
    assert SECRET not in repr(client.config) and SECRET not in repr(client)
    assert caplog.records and SECRET not in caplog.text
    assert SECRET not in json.dumps(response.raw)
    files = list(tmp_path.glob("responses.sqlite*"))
    assert files and all(SECRET.encode() not in f.read_bytes() for f in files)


@pytest.mark.trial("4.2")
@pytest.mark.parametrize("status", [401, 503])
def test_api_key_redacted_from_errors(serve, tmp_path, monkeypatch, status):
    monkeypatch.setenv("FAKE_OPENAI_KEY", SECRET)
    server = serve(Reply(status, {"error": {"message": f"Incorrect API key provided: {SECRET}"}},
                         FAST_RETRY))
    client = make_client(server, tmp_path, api_key_env="FAKE_OPENAI_KEY", max_retries=1)
    with pytest.raises(EfficientEQAError) as raised:
        client.chat(ask())
    assert SECRET not in str(raised.value) and "Incorrect API key provided: ***" in str(raised.value)
    assert raised.value.__cause__ is None and raised.value.__context__ is not None
    if status == 401:
        assert isinstance(raised.value, RequestRejected) and "$FAKE_OPENAI_KEY" in str(raised.value)


@pytest.mark.trial("2.21")
def test_missing_api_key_fails_before_any_request(serve, tmp_path, monkeypatch):
    monkeypatch.delenv("FAKE_OPENAI_KEY", raising=False)
    monkeypatch.setenv("OPENAI_API_KEY", SECRET)  # the SDK's fallback must not stand in
    server = serve()
    with pytest.raises(EfficientEQAError, match="FAKE_OPENAI_KEY is not set") as raised:
        make_client(server, tmp_path, api_key_env="FAKE_OPENAI_KEY")
    assert "\n" not in str(raised.value) and server.requests == []


def test_usage_and_cost(serve, tmp_path):
    server = serve(Reply(body=completion(prompt_tokens=1000, completion_tokens=200)),
                   Reply(body={"choices": [{"message": {"content": None}}]}))
    client = make_client(server, tmp_path, price_prompt_per_1k=0.0025, price_completion_per_1k=0.01)
    first = client.chat(ask("one"))
    empty = client.chat(ask("two"))
    assert (first.prompt_tokens, first.completion_tokens) == (1000, 200) and first.latency_s > 0
    assert empty.text == "" and empty.prompt_tokens == 0 and empty.model == "fake-4o"
    usage = client.usage
    assert (usage.calls, usage.cached_calls) == (2, 0)
    assert (usage.prompt_tokens, usage.completion_tokens) == (1000, 200)
    assert usage.cost_usd == pytest.approx(0.0025 + 0.002)
    assert usage.latency_s >= first.latency_s + empty.latency_s - 1e-9


def test_latency_counts_the_retries(serve, tmp_path):
    server = serve(Reply(503, "busy", {"retry-after-ms": "300"}), Reply())
    assert make_client(server, tmp_path).chat(ask()).latency_s >= 0.3


def test_malformed_reply_is_clear(serve, tmp_path):
    client = make_client(serve(Reply(body="<html>hi</html>")), tmp_path)
    with pytest.raises(EfficientEQAError, match="not JSON: <html>hi</html>"):
        client.chat(ask())
    client = make_client(serve(Reply(body={"error": "x"})), tmp_path)
    with pytest.raises(EfficientEQAError, match="no choices"):
        client.chat(ask())


def test_cache_hit_without_a_request(serve, tmp_path):
    server = serve(Reply(body=completion("C", logprobs=True)))
    client = make_client(server, tmp_path, cache=True, capabilities=Capabilities(logprobs=True),
                         price_prompt_per_1k=1.0)
    first = client.chat(ask(), logprobs=2, temperature=0.7, seed=3)
    second = client.chat(ask(), logprobs=2, temperature=0.7, seed=3)
    assert len(server.requests) == 1
    assert second.cached and not first.cached and second.text == first.text == "C"
    assert second.logprobs == first.logprobs and second.logprobs[0].top == (("C", -0.1), ("A", -2.5))
    assert second.latency_s < 0.05
    assert client.usage.calls == 2 and client.usage.cached_calls == 1
    assert client.usage.cost_usd == pytest.approx(12 / 1000)  # the hit costs nothing
    client.chat(ask(), logprobs=2, temperature=0.7, seed=4)  # seed is part of the key
    assert len(server.requests) == 2


def test_a_cache_hit_needs_no_server(serve, tmp_path):
    server = serve()
    make_client(server, tmp_path, cache=True).chat(ask())
    dead = f"http://127.0.0.1:{closed_port()}/v1"
    replay = make_client(server, tmp_path, cache=True, base_url=dead, max_retries=0)
    assert replay.chat(ask()).cached
    with pytest.raises(EfficientEQAError, match="unreachable"):
        replay.chat(ask("a question never asked"))


def test_cache_shared_across_base_urls_but_keyed_on_images(serve, tmp_path):
    caps = Capabilities(images=True)
    server_a, server_b = serve(), serve()
    client_a = make_client(server_a, tmp_path, cache=True, capabilities=caps)
    client_b = make_client(server_b, tmp_path, cache=True, capabilities=caps)
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


def test_cache_clear_stats_and_processes(serve, tmp_path):
    server = serve()
    client = make_client(server, tmp_path, cache=True)
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


def test_cache_threads(serve, tmp_path):
    from concurrent.futures import ThreadPoolExecutor

    server = serve()
    client = make_client(server, tmp_path, cache=True)
    with ThreadPoolExecutor(4) as pool:
        texts = list(pool.map(lambda i: client.chat(ask(f"q{i % 5}")).text, range(40)))
    assert texts == ["B"] * 40 and client.usage.calls == 40
    assert ResponseCache(tmp_path / "responses.sqlite").stats()["entries"] == 5
    assert 5 <= len(server.requests) <= 40


def test_broken_cache_does_not_fail_the_call(serve, tmp_path, caplog):
    (tmp_path / "responses.sqlite").write_bytes(b"this is not a database" * 100)
    server = serve()
    client = make_client(server, tmp_path, cache=True)
    assert client.chat(ask()).text == "B" and len(server.requests) == 1
    assert "response cache unavailable" in caplog.text


@pytest.mark.parametrize("entry", [
    "{not json", '{"text": "B", "model": 7, "logprobs": [1]}', '[1, 2]', '{"bogus": 1}',
    # fault trial 5.5: valid JSON, fields of another type
    '{"text": "B", "model": "m", "prompt_tokens": null, "completion_tokens": null}',
    '{"text": {"a": 1}, "model": "m", "prompt_tokens": "many"}',
    '{"text": "B", "model": "m", "logprobs": [{"token": "B", "logprob": null}]}',
    '{"text": "B", "model": "m", "logprobs": [{"token": "B", "logprob": -1, "top": [["A"]]}]}',
    '{"text": "B", "model": "m", "cached": 1, "raw": []}'])
def test_a_bad_cache_entry_is_a_miss_and_is_dropped(serve, tmp_path, caplog, entry):
    """Another version of the code may write into the shared cache; an entry this one
    cannot read costs one model call, once, not every episode that hits it. Its fields'
    types are checked on reading (a null token count failed every episode at the usage sum,
    with no word of the cache), and the warning names the cache file."""
    server = serve()
    client = make_client(server, tmp_path, cache=True)
    client.chat(ask())  # stores the reply
    cache = ResponseCache(tmp_path / "responses.sqlite")
    cache._connection().execute("UPDATE responses SET response = ?", (entry,))
    fresh = make_client(server, tmp_path, cache=True)
    assert fresh.chat(ask()).text == "B" and len(server.requests) == 2  # a miss, called again
    assert "dropped an unreadable response-cache entry" in caplog.text
    assert str(tmp_path / "responses.sqlite") in caplog.text
    assert make_client(server, tmp_path, cache=True).chat(ask()).cached  # the new reply is kept


def test_the_cache_checks_the_type_of_every_field_of_a_response():
    from dataclasses import fields

    from efficienteqa.models.base import ChatResponse, TokenLogprob
    from efficienteqa.models.cache import FIELD_TYPES, response_from_json, response_to_json

    assert set(FIELD_TYPES) == {f.name for f in fields(ChatResponse)}
    full = ChatResponse("B", "m", 3, 1, 0.5, False, [TokenLogprob("B", -0.1, (("A", -2.0),))],
                        {"id": "x"}, "stop")
    assert response_from_json(response_to_json(full)) == full


def test_a_reply_that_is_not_utf8_is_one_line(serve, tmp_path):
    """Bytes that are not UTF-8 from a server are a clear error, not a traceback."""
    bad = b'{"choices": [{"index": 0, "message": {"role": "assistant", "content": "\xff\xfe"}}]}'
    client = make_client(serve(Reply(body=bad)), tmp_path)
    with pytest.raises(EfficientEQAError, match="not UTF-8|not JSON") as err:
        client.chat(ask())
    assert "\n" not in str(err.value)


def test_probe_capabilities(serve, tmp_path):
    server = serve(Reply(body=completion(logprobs=True)))
    client = make_client(server, tmp_path, cache=True, capabilities=Capabilities(logprobs=True))
    assert client.probe_capabilities().logprobs and client.capabilities.logprobs
    assert server.body()["logprobs"] is True and server.body()["max_tokens"] == 1
    client = make_client(serve(Reply(400, "logprobs unsupported"), Reply()), tmp_path,
                         capabilities=Capabilities(logprobs=True, images=True))
    caps = client.probe_capabilities()
    assert not caps.logprobs and caps.images
    client = make_client(serve(Reply(body=completion())), tmp_path, capabilities=Capabilities(logprobs=True))
    assert not client.probe_capabilities().logprobs  # answered, but without logprobs


# ------------------------------------------------ real servers' habits: the model layer

@pytest.fixture
def private_cache(tmp_path, monkeypatch):
    """Probes and replies kept under tmp_path, never in the user's cache."""
    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def openai_backend(server: FakeServer, **overrides) -> ChatBackend:
    return ChatBackend(**{"kind": "openai", "model": "fake-4o", "base_url": server.base_url,
                          "timeout_s": 10.0, "retries": 0, **overrides})


def test_an_openai_server_is_probed_once_and_the_probe_is_kept(serve, private_cache):
    server = serve(Reply(body=completion(logprobs=True)))
    client = build_chat_model(openai_backend(server))
    caps = client.capabilities
    assert caps.logprobs and caps.json_schema and caps.source == "probed"
    assert caps.probed == {"logprobs": "returned", "json_schema": "accepted"}
    first, second = server.requests
    assert first.body["logprobs"] is True and first.body["top_logprobs"] == 10
    assert second.body["response_format"]["type"] == "json_schema"
    again = build_chat_model(openai_backend(server)).capabilities
    assert len(server.requests) == 2  # the second run reads the kept probe
    assert again.logprobs and again.source == "probe cache" and again.probed == caps.probed
    assert list((private_cache / "probes").glob("*.json"))


def test_a_server_that_ignores_logprobs_is_probed_as_without_them(serve, private_cache):
    server = serve(Reply(body=completion()))
    caps = build_chat_model(openai_backend(server)).capabilities
    assert not caps.logprobs and caps.probed["logprobs"] == "ignored"


def test_a_server_that_rejects_logprobs_is_probed_as_without_them(serve, private_cache):
    server = serve(Reply(400, {"error": {"message": "logprobs is not supported"}}),
                   Reply(body=completion()))
    client = build_chat_model(openai_backend(server))
    caps = client.capabilities
    assert not caps.logprobs and caps.probed["logprobs"] == "rejected: HTTP 400"
    assert "logprobs" not in server.requests[1].body  # the plain request passed
    client.chat(ask(), logprobs=10)  # the agent's request then carries no logprobs
    assert "logprobs" not in server.body()


def test_a_server_that_rejects_every_request_fails_the_probe_in_one_line(serve, private_cache):
    server = serve(Reply(400, {"error": {"message": "model 'fake-4o' does not exist"}}))
    with pytest.raises(RequestRejected, match="does not exist") as raised:
        build_chat_model(openai_backend(server))
    assert "\n" not in str(raised.value) and len(server.requests) == 2


def test_an_unreachable_openai_server_fails_before_the_work_with_its_own_hint(private_cache):
    base_url = f"http://127.0.0.1:{closed_port()}/v1"
    with pytest.raises(EfficientEQAError) as raised:
        build_chat_model(ChatBackend(kind="openai", model="m", base_url=base_url, retries=0))
    message = str(raised.value)
    assert "\n" not in message and message.startswith(f"model server at {base_url}")
    assert "unreachable after 1 tries" in message
    assert "models serve" not in message and f"--backends.vlm openai:m@{base_url}" in message


def test_the_probe_retries_once_whatever_the_retries(serve, private_cache):
    """A dead or hung server fails the start in two tries, not the calls' five."""
    base_url = f"http://127.0.0.1:{closed_port()}/v1"
    with pytest.raises(EfficientEQAError, match="unreachable after 2 tries"):
        build_chat_model(ChatBackend(kind="openai", model="m", base_url=base_url, retries=4))
    server = serve(Reply(delay_s=2.0))
    start = time.monotonic()
    with pytest.raises(EfficientEQAError, match=r"within 0.3 s \(2 tries\)"):
        build_chat_model(openai_backend(server, timeout_s=0.3, retries=4))
    assert time.monotonic() - start < 1.8 and len(server.requests) == 2


def test_the_local_server_is_not_probed(serve, private_cache):
    server = serve()
    caps = build_chat_model(ChatBackend(kind="local", model="m", base_url=server.base_url)).capabilities
    assert server.requests == []
    assert (caps.logprobs, caps.images, caps.grammar, caps.source) == (True, False, True, "declared")


def test_the_image_probe_finds_a_per_request_cap(serve, private_cache):
    """vLLM's --limit-mm-per-prompt image=1 answers HTTP 400 to 5 images."""
    limit = Reply(400, {"error": {"message": "At most 1 image(s) may be provided in one request."}})
    server = serve(Reply(body=completion(logprobs=True)), Reply(), limit, Reply())
    caps = build_chat_model(openai_backend(server, images=True)).capabilities
    assert caps.images and caps.max_images == 1
    assert caps.probed["images"] == "1 accepted, 5 rejected: HTTP 400"
    counts = [sum(p.get("type") == "image_url" for p in r.body["messages"][0]["content"])
              for r in server.requests[2:]]
    assert counts == [5, 1]
    assert build_chat_model(openai_backend(server, images=True)).capabilities.max_images == 1
    assert len(server.requests) == 4  # kept


def test_images_are_probed_only_when_asked_and_then_added_to_the_kept_probe(serve, private_cache):
    server = serve(Reply(body=completion(logprobs=True)))
    assert build_chat_model(openai_backend(server)).capabilities.max_images is None
    assert len(server.requests) == 2  # no image request for a text run
    caps = build_chat_model(openai_backend(server, images=True)).capabilities
    assert len(server.requests) == 3 and caps.images and caps.max_images is None
    assert caps.probed["images"] == "5 accepted" and caps.logprobs


def test_a_server_without_images_is_probed_as_such(serve, private_cache):
    no = Reply(400, {"error": {"message": "this model does not support images"}})
    server = serve(Reply(body=completion(logprobs=True)), Reply(), no)
    caps = build_chat_model(openai_backend(server, images=True)).capabilities
    assert not caps.images and caps.probed["images"].startswith("rejected:")


def test_a_rejection_after_a_kept_probe_drops_it(serve, private_cache):
    server = serve(Reply(body=completion(logprobs=True)))
    build_chat_model(openai_backend(server))
    server.replies = [Reply(400, {"error": {"message": "logprobs are off now"}})]
    client = build_chat_model(openai_backend(server, cache=False))
    assert client.capabilities.source == "probe cache"
    with pytest.raises(RequestRejected, match="probe, now dropped"):
        client.chat(ask(), logprobs=10)
    assert not list((private_cache / "probes").glob("*.json"))


def test_a_reply_cut_at_max_tokens_says_so_and_the_cache_keeps_it(serve, tmp_path):
    cut = completion("The answer is")
    cut["choices"][0]["finish_reason"] = "length"
    server = serve(Reply(body=cut))
    client = make_client(server, tmp_path, cache=True)
    assert client.chat(ask(), max_tokens=3).finish_reason == "length"
    hit = client.chat(ask(), max_tokens=3)
    assert hit.cached and hit.finish_reason == "length"
    assert client.chat(ask("other")).finish_reason == "length"


def test_an_old_cache_entry_without_finish_reason_still_loads():
    from efficienteqa.models.cache import response_from_json

    old = json.dumps({"text": "B", "model": "m", "prompt_tokens": 1, "completion_tokens": 1,
                      "latency_s": 0.1, "cached": False, "logprobs": None, "raw": {}})
    response = response_from_json(old)
    assert response.text == "B" and response.finish_reason is None


def test_timeout_and_retries_reach_the_client_from_the_stack():
    from efficienteqa.stack import Stack, parse_vlm

    stack = Stack(vlm="openai:m@http://127.0.0.1:9/v1", timeout_s=3.5, retries=1,
                  image_format="png", image_max_side=256, image_detail="low", api_key_env="none")
    backend = replace(parse_vlm(stack.vlm, images=True, **stack.server_options()), probe=False)
    config = build_chat_model(backend).config
    assert (config.timeout_s, config.max_retries) == (3.5, 1)
    assert (config.image_format, config.image_max_side, config.image_detail) == ("png", 256, "low")
    assert config.api_key_env is None
    default = replace(parse_vlm("openai:m@http://127.0.0.1:9/v1", images=True), probe=False)
    assert (default.timeout_s, default.retries) == (120.0, 4)
    assert build_chat_model(default).config.image_format == "jpeg"
    for bad, message in [({"timeout_s": 0}, "not a positive number"), ({"retries": -1}, "negative"),
                         ({"image_format": "gif"}, "unknown image format"),
                         ({"image_detail": "max"}, "unknown image detail"),
                         ({"image_max_side": 4}, "too small")]:
        with pytest.raises(EfficientEQAError, match=message):
            parse_vlm("openai:m", images=True, **bad)


def test_a_timeout_names_the_option(serve, tmp_path):
    server = serve(Reply(delay_s=2.0))
    with pytest.raises(EfficientEQAError, match="raise --backends.timeout-s"):
        make_client(server, tmp_path, timeout_s=0.2, max_retries=0).chat(ask())


def test_the_cli_refuses_a_bad_server_option_in_one_line(cli, tmp_path):
    result = cli("ask", "Where is the sofa?", "--image-format", "gif", "--out", str(tmp_path / "out"))
    assert result.returncode == 1 and "unknown image format 'gif'" in result.stdout
    assert "Traceback" not in result.stdout + result.stderr and not (tmp_path / "out").exists()


def test_image_format_size_and_detail_reach_the_request(serve, private_cache):
    server = serve(Reply(body=completion(logprobs=True)))
    client = build_chat_model(openai_backend(server, images=True, image_detail="low",
                                             image_max_side=128))
    image = np.random.default_rng(0).integers(0, 255, (384, 512, 3), np.uint8)
    client.chat(ask("What is here?", image))
    part = server.body()["messages"][1]["content"][1]["image_url"]
    assert part["detail"] == "low" and part["url"].startswith("data:image/jpeg;base64,")
    decoded = Image.open(io.BytesIO(base64.b64decode(part["url"].split(",", 1)[1])))
    assert decoded.size == (128, 96) and decoded.format == "JPEG"
    plain = build_chat_model(openai_backend(server, images=True, image_format="png"))
    plain.chat(ask("What is here?", image))
    part = server.body()["messages"][1]["content"][1]["image_url"]
    assert "detail" not in part and part["url"].startswith("data:image/png;base64,")


def test_the_image_encoding_is_part_of_the_cache_key():
    image = np.zeros((8, 8, 3), np.uint8)
    keys = {request_key("m", ask("q", image), max_tokens=8, temperature=0.0, logprobs=None,
                        json_schema=None, seed=None, image_encoding=ClientConfig(
                            image_format=f, image_detail=d).image_encoding)
            for f in ("png", "jpeg") for d in (None, "low", "high")}
    assert len(keys) == 6
    assert ClientConfig().image_encoding == "png@512"  # as before detail existed


def test_the_openai_key_never_reaches_another_host(serve, private_cache, monkeypatch):
    monkeypatch.setenv("OPENAI_API_KEY", SECRET)
    monkeypatch.setenv("VLLM_KEY", "vllm-secret")
    server = serve(Reply(body=completion(logprobs=True)))
    build_chat_model(openai_backend(server, cache=False)).chat(ask())
    build_chat_model(openai_backend(server, cache=False, api_key_env="none")).chat(ask("2"))
    assert server.requests and all(SECRET not in r.headers.get("authorization", "")
                                   for r in server.requests)
    build_chat_model(openai_backend(server, cache=False, api_key_env="VLLM_KEY")).chat(ask("3"))
    assert server.requests[-1].headers["authorization"] == "Bearer vllm-secret"
    build_chat_model(openai_backend(server, cache=False,
                                    api_key_env="OPENAI_API_KEY")).chat(ask("4"))
    assert server.requests[-1].headers["authorization"] == f"Bearer {SECRET}"  # named: sent


def test_the_openai_key_is_sent_to_the_official_host_only():
    assert ChatBackend(kind="openai", model="gpt-4o").key_env == "OPENAI_API_KEY"
    assert ChatBackend(kind="openai", model="gpt-4o",
                       base_url="https://api.openai.com/v1").key_env == "OPENAI_API_KEY"
    for url in ("http://api.openai.com/v1", "https://api.openai.com.evil.example/v1",
                "http://127.0.0.1:8000/v1", "https://vllm.example.org/v1"):
        assert ChatBackend(kind="openai", model="m", base_url=url).key_env is None, url
    assert ChatBackend(kind="openai", model="m", base_url="http://h/v1",
                       api_key_env="MY_KEY").key_env == "MY_KEY"
    assert ChatBackend(kind="openai", model="gpt-4o", api_key_env="None").key_env is None
    assert ChatBackend(kind="local").key_env is None


def test_the_cache_key_holds_the_server_of_an_openai_backend(serve, private_cache):
    server_a, server_b = serve(Reply(body=completion("A", logprobs=True))), serve(
        Reply(body=completion("B", logprobs=True)))
    assert build_chat_model(openai_backend(server_a, cache=True)).chat(ask()).text == "A"
    reply = build_chat_model(openai_backend(server_b, cache=True)).chat(ask())
    assert not reply.cached and reply.text == "B"  # another server, same model name
    assert build_chat_model(openai_backend(server_a, cache=True)).chat(ask()).cached


def test_an_ask_against_a_dead_openai_server_does_not_succeed_from_the_cache(serve, private_cache):
    server = serve(Reply(body=completion(logprobs=True)))
    build_chat_model(openai_backend(server, cache=True)).chat(ask())
    dead = f"http://127.0.0.1:{closed_port()}/v1"
    with pytest.raises(EfficientEQAError, match="unreachable"):
        build_chat_model(ChatBackend(kind="openai", model="fake-4o", base_url=dead, retries=0))


def test_the_local_models_cache_key_is_unchanged():
    """The embedded local model is keyed as before the server URL was: its cache still hits."""
    messages = [Message("system", "You explore houses."), Message("user", "Which door, A or B?")]
    key = request_key("qwen2.5-coder-1.5b", messages, max_tokens=64, temperature=0.0,
                      logprobs=10, json_schema={"type": "object"}, seed=None, image_encoding="")
    assert key == "e497035d15646dbacd71b112bd9c857a8cec625ad0f06d0f80214893fb5f63b8"
    assert request_key("qwen2.5-coder-1.5b", messages, max_tokens=64, temperature=0.0,
                       logprobs=10, json_schema={"type": "object"}, seed=None,
                       server="http://127.0.0.1:8000/v1") != key


def test_a_local_backend_keys_its_cache_without_its_port(serve, tmp_path, private_cache):
    first, second = serve(Reply(body=completion("A"))), serve(Reply(body=completion("B")))
    assert build_chat_model(ChatBackend(kind="local", model="m", base_url=first.base_url)).config \
        .cache_server is None
    build_chat_model(ChatBackend(kind="local", model="m", base_url=first.base_url)).chat(ask())
    again = build_chat_model(ChatBackend(kind="local", model="m", base_url=second.base_url))
    assert again.chat(ask()).cached and second.requests == []


def test_usage_serialises_its_cost():
    from dataclasses import asdict

    from efficienteqa.models.base import ChatResponse, Usage

    usage = Usage()
    usage.add(ChatResponse("x", "m", prompt_tokens=10, completion_tokens=2), cost_usd=0.25)
    assert asdict(usage) == usage.to_dict() == {
        "calls": 1, "cached_calls": 0, "prompt_tokens": 10, "completion_tokens": 2,
        "latency_s": 0.0, "cost_usd": 0.25}


def test_gpt4o_usage_is_priced(serve, private_cache):
    server = serve(Reply(body=completion(prompt_tokens=1000, completion_tokens=100, logprobs=True)))
    client = build_chat_model(openai_backend(server, model="gpt-4o", cache=False))
    client.chat(ask())
    assert client.usage.cost_usd == pytest.approx(0.0025 + 0.001)
    assert client.usage.calls == 1  # the probe is not counted


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
        pytest.skip("llama_cpp is not importable (build llama-cpp-python with GGML_NATIVE=OFF)")
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


def test_a_server_that_fails_on_json_schemas_is_probed_as_without_them(serve, private_cache):
    """llama-cpp-python's server answers HTTP 500 to a JSON-schema response_format: the probe
    reads that as "not supported" (a plain request passes) and the run goes on without it."""
    server = serve(Reply(body=completion(logprobs=True)),
                   Reply(500, {"error": {"message": "Input should be 'text' or 'json_object'"}}),
                   Reply(body=completion()))
    caps = build_chat_model(openai_backend(server)).capabilities
    assert caps.logprobs and not caps.json_schema
    assert caps.probed["json_schema"] == "failed: HTTP 500, read as not supported"
    assert "response_format" not in server.requests[2].body  # the plain request that passed


def test_a_server_that_fails_every_request_still_fails_the_probe_in_one_line(serve, private_cache):
    server = serve(Reply(500, {"error": {"message": "internal error"}}))
    with pytest.raises(EfficientEQAError, match="HTTP 500") as raised:
        build_chat_model(openai_backend(server))
    assert "\n" not in str(raised.value)


def test_a_missing_key_names_the_flag_that_changes_it(tmp_path, monkeypatch):
    monkeypatch.delenv("EFFICIENTEQA_TEST_KEY", raising=False)
    with pytest.raises(EfficientEQAError) as raised:
        OpenAIChatClient(ClientConfig(base_url="http://127.0.0.1:9/v1", model="m",
                                      api_key_env="EFFICIENTEQA_TEST_KEY"))
    assert "--backends.api-key-env none" in str(raised.value) and "None" not in str(raised.value)


@pytest.mark.slow
def test_the_projects_own_server_works_through_openai_as_through_local(llama_server, private_cache):
    """`--vlm openai:MODEL@URL` against the llama-cpp-python server `models serve` runs: the
    probe passes (the server's HTTP 500 to a JSON schema reads as not supported) and the
    replies are the ones `local:` gets from the same server."""
    openai_model = build_chat_model(ChatBackend(kind="openai", model="smollm2-135m",
                                                base_url=llama_server, retries=0, timeout_s=60))
    caps = openai_model.capabilities
    assert caps.source == "probed" and caps.logprobs
    assert caps.probed["json_schema"] in ("accepted", "failed: HTTP 500, read as not supported")
    print(f"\nllama-cpp-python server probed: {caps.probed}")
    local_model = build_chat_model(ChatBackend(kind="local", model="smollm2-135m",
                                               base_url=llama_server, timeout_s=60))
    messages = [Message("user", "Answer with one letter. Is the sky blue? A: yes, B: no.")]
    a = openai_model.chat(messages, max_tokens=4, logprobs=3, temperature=0.0)
    b = local_model.chat(messages, max_tokens=4, logprobs=3, temperature=0.0)
    assert a.text == b.text and a.logprobs and b.logprobs
    # the same tokens and alternatives; the values agree up to llama.cpp's run-to-run noise
    # (its prompt cache evaluates a repeated prefix in another batch: about 0.04 nats here)
    assert [t.token for t in a.logprobs] == [t.token for t in b.logprobs]
    assert [lp.logprob for lp in a.logprobs] == pytest.approx([lp.logprob for lp in b.logprobs],
                                                             abs=0.15)


# ------------------------------------------------------------------ --capabilities FILE

def test_a_capabilities_file_stands_in_for_the_probe(serve, private_cache, tmp_path):
    """A server whose answers mislead the probe: the user says what it can do, and it is not
    asked."""
    server = serve(Reply(body=completion()))
    declared = tmp_path / "caps.json"
    declared.write_text('{"logprobs": true, "json_schema": false, "images": true, "max_images": 1}')
    client = build_chat_model(openai_backend(server, images=True,
                                             capabilities_file=str(declared)))
    caps = client.capabilities
    assert server.requests == []
    assert (caps.logprobs, caps.json_schema, caps.images, caps.max_images, caps.source) == (
        True, False, True, 1, "file")
    text_only = build_chat_model(openai_backend(server, capabilities_file=str(declared)))
    assert not text_only.capabilities.images  # images only where the run reads them


@pytest.mark.parametrize("text, said", [
    ("not json", "is not JSON"), ("[1, 2]", "holds no JSON object"),
    ('{"logprobs": "yes"}', "bad entry 'logprobs'"), ('{"max_images": true}', "bad entry"),
    ('{"max_images": 0}', "allows 0 images"), ('{"speed": 3}', "bad entry 'speed'")])
def test_a_bad_capabilities_file_is_one_line_before_any_work(tmp_path, text, said):
    from efficienteqa.stack import parse_vlm

    bad = tmp_path / "caps.json"
    bad.write_text(text)
    with pytest.raises(EfficientEQAError, match=said) as raised:
        parse_vlm("openai:m@http://127.0.0.1:9/v1", images=False, capabilities=str(bad))
    assert "\n" not in str(raised.value)


def test_capabilities_are_refused_for_the_embedded_server_and_a_missing_file_is_said(tmp_path):
    from efficienteqa.stack import parse_vlm

    good = tmp_path / "caps.json"
    good.write_text("{}")
    with pytest.raises(EfficientEQAError, match="embedded one"):
        parse_vlm("local:qwen2.5-coder-1.5b", images=False, capabilities=str(good))
    with pytest.raises(EfficientEQAError, match="cannot read the capabilities file"):
        parse_vlm("openai:m", images=False, capabilities=str(tmp_path / "missing.json"))


@pytest.mark.slow
def test_ask_through_openai_matches_local_on_the_projects_own_server(llama_server, private_cache,
                                                                    tmp_path):
    """The same question through `--vlm openai:smollm2-135m@URL` and `--vlm
    local:smollm2-135m@URL` on the llama-cpp-python server `models serve` runs: the same answer,
    steps, stop and replies (an eval's episode is this ask, run by the runner)."""
    from efficienteqa.ask import ask
    from efficienteqa.config.presets import build_config, build_stack

    said = {}
    for kind in ("openai", "local"):
        options = {"vlm": f"{kind}:smollm2-135m@{llama_server}", "relevancy": "overlap",
                   "matching": "words", "reading": "rules", "max_steps": 2, "cache": False,
                   "timeout_s": 60}
        one = ask("What is on the desk in the office?", "synthetic:0", tmp_path / kind,
                  stack=build_stack(options), config=build_config(options), assets="builtin",
                  report=False)
        record = json.loads(one.episode_json.read_text())
        said[kind] = (one.result.answer, one.result.steps, one.result.stop_reason,
                      [e["reply"] for e in record["model"]["exchanges"]])
    assert said["openai"] == said["local"]


@pytest.mark.trial("2.17")
def test_an_unreachable_judge_is_named_as_the_judge(private_cache, monkeypatch):
    """The hint of a server that cannot be reached names the option that chose it."""
    from efficienteqa.eval.runner import build_judge

    monkeypatch.delenv("OPENAI_API_KEY", raising=False)
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    url = f"http://127.0.0.1:{port}/v1"
    with pytest.raises(EfficientEQAError) as judge:
        build_judge(f"openai:gpt-4o@{url}", "grade")
    assert f"the server of --judge openai:gpt-4o@{url}" in str(judge.value)
    from efficienteqa.stack import parse_vlm

    backend = replace(parse_vlm(f"openai:gpt-4o@{url}", images=False), retries=0)
    with pytest.raises(EfficientEQAError) as vlm:
        build_chat_model(backend)
    assert f"the server of --backends.vlm openai:gpt-4o@{url}" in str(vlm.value)
