"""An OpenAI-compatible replay server, for benchmarks only (DESIGN 6, results/ray/).

It answers ``POST /v1/chat/completions`` from the project's response cache
(``efficienteqa.models.cache``) after sleeping a set latency, so that the evaluation runner can be
timed as a user of GPT-4o or of a shared vLLM server would see it: bound by latency, not by the
CPU that runs the model. ``GET /v1/models`` lists the models in the cache; ``GET /stats`` gives
the request, hit and miss counts and the most requests ever in flight at once.

How a request finds its cached reply: the client (``models/client.py``) keys a reply by
``request_key(model, messages, max_tokens, temperature, logprobs, json_schema, seed,
image_encoding)`` *before* turning the request into its HTTP body. This server turns the body
back into those arguments: message text and ``data:`` images (decoded to pixels: exact for PNG
images not shrunk by the client), ``top_logprobs`` when ``logprobs`` is on, and the schema of a
``response_format`` (tried both bare and in OpenAI's ``{"name", "schema"}`` wrapper, since the
client wraps a bare schema). The cached reply's raw JSON is sent back when the cache holds it,
else a reply built from its text and logprobs.

A miss (a request the cache does not hold) is counted and answered, after the same latency, with
a fixed valid reply so that episodes run on: the text ``--fallback-text`` (default
``"I don't know."``), or, when the request asks for a JSON schema, the smallest JSON instance of
that schema (required properties only; strings "", numbers the minimum or 0, arrays
``minItems`` copies, enums their first value), with each word's logprob 0 when logprobs are
asked (the client's capability probe is such a miss). ``--miss error`` answers HTTP 404 instead, which
the client reports as a rejected request. Replies to misses are never written to the cache.

    python -m benchmarks.replay_server --port 8799 --latency-s 1.5
    OPENAI_API_KEY=replay efficienteqa eval --method blind --no-cache \\
        --vlm openai:qwen2.5-coder-1.5b@http://127.0.0.1:8799/v1 --out out/replay_run

The client must run with ``--no-cache`` (else it answers from the same cache without asking),
and the model named in ``--vlm`` must be the cached one (``GET /v1/models`` lists them). The key
is never checked: any ``OPENAI_API_KEY`` value works. Standard library plus numpy and Pillow
(already dependencies); one thread per request (``ThreadingHTTPServer``), so the latency of one
worker's call does not delay another's.
"""

from __future__ import annotations

import argparse
import base64
import io
import json
import sys
import threading
import time
import uuid
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.models.base import ChatResponse, Message, TokenLogprob
from efficienteqa.models.cache import ResponseCache, request_key

DEFAULT_FALLBACK = "I don't know."


@dataclass
class ReplayStats:
    requests: int = 0
    hits: int = 0
    misses: int = 0
    in_flight: int = 0
    max_in_flight: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def to_dict(self) -> dict[str, int]:
        with self.lock:
            return {"requests": self.requests, "hits": self.hits, "misses": self.misses,
                    "in_flight": self.in_flight, "max_in_flight": self.max_in_flight}


def _decode_image(url: str) -> tuple[np.ndarray, str]:
    """A ``data:image/FMT;base64,...`` URL as an RGB uint8 array, and FMT."""
    from PIL import Image

    head, _, payload = url.partition(",")
    fmt = head.removeprefix("data:image/").split(";")[0] or "png"
    with Image.open(io.BytesIO(base64.b64decode(payload))) as image:
        return np.asarray(image.convert("RGB")), fmt


def _messages(body: dict[str, Any]) -> tuple[list[Message], str | None]:
    """The request's messages as the client's ``Message``s, and the image format if any."""
    messages: list[Message] = []
    fmt = None
    for m in body.get("messages") or []:
        content = m.get("content")
        if isinstance(content, str) or content is None:
            messages.append(Message(m.get("role", "user"), content or ""))
            continue
        texts, images = [], []
        for part in content:
            if part.get("type") == "text":
                texts.append(part.get("text", ""))
            elif part.get("type") == "image_url":
                image, fmt = _decode_image((part.get("image_url") or {}).get("url", ""))
                images.append(image)
        messages.append(Message(m.get("role", "user"), "".join(texts), tuple(images)))
    return messages, fmt


def _schemas(body: dict[str, Any]) -> list[dict[str, Any] | None]:
    """The ``json_schema`` arguments that could have produced this body, likeliest first."""
    fmt = body.get("response_format")
    if not isinstance(fmt, dict):
        return [None]
    if fmt.get("type") == "json_schema" and isinstance(fmt.get("json_schema"), dict):
        wrapped = fmt["json_schema"]
        candidates = [wrapped]
        if wrapped.get("name") == "reply" and set(wrapped) == {"name", "schema"}:
            candidates.insert(0, wrapped["schema"])  # the client wrapped a bare schema
        return candidates
    if fmt.get("type") == "json_object" and isinstance(fmt.get("schema"), dict):
        return [fmt["schema"]]  # llama.cpp's grammar form (capabilities.grammar)
    return [None]


def request_keys(body: dict[str, Any], image_max_side: int = 512) -> list[str]:
    """The cache keys this request may have been stored under (see the module docstring)."""
    messages, fmt = _messages(body)
    logprobs = body.get("top_logprobs", 0) if body.get("logprobs") else None
    encoding = f"{fmt}@{image_max_side}" if fmt else ""
    return [request_key(str(body.get("model", "")), messages,
                        max_tokens=int(body.get("max_tokens") or body.get("max_completion_tokens")
                                       or 256),
                        temperature=float(body.get("temperature") or 0.0), logprobs=logprobs,
                        json_schema=schema, seed=body.get("seed"), image_encoding=encoding)
            for schema in _schemas(body)]


def minimal_instance(schema: dict[str, Any]) -> Any:
    """The smallest JSON value valid for a (simple) JSON schema; see the module docstring."""
    if "schema" in schema and "name" in schema:
        schema = schema["schema"]
    if "enum" in schema:
        return schema["enum"][0]
    if "const" in schema:
        return schema["const"]
    for key in ("anyOf", "oneOf", "allOf"):
        if schema.get(key):
            return minimal_instance(schema[key][0])
    kind = schema.get("type", "object")
    if isinstance(kind, list):
        kind = next((k for k in kind if k != "null"), "null")
    if kind == "object":
        props = schema.get("properties") or {}
        return {k: minimal_instance(props.get(k, {})) for k in schema.get("required", props)}
    if kind == "array":
        return [minimal_instance(schema.get("items") or {})
                for _ in range(int(schema.get("minItems", 0)))]
    if kind in ("number", "integer"):
        low = schema.get("minimum", 0)
        return int(low) if kind == "integer" else float(low)
    if kind == "boolean":
        return False
    if kind == "null":
        return None
    return ""


def completion(text: str, model: str, response: ChatResponse | None = None) -> dict[str, Any]:
    """An OpenAI ``chat.completion`` body for ``text`` (with ``response``'s logprobs, if any)."""
    choice: dict[str, Any] = {"index": 0, "finish_reason": "stop",
                              "message": {"role": "assistant", "content": text}, "logprobs": None}
    if response is not None and response.logprobs:
        choice["logprobs"] = {"content": [
            {"token": t.token, "logprob": t.logprob, "bytes": None,
             "top_logprobs": [{"token": a, "logprob": b, "bytes": None} for a, b in t.top]}
            for t in response.logprobs]}
    prompt = response.prompt_tokens if response is not None else 0
    done = response.completion_tokens if response is not None else 0
    return {"id": f"chatcmpl-replay-{uuid.uuid4().hex[:12]}", "object": "chat.completion",
            "created": int(time.time()), "model": model, "choices": [choice],
            "usage": {"prompt_tokens": prompt, "completion_tokens": done,
                      "total_tokens": prompt + done}}


class ReplayServer(ThreadingHTTPServer):
    """``ThreadingHTTPServer`` answering from ``cache`` after ``latency_s``."""

    daemon_threads = True
    request_queue_size = 128

    def __init__(self, address: tuple[str, int], cache: ResponseCache, *, latency_s: float = 1.5,
                 miss: str = "fallback", fallback_text: str = DEFAULT_FALLBACK,
                 image_max_side: int = 512, verbose: bool = False) -> None:
        if miss not in ("fallback", "error"):
            raise ValueError(f"miss must be 'fallback' or 'error', not {miss!r}")
        super().__init__(address, _Handler)
        self.cache = cache
        self.latency_s = latency_s
        self.miss = miss
        self.fallback_text = fallback_text
        self.image_max_side = image_max_side
        self.verbose = verbose
        self.stats = ReplayStats()

    @property
    def base_url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{host!s}:{port}/v1"

    def lookup(self, body: dict[str, Any]) -> ChatResponse | None:
        for key in request_keys(body, self.image_max_side):
            hit = self.cache.get(key)
            if hit is not None:
                return hit
        return None

    def models(self) -> list[str]:
        rows = self.cache._connection().execute("SELECT DISTINCT model FROM responses").fetchall()
        return sorted(r[0] for r in rows)


class _Handler(BaseHTTPRequestHandler):
    server: ReplayServer

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - the base's name
        if self.server.verbose:
            super().log_message(format, *args)

    def _send(self, status: int, payload: Any) -> None:
        data = json.dumps(payload).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def do_GET(self) -> None:  # noqa: N802 - http.server's name
        path = self.path.rstrip("/")
        if path == "/v1/models":
            self._send(200, {"object": "list", "data": [
                {"id": m, "object": "model", "created": 0, "owned_by": "replay"}
                for m in self.server.models()]})
        elif path == "/stats":
            self._send(200, self.server.stats.to_dict())
        else:
            self._send(404, {"error": {"message": f"no route {self.path}", "type": "not_found"}})

    def do_POST(self) -> None:  # noqa: N802 - http.server's name
        if self.path.rstrip("/") != "/v1/chat/completions":
            self._send(404, {"error": {"message": f"no route {self.path}", "type": "not_found"}})
            return
        stats = self.server.stats
        with stats.lock:
            stats.requests += 1
            stats.in_flight += 1
            stats.max_in_flight = max(stats.max_in_flight, stats.in_flight)
        try:
            start = time.perf_counter()
            length = int(self.headers.get("Content-Length") or 0)
            try:
                body = json.loads(self.rfile.read(length) or b"{}")
                hit = self.server.lookup(body)
            except (ValueError, TypeError, OSError) as error:
                self._send(400, {"error": {"message": f"unreadable request: {error}",
                                           "type": "invalid_request_error"}})
                return
            with stats.lock:
                if hit is None:
                    stats.misses += 1
                else:
                    stats.hits += 1
            time.sleep(max(0.0, self.server.latency_s - (time.perf_counter() - start)))
            model = str(body.get("model", ""))
            if hit is not None:
                raw = hit.raw if isinstance(hit.raw, dict) and hit.raw.get("choices") else None
                self._send(200, raw or completion(hit.text, model, hit))
            elif self.server.miss == "error":
                self._send(404, {"error": {"message": "the replay cache holds no reply to this "
                                           "request", "type": "replay_miss"}})
            else:
                fmt = body.get("response_format") or {}
                schema = fmt.get("json_schema") or fmt.get("schema")
                text = (json.dumps(minimal_instance(schema)) if isinstance(schema, dict)
                        else self.server.fallback_text)
                # Logprobs where asked (each word certain), as the replayed server gives them:
                # the client's capability probe is a miss, and must find them.
                tokens = ([TokenLogprob(w, 0.0, ((w, 0.0),)) for w in text.split()]
                          if body.get("logprobs") else None)
                self._send(200, completion(text, model, ChatResponse(text, model, logprobs=tokens)
                                           if tokens else None))
        finally:
            with stats.lock:
                stats.in_flight -= 1


def serve(cache_path: str | Path | None, host: str = "127.0.0.1", port: int = 0, **options: Any
          ) -> ReplayServer:
    """A ``ReplayServer`` serving on a daemon thread (``port`` 0: a free one); ``shutdown()``."""
    server = ReplayServer((host, port), ResponseCache(cache_path), **options)
    threading.Thread(target=server.serve_forever, name="replay-server", daemon=True).start()
    return server


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=8799)
    parser.add_argument("--latency-s", type=float, default=1.5, help="seconds per reply")
    parser.add_argument("--cache", default=None, help="the response cache's sqlite file "
                        "(default: the project's, cache_dir('responses')/responses.sqlite)")
    parser.add_argument("--miss", choices=("fallback", "error"), default="fallback")
    parser.add_argument("--fallback-text", default=DEFAULT_FALLBACK)
    parser.add_argument("--image-max-side", type=int, default=512,
                        help="the clients' image_max_side (part of the key of image requests)")
    parser.add_argument("--verbose", action="store_true", help="log every request")
    args = parser.parse_args(argv)
    server = ReplayServer((args.host, args.port), ResponseCache(args.cache),
                          latency_s=args.latency_s, miss=args.miss,
                          fallback_text=args.fallback_text, image_max_side=args.image_max_side,
                          verbose=args.verbose)
    print(f"replay server on {server.base_url} (latency {args.latency_s:g} s, cache "
          f"{server.cache.path}, models {', '.join(server.models()) or 'none'})", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        print(json.dumps(server.stats.to_dict()), file=sys.stderr)
        server.server_close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
