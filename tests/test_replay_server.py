"""The timing benchmarks' replay server (benchmarks/replay_server.py): cached replies after the
latency, concurrently; misses as documented (a fixed fallback reply, or HTTP 404 with --miss
error)."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from efficienteqa.models.base import Capabilities, ChatResponse, Message, TokenLogprob
from efficienteqa.models.cache import ResponseCache, request_key
from efficienteqa.models.client import OpenAIChatClient
from efficienteqa.models.client_config import ClientConfig
from efficienteqa.models.client_errors import RequestRejected

MODEL = "replay-test-model"
SCHEMA = {"type": "object", "required": ["answer", "confidence"],
          "properties": {"answer": {"type": "string"},
                         "confidence": {"type": "number", "minimum": 0.1}}}


@pytest.fixture(scope="module")
def replay():
    from benchmarks import replay_server

    return replay_server


def _client(url: str) -> OpenAIChatClient:
    """The project's client as the runner builds it for ``openai:MODEL@URL``, its cache off."""
    return OpenAIChatClient(ClientConfig(
        base_url=url, model=MODEL, cache=False, max_retries=0, timeout_s=10,
        capabilities=Capabilities(images=True, logprobs=True, json_schema=True)))


def _store(cache: ResponseCache, messages: list[Message], text: str, **kwargs) -> None:
    args = {"max_tokens": 256, "temperature": 0.0, "logprobs": None, "json_schema": None,
            "seed": None, **kwargs}
    images = any(m.images for m in messages)
    key = request_key(MODEL, messages, image_encoding="png@512" if images else "", **args)
    cache.put(key, ChatResponse(text=text, model=MODEL, prompt_tokens=7, completion_tokens=2,
                                logprobs=[TokenLogprob("yes", -0.1, (("yes", -0.1),))]))


@pytest.fixture
def server(replay, tmp_path: Path):
    made = []

    def start(**options):
        s = replay.serve(tmp_path / "responses.sqlite", **options)
        made.append(s)
        return s

    yield start
    for s in made:
        s.shutdown()
        s.server_close()


def test_a_cached_request_gets_the_cached_reply_after_the_latency(server, tmp_path: Path) -> None:
    s = server(latency_s=0.2)
    cache = ResponseCache(tmp_path / "responses.sqlite")
    plain = [Message("user", "What is on the table?")]
    image = [Message("user", "And here?", (np.full((8, 6, 3), 90, np.uint8),))]
    _store(cache, plain, "a lamp", max_tokens=96)
    _store(cache, plain, '{"answer": "a lamp", "confidence": 0.9}', json_schema=SCHEMA, logprobs=1)
    _store(cache, image, "a cup")

    client = _client(s.base_url)
    start = time.perf_counter()
    reply = client.chat(plain, max_tokens=96)
    assert time.perf_counter() - start >= 0.2
    assert reply.text == "a lamp" and reply.prompt_tokens == 7
    structured = client.chat(plain, json_schema=SCHEMA, logprobs=1)
    assert json.loads(structured.text)["answer"] == "a lamp"
    assert structured.logprobs is not None and structured.logprobs[0].token == "yes"
    assert client.chat(image).text == "a cup"  # PNG images decode to the cached pixels
    assert s.stats.to_dict()["hits"] == 3 and s.stats.to_dict()["misses"] == 0

    import urllib.request
    with urllib.request.urlopen(s.base_url + "/models") as r:
        assert [m["id"] for m in json.load(r)["data"]] == [MODEL]


def test_requests_are_served_concurrently(server, tmp_path: Path) -> None:
    s = server(latency_s=0.3)
    _store(ResponseCache(tmp_path / "responses.sqlite"), [Message("user", "hi")], "hello")
    replies: list[str] = []
    clients = [_client(s.base_url) for _ in range(2)]
    for c in clients:
        c._client()  # import the SDK and build its client before the clock starts

    def ask(client: OpenAIChatClient) -> None:
        replies.append(client.chat([Message("user", "hi")]).text)

    threads = [threading.Thread(target=ask, args=(c,)) for c in clients]
    start = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert replies == ["hello", "hello"]
    assert time.perf_counter() - start < 0.55  # serialized, it would take 0.6 s
    assert s.stats.to_dict()["max_in_flight"] == 2


def test_a_miss_gets_the_fallback_reply_and_is_counted(replay, server) -> None:
    s = server(latency_s=0.0)
    client = _client(s.base_url)
    assert client.chat([Message("user", "never asked")]).text == replay.DEFAULT_FALLBACK
    reply = json.loads(client.chat([Message("user", "never asked")], json_schema=SCHEMA).text)
    assert reply == {"answer": "", "confidence": 0.1}  # the smallest valid instance
    deadline = time.monotonic() + 2.0  # the handler leaves "in flight" after its reply is sent
    while s.stats.to_dict()["in_flight"] and time.monotonic() < deadline:
        time.sleep(0.01)
    assert s.stats.to_dict() == {"requests": 2, "hits": 0, "misses": 2, "in_flight": 0,
                                 "max_in_flight": 1}


def test_a_miss_is_an_error_with_miss_error(server) -> None:
    s = server(latency_s=0.0, miss="error")
    with pytest.raises(RequestRejected) as error:
        _client(s.base_url).chat([Message("user", "never asked")])
    assert error.value.status == 404
    assert s.stats.to_dict()["misses"] == 1


def test_a_miss_that_asks_for_logprobs_gets_them(server, monkeypatch, tmp_path) -> None:
    """The client's capability probe is a miss: it must find the logprobs the replayed server
    (llama.cpp) gives, or every replayed run would fall back to the verbalized answer."""
    from efficienteqa.models.backends import ChatBackend, build_chat_model

    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(tmp_path / "cache"))  # the probe is kept there
    s = server(latency_s=0.0)
    reply = _client(s.base_url).chat([Message("user", "never asked")], logprobs=1)
    assert reply.logprobs and all(t.logprob == 0.0 for t in reply.logprobs)
    model = build_chat_model(ChatBackend(kind="openai", model=MODEL, base_url=s.base_url,
                                         cache=False))
    assert model.capabilities.logprobs and model.capabilities.source == "probed"
