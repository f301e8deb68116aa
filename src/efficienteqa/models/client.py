"""OpenAI-compatible chat client (GPT-4o, vLLM, Ollama, the llama.cpp server) over httpx.

Retries connection errors, timeouts, 429 and 5xx with seeded exponential backoff (``Retry-After``
respected); other 4xx fail at once. Replies are cached on disk (``models/cache.py``). The API key
is read from the environment variable named in the config at request time and only ever put in
the ``Authorization`` header: never in configs, reprs, logs, errors or the cache.
"""

from __future__ import annotations

import base64
import email.utils
import io
import logging
import math
import os
import random
import sqlite3
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import httpx
import numpy as np
from PIL import Image

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import Capabilities, ChatResponse, Message, TokenLogprob, Usage
from efficienteqa.models.cache import ResponseCache, request_key

log = logging.getLogger(__name__)

_RETRY_STATUS = frozenset({408, 409, 425, 429}) | frozenset(range(500, 600))
_SERVE_FIX = "start it with `efficienteqa models serve` or check base_url"


@dataclass(frozen=True)
class ClientConfig:
    """Where the model is and how to talk to it. Prices in USD per 1,000 tokens (0 for local).

    ``api_key_env`` names the environment variable holding the key (None: send no key).
    ``max_retries``: retries after the first try. Backoff before retry ``i`` (0-based) is
    ``min(backoff_max_s, backoff_base_s * 2**i)`` scaled by a seeded jitter in [0.5, 1].
    """

    base_url: str = "http://127.0.0.1:8080/v1"
    model: str = "local"
    api_key_env: str | None = None
    timeout_s: float = 60.0
    max_retries: int = 4
    backoff_base_s: float = 0.5
    backoff_max_s: float = 30.0
    backoff_seed: int = 0
    image_max_side: int = 512
    image_format: str = "png"  # "png" | "jpeg"
    capabilities: Capabilities = field(default_factory=Capabilities)
    price_prompt_per_1k: float = 0.0
    price_completion_per_1k: float = 0.0
    cache: bool = True
    cache_path: str | None = None  # None: cache_dir("responses")/responses.sqlite
    temperature: float | None = None  # replaces every request's temperature (the paper's T = 1)


def encode_image(image: np.ndarray, max_side: int = 512, fmt: str = "png") -> str:
    """A ``data:`` URL of an RGB uint8 (H, W, 3) image, longer side shrunk to ``max_side`` px."""
    array = np.asarray(image)
    if array.ndim not in (2, 3) or array.size == 0:
        raise EfficientEQAError(f"image must be an (H, W, 3) array, got shape {array.shape}")
    if array.dtype != np.uint8:
        array = np.clip(array, 0, 255).astype(np.uint8)
    pil = Image.fromarray(array)
    if max(pil.size) > max_side:
        scale = max_side / max(pil.size)
        size = (max(1, round(pil.width * scale)), max(1, round(pil.height * scale)))
        pil = pil.resize(size, Image.Resampling.LANCZOS)
    buffer = io.BytesIO()
    if fmt == "jpeg":
        pil.convert("RGB").save(buffer, format="JPEG", quality=90)
    else:
        pil.save(buffer, format="PNG")
    return f"data:image/{fmt};base64,{base64.b64encode(buffer.getvalue()).decode()}"


def _one_line(text: str, limit: int = 300) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _retry_after_s(response: httpx.Response) -> float | None:
    value = response.headers.get("retry-after")
    if not value:
        return None
    try:
        return max(0.0, float(value))
    except ValueError:
        pass
    try:  # an HTTP date
        return max(0.0, email.utils.parsedate_to_datetime(value).timestamp() - time.time())
    except (TypeError, ValueError):
        return None


def parse_logprobs(choice: dict[str, Any]) -> list[TokenLogprob] | None:
    """Chat-style (``content: [{token, logprob, top_logprobs}]``) or completion-style
    (``tokens``, ``token_logprobs``, ``top_logprobs: [{token: logprob}]``) logprobs."""
    data = choice.get("logprobs")
    if not data:
        return None
    if isinstance(data.get("content"), list):
        return [TokenLogprob(token=t.get("token", ""), logprob=float(t.get("logprob", -math.inf)),
                             top=tuple((a.get("token", ""), float(a.get("logprob", -math.inf)))
                                       for a in t.get("top_logprobs") or ()))
                for t in data["content"]]
    if isinstance(data.get("tokens"), list):
        tops = data.get("top_logprobs") or [None] * len(data["tokens"])
        return [TokenLogprob(token=t, logprob=float(lp if lp is not None else -math.inf),
                             top=tuple((a, float(b)) for a, b in (top or {}).items()))
                for t, lp, top in zip(data["tokens"], data.get("token_logprobs") or [], tops)]
    return None


class RequestRejected(EfficientEQAError):
    """The server answered with a 4xx that retrying will not fix (``status``: the HTTP code)."""

    def __init__(self, message: str, status: int, fix: str | None = None) -> None:
        super().__init__(message, fix=fix)
        self.status = status


class OpenAIChatClient:
    """A ``ChatModel`` over ``POST {base_url}/chat/completions``.

    ``json_schema`` is sent as ``response_format={"type": "json_schema", ...}`` when
    ``capabilities.json_schema``; else as llama.cpp's ``{"type": "json_object", "schema": ...}``
    when ``capabilities.grammar``; else the reply is not constrained (the caller must parse
    leniently). ``logprobs`` is only sent when ``capabilities.logprobs``; otherwise the reply has
    ``logprobs=None``. ``latency_s`` is the wall-clock time of the whole call, retries included.

    ``http`` and ``cache`` may be injected; otherwise they are created on the first call.
    """

    def __init__(self, config: ClientConfig, *, http: httpx.Client | None = None,
                 cache: ResponseCache | None = None,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.config = config
        self.name = config.model
        self.usage = Usage()
        self._capabilities = config.capabilities
        self._http = http
        self._cache = cache
        self._sleep = sleep
        self._rng = random.Random(config.backoff_seed)
        self._lock = threading.Lock()

    def __repr__(self) -> str:
        return f"OpenAIChatClient(model={self.name!r}, base_url={self.config.base_url!r})"

    @property
    def capabilities(self) -> Capabilities:
        return self._capabilities

    @property
    def url(self) -> str:
        return self.config.base_url.rstrip("/") + "/chat/completions"

    def close(self) -> None:
        if self._http is not None:
            self._http.close()
        if self._cache is not None:
            self._cache.close()

    def __enter__(self) -> OpenAIChatClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def chat(self, messages: list[Message], *, max_tokens: int = 256, temperature: float = 0.0,
             logprobs: int | None = None, json_schema: dict[str, Any] | None = None,
             seed: int | None = None) -> ChatResponse:
        if self.config.temperature is not None:
            temperature = self.config.temperature
        cache = self._response_cache()
        key = None
        if cache is not None:
            key = request_key(self.name, messages, max_tokens=max_tokens, temperature=temperature,
                              logprobs=logprobs, json_schema=json_schema, seed=seed,
                              image_encoding=f"{self.config.image_format}@{self.config.image_max_side}")
            hit = self._cache_call(cache.get, key)
            if hit is not None:
                with self._lock:
                    self.usage.add(hit, 0.0)
                return hit
        body = self.request_body(messages, max_tokens=max_tokens, temperature=temperature,
                                 logprobs=logprobs, json_schema=json_schema, seed=seed)
        start = time.perf_counter()
        data = self._post(body)
        response = self._parse(data, time.perf_counter() - start)
        if cache is not None and key is not None:
            self._cache_call(cache.put, key, response)
        cost = (response.prompt_tokens * self.config.price_prompt_per_1k
                + response.completion_tokens * self.config.price_completion_per_1k) / 1000.0
        with self._lock:
            self.usage.add(response, cost)
        return response

    def request_body(self, messages: list[Message], *, max_tokens: int = 256,
                     temperature: float = 0.0, logprobs: int | None = None,
                     json_schema: dict[str, Any] | None = None,
                     seed: int | None = None) -> dict[str, Any]:
        """The JSON body sent for these arguments (only fields the capabilities allow)."""
        caps = self._capabilities
        body: dict[str, Any] = {"model": self.name, "messages": [self._message(m) for m in messages],
                                "max_tokens": max_tokens, "temperature": temperature}
        if seed is not None:
            body["seed"] = seed
        if logprobs is not None and caps.logprobs:
            body["logprobs"] = True
            body["top_logprobs"] = logprobs
        if json_schema is not None:
            if caps.json_schema:
                wrapped = json_schema if _is_wrapper(json_schema) else {"name": "reply",
                                                                         "schema": json_schema}
                body["response_format"] = {"type": "json_schema", "json_schema": wrapped}
            elif caps.grammar:
                schema = json_schema["schema"] if _is_wrapper(json_schema) else json_schema
                body["response_format"] = {"type": "json_object", "schema": schema}
        return body

    def probe_capabilities(self) -> Capabilities:
        """Ask for one token with ``top_logprobs=1``; logprobs are supported if they come back.

        Updates and returns ``capabilities`` (other flags stay as declared). Not cached.
        """
        body = {"model": self.name, "messages": [{"role": "user", "content": "Say yes."}],
                "max_tokens": 1, "temperature": 0.0, "logprobs": True, "top_logprobs": 1}
        try:
            data = self._post(body)
            choices = data.get("choices") or [{}]
            supported = bool(parse_logprobs(choices[0]))
        except RequestRejected:
            supported = False
        self._capabilities = replace(self._capabilities, logprobs=supported)
        return self._capabilities

    # -- internals --

    def _response_cache(self) -> ResponseCache | None:
        if not self.config.cache:
            return None
        if self._cache is None:
            self._cache = ResponseCache(self.config.cache_path)
        return self._cache

    def _cache_call(self, method: Callable[..., Any], *args: Any) -> Any:
        """A broken or locked cache costs a model call, not the episode."""
        try:
            return method(*args)
        except sqlite3.Error as error:
            log.warning("response cache unavailable (%s); calling the model", _one_line(str(error)))
            return None

    def _message(self, message: Message) -> dict[str, Any]:
        if not message.images:
            return {"role": message.role, "content": message.text}
        if not self._capabilities.images:
            raise EfficientEQAError(f"model {self.name!r} does not accept images",
                                    fix="use a vision model or set capabilities.images")
        parts: list[dict[str, Any]] = [{"type": "text", "text": message.text}]
        parts += [{"type": "image_url", "image_url": {"url": encode_image(
            image, self.config.image_max_side, self.config.image_format)}} for image in message.images]
        return {"role": message.role, "content": parts}

    def _headers(self) -> dict[str, str]:
        env = self.config.api_key_env
        if env is None:
            return {}
        key = os.environ.get(env)
        if not key:
            raise EfficientEQAError(f"environment variable {env} is not set",
                                    fix=f"export {env}=... or set api_key_env to None for a local server")
        return {"Authorization": f"Bearer {key}"}

    def _redact(self, text: str) -> str:
        key = os.environ.get(self.config.api_key_env or "") if self.config.api_key_env else None
        return text.replace(key, "***") if key else text

    def _backoff_s(self, retry: int) -> float:
        with self._lock:
            jitter = 0.5 + 0.5 * self._rng.random()
        return min(self.config.backoff_max_s, self.config.backoff_base_s * 2**retry) * jitter

    def _post(self, body: dict[str, Any]) -> dict[str, Any]:
        if self._http is None:
            self._http = httpx.Client(timeout=self.config.timeout_s)
        headers = self._headers()
        tries = self.config.max_retries + 1
        last = ""
        for attempt in range(tries):
            wait: float | None = None
            try:
                reply = self._http.post(self.url, json=body, headers=headers,
                                        timeout=self.config.timeout_s)
            except httpx.TransportError as error:  # connection refused, timeouts, resets
                last = f"{type(error).__name__}: {error}"
            else:
                if reply.status_code < 400:
                    try:
                        return reply.json()
                    except ValueError as error:
                        raise EfficientEQAError(
                            f"model server at {self.url} sent a reply that is not JSON: "
                            f"{_one_line(reply.text, 120)}", fix="check base_url") from error
                detail = self._redact(_one_line(reply.text, 200))
                if reply.status_code not in _RETRY_STATUS:
                    raise RequestRejected(
                        f"model server at {self.url} rejected the request: HTTP {reply.status_code} "
                        f"{detail}", reply.status_code, fix=self._fix_for(reply.status_code))
                last = f"HTTP {reply.status_code} {detail}"
                wait = _retry_after_s(reply)
            if attempt + 1 < tries:
                delay = min(wait, self.config.backoff_max_s) if wait is not None else self._backoff_s(attempt)
                log.warning("model server at %s: %s; retry %d/%d in %.1f s", self.url,
                            self._redact(_one_line(last, 200)), attempt + 1, tries - 1, delay)
                self._sleep(delay)
        raise EfficientEQAError(
            f"model server at {self.url} unreachable after {tries} tries: "
            f"{self._redact(_one_line(last, 200))}", fix=_SERVE_FIX)

    def _fix_for(self, status: int) -> str:
        if status in (401, 403):
            return f"check the API key in ${self.config.api_key_env}"
        if status == 404:
            return "check base_url (it usually ends in /v1) and the model name"
        return "check the model name and the request parameters the server supports"

    def _parse(self, data: dict[str, Any], latency_s: float) -> ChatResponse:
        choices = data.get("choices") or []
        if not choices or not isinstance(choices[0], dict):
            raise EfficientEQAError(f"model server at {self.url} sent no choices: "
                                    f"{_one_line(str(data), 120)}", fix="check base_url and model")
        choice = choices[0]
        usage = data.get("usage") or {}
        return ChatResponse(
            text=(choice.get("message") or {}).get("content") or "",
            model=data.get("model") or self.name,
            prompt_tokens=int(usage.get("prompt_tokens") or 0),
            completion_tokens=int(usage.get("completion_tokens") or 0),
            latency_s=latency_s,
            logprobs=parse_logprobs(choice),
            raw=data,
        )


def _is_wrapper(schema: dict[str, Any]) -> bool:
    """OpenAI's ``{"name", "schema", "strict"?}`` wrapper rather than a bare JSON schema."""
    return "schema" in schema and "name" in schema and set(schema) <= {
        "name", "schema", "strict", "description"}
