"""OpenAI-compatible chat client (GPT-4o, vLLM, Ollama, the llama.cpp server) on the official
``openai`` SDK.

The SDK retries connection errors, timeouts, 408, 409, 429 and 5xx ``max_retries`` times with
exponential backoff (0.5 s doubling to 8 s, jittered), waiting what ``Retry-After`` asks where
the server sends it; other 4xx fail at once. A 5xx left after the retries is a ``ServerFailed``:
the capability probe reads one to a feature request as "not supported" (once a plain request has
passed). The SDK's typed errors become one-line ``EfficientEQAError``s here. Replies are cached
on disk (``models/cache.py``). The API key is read from the environment variable named in the
config and handed to the SDK only, which sends it in the ``Authorization`` header: it is never
in configs, reprs, logs, errors or the cache.

``openai`` is imported on the first request, so modules that only need ``encode_image`` stay
light.

``probe()`` asks the server what it can do (logprobs: returned, ignored or rejected; JSON
schemas; how many images one request may carry) with a few one-token requests, once per
(base URL, model): the result is kept in ``cache_dir("probes")`` and read back by later runs.
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import logging
import math
import os
import re
import sqlite3
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from PIL import Image

from efficienteqa.cache import cache_path
from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import Capabilities, ChatResponse, Message, TokenLogprob, Usage
from efficienteqa.models.cache import ResponseCache, request_key
from efficienteqa.records import write_json
from efficienteqa.redact import redact_urls

if TYPE_CHECKING:
    import openai

log = logging.getLogger(__name__)

_SERVE_FIX = "start it with `efficienteqa models serve` or check base_url"
IMAGE_FORMATS = ("png", "jpeg")
IMAGE_DETAILS = ("auto", "low", "high")
# The probe: as many top alternatives as the agent asks for (vc.logprobs.TOP_LOGPROBS), and as
# many images as one request of the agent carries at most (the answer's K = 5 frames).
PROBE_TOP_LOGPROBS = 10
PROBE_IMAGES = 5
PROBE_RETRIES = 1
# A call that has waited this long for the server says so, once, on stderr (and goes on
# waiting): a hung server otherwise costs its timeout and retries in silence.
WAIT_NOTICE_S = 15.0
# Sent where no key is configured: the SDK insists on one, and without it would read
# OPENAI_API_KEY from the environment and send the user's OpenAI key to a local server.
_NO_KEY = "no-key"
_WARNED: set[str] = set()


def _warn_once(message: str) -> None:
    """A warning that every client of this process would repeat (a run builds one per
    episode), said once."""
    if message not in _WARNED:
        _WARNED.add(message)
        log.warning(message)


@dataclass(frozen=True)
class ClientConfig:
    """Where the model is and how to talk to it. Prices in USD per 1,000 tokens (0 for local).

    ``api_key_env`` names the environment variable holding the key (None: send no key).
    ``max_retries``: retries after the first try, by the SDK (see the module docstring);
    ``timeout_s``: the limit of each try.
    ``image_format``/``image_max_side``/``image_detail``: how images are sent (``encode_image``;
    ``detail`` goes in ``image_url.detail``, None: not sent, the server's default); all three
    are part of the cache key.
    ``cache_server``: the base URL to key cached replies by (a server named by URL), or None
    (the embedded local model, keyed as before server URLs were keyed; ``models/cache.py``).
    ``unreachable_fix``: what to do when the server cannot be reached (per back-end kind).
    """

    base_url: str = "http://127.0.0.1:8080/v1"
    model: str = "local"
    api_key_env: str | None = None
    timeout_s: float = 60.0
    max_retries: int = 4
    image_max_side: int = 512
    image_format: str = "png"  # "png" | "jpeg"
    image_detail: str | None = None  # "auto" | "low" | "high"; None: not sent
    capabilities: Capabilities = field(default_factory=Capabilities)
    price_prompt_per_1k: float = 0.0
    price_completion_per_1k: float = 0.0
    cache: bool = True
    cache_path: str | None = None  # None: cache_dir("responses")/responses.sqlite
    temperature: float | None = None  # replaces every request's temperature (the paper's T = 1)
    cache_server: str | None = None
    unreachable_fix: str = _SERVE_FIX
    probe_dir: str | None = None  # None: cache_dir("probes")

    def __post_init__(self) -> None:
        if self.image_format not in IMAGE_FORMATS:
            raise EfficientEQAError(f"unknown image format {self.image_format!r}",
                                    fix=f"use one of {', '.join(IMAGE_FORMATS)}")
        if self.image_detail is not None and self.image_detail not in IMAGE_DETAILS:
            raise EfficientEQAError(f"unknown image detail {self.image_detail!r}",
                                    fix=f"use one of {', '.join(IMAGE_DETAILS)}")
        if self.image_max_side < 16:
            raise EfficientEQAError(f"image max side {self.image_max_side} px is too small",
                                    fix="use at least 16 px, e.g. 512")
        if not (self.timeout_s > 0 and math.isfinite(self.timeout_s)):
            raise EfficientEQAError(f"timeout {self.timeout_s} s is not a positive number",
                                    fix="use e.g. --backends.timeout-s 60")
        if self.max_retries < 0:
            raise EfficientEQAError(f"retries {self.max_retries} is negative",
                                    fix="use 0 (one try) or more")

    @property
    def image_encoding(self) -> str:
        """The image encoding in the cache key: ``png@512`` (as before ``detail`` existed),
        ``jpeg@512``, ``jpeg@512/low``."""
        encoding = f"{self.image_format}@{self.image_max_side}"
        return encoding + (f"/{self.image_detail}" if self.image_detail else "")


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


class ServerFailed(EfficientEQAError):
    """The server still answered with a 5xx after its retries (``status``: the HTTP code). Some
    servers answer 500 to a request option they do not know (llama-cpp-python to a JSON-schema
    ``response_format``), so the capability probe reads it as "not supported"."""

    def __init__(self, message: str, status: int, fix: str | None = None) -> None:
        super().__init__(message, fix=fix)
        self.status = status


class OpenAIChatClient:
    """A ``ChatModel`` over ``POST {base_url}/chat/completions``.

    ``json_schema`` is sent as ``response_format={"type": "json_schema", ...}`` when
    ``capabilities.json_schema``; else as llama.cpp's ``{"type": "json_object", "schema": ...}``
    (a server extension, in the SDK's ``extra_body``) when ``capabilities.grammar``; else the
    reply is not constrained (the caller must parse leniently). ``logprobs`` is only sent when
    ``capabilities.logprobs``; otherwise the reply has ``logprobs=None``. ``latency_s`` is the
    wall-clock time of the whole call, retries included.

    A configured key variable that is unset fails here, before any request. The SDK client is
    created on the first request that misses the cache; ``cache`` may be injected.
    """

    def __init__(self, config: ClientConfig, *, cache: ResponseCache | None = None) -> None:
        self.config = config
        self.name = config.model
        self.usage = Usage()
        self._capabilities = config.capabilities
        self._api_key()  # a missing key is a set-up error: say so before anything runs
        self._cache = cache
        self._cache_off = False  # its folder cannot be made: the run goes on without it
        self._sdk: openai.OpenAI | None = None
        self._lock = threading.Lock()

    def __repr__(self) -> str:
        return f"OpenAIChatClient(model={self.name!r}, base_url={redact_urls(self.config.base_url)!r})"

    @property
    def capabilities(self) -> Capabilities:
        return self._capabilities

    @property
    def url(self) -> str:
        """The endpoint as errors and warnings name it (a password in it as ``***``)."""
        return redact_urls(self.config.base_url.rstrip("/") + "/chat/completions")

    @property
    def server(self) -> str | None:
        """The server replies are keyed by (``ClientConfig.cache_server``: the base URL of a
        server named by URL, its password as ``***``; None for the embedded local model), which
        the judge's grades are keyed by too."""
        return self.config.cache_server

    def _notice(self, tries: int) -> threading.Timer:
        """A started timer that says, once ``WAIT_NOTICE_S`` have passed, which server this
        call is waiting on; cancelled when the call ends."""
        said = (f"efficienteqa: still waiting for the model server at {self.url} after "
                f"{WAIT_NOTICE_S:g} s (each try may take {self.config.timeout_s:g} s, {tries} "
                "tries; --backends.timeout-s and --backends.retries set them)")
        timer = threading.Timer(WAIT_NOTICE_S, lambda: print(said, file=sys.stderr, flush=True))
        timer.daemon = True
        timer.start()
        return timer

    def close(self) -> None:
        if self._sdk is not None:
            self._sdk.close()
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
                              image_encoding=self.config.image_encoding,
                              server=self.config.cache_server)
            hit = self._cache_call(cache.get, key)
            if hit is not None:
                with self._lock:
                    self.usage.add(hit, 0.0)
                return hit
        arguments = self.request_arguments(messages, max_tokens=max_tokens, temperature=temperature,
                                           logprobs=logprobs, json_schema=json_schema, seed=seed)
        start = time.perf_counter()
        try:
            data = self._complete(arguments)
        except RequestRejected as error:
            raise self._stale_probe(error) from None
        response = self._parse(data, time.perf_counter() - start)
        if cache is not None and key is not None:
            self._cache_call(cache.put, key, response)
        cost = (response.prompt_tokens * self.config.price_prompt_per_1k
                + response.completion_tokens * self.config.price_completion_per_1k) / 1000.0
        with self._lock:
            self.usage.add(response, cost)
        return response

    def request_arguments(self, messages: list[Message], *, max_tokens: int = 256,
                          temperature: float = 0.0, logprobs: int | None = None,
                          json_schema: dict[str, Any] | None = None,
                          seed: int | None = None) -> dict[str, Any]:
        """The arguments of ``chat.completions.create`` for these (only fields the capabilities
        allow; server extensions in ``extra_body``)."""
        caps = self._capabilities
        arguments: dict[str, Any] = {"model": self.name,
                                     "messages": [self._message(m) for m in messages],
                                     "max_tokens": max_tokens, "temperature": temperature}
        if seed is not None:
            arguments["seed"] = seed
        if logprobs is not None and caps.logprobs:
            arguments["logprobs"] = True
            arguments["top_logprobs"] = logprobs
        if json_schema is not None:
            if caps.json_schema:
                wrapped = json_schema if _is_wrapper(json_schema) else {"name": "reply",
                                                                         "schema": json_schema}
                arguments["response_format"] = {"type": "json_schema", "json_schema": wrapped}
            elif caps.grammar:
                schema = json_schema["schema"] if _is_wrapper(json_schema) else json_schema
                # llama.cpp turns the schema into a grammar; the SDK's types do not know this form
                arguments["extra_body"] = {"response_format": {"type": "json_object", "schema": schema}}
        return arguments

    def probe_capabilities(self, images: bool = False) -> Capabilities:
        """Ask the server what it can do, with one-token requests (not cached, not counted in
        ``usage``), and update and return ``capabilities`` (a flag declared off stays off):

        - logprobs: one request with ``logprobs`` and ``top_logprobs=10``: "returned" (they
          come back), "ignored" (a reply without them) or "rejected" (HTTP 4xx; a plain request
          then must pass, else the server or the model name is wrong and that error is raised);
        - JSON schemas (where declared): a ``response_format`` of type json_schema, accepted
          or rejected;
        - images (only with ``images`` and where declared): 5 tiny images in one request; if
          rejected, the count the server's message names (vLLM: "At most N image(s)"), else 1:
          ``max_images`` is the count accepted (None when 5 pass), ``images`` False when even
          one is rejected.

        A server that cannot be reached fails here, in one line. ``capabilities.probed`` says
        what each probe found; ``source`` becomes "probed".
        """
        found = self._probe_text()
        if images and self._capabilities.images:
            found.update(self._probe_images())
        self._apply_probe(found, "probed")
        return self._capabilities

    def probe(self, images: bool = False, *, use_cache: bool = True) -> Capabilities:
        """``probe_capabilities`` once per (base URL, model): an earlier probe's result, kept in
        ``cache_dir("probes")``, is read back (``source`` "probe cache"); the image probe runs
        only when ``images`` is asked (and declared) and no earlier probe did it."""
        path = self._probe_path()
        stored = _read_json(path) if use_cache else None
        want_images = images and self._capabilities.images
        if stored is not None and (not want_images or "images" in stored):
            self._apply_probe(stored, "probe cache")
            return self._capabilities
        found = stored if stored is not None else self._probe_text()
        if want_images:
            found.update(self._probe_images())
        self._apply_probe(found, "probed")
        record = {"base_url": self.config.base_url.rstrip("/"), "model": self.name, **found,
                  "at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        try:
            write_json(path, record)
        except OSError as error:  # e.g. a read-only cache folder: probed again next time
            _warn_once(f"cannot keep the probe of {self.url} in {path.parent} "
                       f"({error.strerror or error}): each run probes it again (set "
                       "EFFICIENTEQA_CACHE to a writable folder to keep it)")
        return self._capabilities

    def declare(self, capabilities: Capabilities) -> Capabilities:
        """Take ``capabilities`` as the server's, without asking it (``--backends.capabilities FILE``)."""
        self._capabilities = capabilities
        return capabilities

    def forget_probe(self) -> None:
        """Drop this server's kept probe: the next ``probe`` asks the server again."""
        self._probe_path().unlink(missing_ok=True)

    # -- internals --

    def _probe_path(self) -> Path:
        """Where this server's probe is kept; the folder is made only when it is written, so a
        read-only cache costs the keeping, not the run."""
        ident = f"{redact_urls(self.config.base_url.rstrip('/'))}|{self.name}"
        folder = Path(self.config.probe_dir) if self.config.probe_dir else cache_path("probes")
        return folder / f"{hashlib.sha256(ident.encode()).hexdigest()[:24]}.json"

    def _apply_probe(self, found: dict[str, Any], source: str) -> None:
        """The declared capabilities, each flag the server lacks turned off (see ``probe``)."""
        declared = self._capabilities
        notes = {k: str(found[k + "_probe"]) for k in ("logprobs", "json_schema", "images")
                 if k + "_probe" in found}
        self._capabilities = replace(
            declared, logprobs=declared.logprobs and bool(found.get("logprobs")),
            json_schema=declared.json_schema and bool(found.get("json_schema", True)),
            images=declared.images and bool(found.get("images", True)),
            max_images=found.get("max_images") if declared.images else declared.max_images,
            source=source, probed=notes)

    def _probe_text(self) -> dict[str, Any]:
        """Logprobs and JSON schemas (see ``probe_capabilities``), as the kept probe's fields."""
        found: dict[str, Any] = {}
        plain = {"model": self.name, "messages": [{"role": "user", "content": "Say yes."}],
                 "max_tokens": 1, "temperature": 0.0}
        try:
            data = self._complete({**plain, "logprobs": True,
                                   "top_logprobs": PROBE_TOP_LOGPROBS}, probe=True)
            choices = data.get("choices") or [{}]
            found["logprobs"] = bool(parse_logprobs(choices[0]))
            found["logprobs_probe"] = "returned" if found["logprobs"] else "ignored"
        except (RequestRejected, ServerFailed) as error:
            if error.status in (401, 403, 404):
                raise
            self._complete(plain, probe=True)  # the server answers a plain request, or this raises
            found["logprobs"] = False
            found["logprobs_probe"] = _refusal(error)
        if self._capabilities.json_schema:
            schema = {"name": "probe", "schema": {"type": "object", "properties": {
                "ok": {"type": "boolean"}}, "required": ["ok"]}}
            try:
                self._complete({**plain, "max_tokens": 8, "response_format": {
                    "type": "json_schema", "json_schema": schema}}, probe=True)
                found["json_schema"], found["json_schema_probe"] = True, "accepted"
            except (RequestRejected, ServerFailed) as error:
                if isinstance(error, ServerFailed):  # a failing server, or one failing on this?
                    self._complete(plain, probe=True)
                found["json_schema"] = False
                found["json_schema_probe"] = _refusal(error)
        return found

    def _probe_images(self) -> dict[str, Any]:
        """How many images one request may carry (see ``probe_capabilities``)."""
        tiny = np.zeros((32, 32, 3), np.uint8)
        tiny[8:24, 8:24] = (200, 60, 40)

        def request(n: int) -> dict[str, Any]:
            message = self._message(Message("user", "How many images are there?", (tiny,) * n))
            return {"model": self.name, "messages": [message], "max_tokens": 1,
                    "temperature": 0.0}

        try:
            self._complete(request(PROBE_IMAGES), probe=True)
            return {"images": True, "max_images": None,
                    "images_probe": f"{PROBE_IMAGES} accepted"}
        except (RequestRejected, ServerFailed) as error:
            said = re.search(r"at most (\d+) image", str(error), re.IGNORECASE)
            fewer = int(said.group(1)) if said else 1
            fewer = fewer if 1 <= fewer < PROBE_IMAGES else 1
            try:
                self._complete(request(fewer), probe=True)
            except (RequestRejected, ServerFailed) as again:
                return {"images": False, "max_images": None,
                        "images_probe": f"rejected: {_one_line(str(again), 200)}"}
            return {"images": True, "max_images": fewer,
                    "images_probe": f"{fewer} accepted, {PROBE_IMAGES} rejected: HTTP {error.status}"}

    def _stale_probe(self, error: RequestRejected) -> RequestRejected:
        """A request rejected while the capabilities came from an earlier run's probe: the
        server may have changed since, so that probe is dropped (the next run asks again)."""
        if self._capabilities.source != "probe cache" or error.status != 400:
            return error
        try:
            self.forget_probe()
        except OSError:
            return error
        return RequestRejected(
            f"{error.args[0]} (the server's capabilities came from an earlier run's probe, "
            "now dropped)", error.status,
            fix="run again: the server is probed afresh" + (f"; {error.fix}" if error.fix else ""))

    def _api_key(self) -> str:
        env = self.config.api_key_env
        if env is None:
            return _NO_KEY
        key = os.environ.get(env)
        if not key:
            raise EfficientEQAError(f"environment variable {env} is not set",
                                    fix=f"export {env}=..., or --backends.api-key-env none for a server that "
                                        "needs no key")
        return key

    def _client(self) -> openai.OpenAI:
        with self._lock:
            if self._sdk is None:
                import openai

                self._sdk = openai.OpenAI(api_key=self._api_key(), base_url=self.config.base_url,
                                          timeout=self.config.timeout_s,
                                          max_retries=self.config.max_retries)
            return self._sdk

    def _response_cache(self) -> ResponseCache | None:
        """The response cache, or None: off by configuration, or its folder cannot be made
        (a read-only cache folder: the run goes on without it, saying so once)."""
        if not self.config.cache or self._cache_off:
            return None
        if self._cache is None:
            try:
                self._cache = ResponseCache(self.config.cache_path or ResponseCache.default_path())
            except EfficientEQAError as error:
                _warn_once(f"response cache off: {error}")
                self._cache_off = True
        return self._cache

    def _cache_call(self, method: Callable[..., Any], *args: Any) -> Any:
        """A broken or locked cache, or one that cannot be written, costs a model call, not the
        episode."""
        try:
            return method(*args)
        except (sqlite3.Error, OSError) as error:
            log.warning("response cache unavailable (%s); calling the model", _one_line(str(error)))
            return None

    def _message(self, message: Message) -> dict[str, Any]:
        if not message.images:
            return {"role": message.role, "content": message.text}
        if not self._capabilities.images:
            raise EfficientEQAError(f"model {self.name!r} does not accept images",
                                    fix="use a vision model or set capabilities.images")
        parts: list[dict[str, Any]] = [{"type": "text", "text": message.text}]
        for image in message.images:
            url: dict[str, Any] = {"url": encode_image(image, self.config.image_max_side,
                                                       self.config.image_format)}
            if self.config.image_detail is not None:
                url["detail"] = self.config.image_detail
            parts.append({"type": "image_url", "image_url": url})
        return {"role": message.role, "content": parts}

    def _redact(self, text: str) -> str:
        key = os.environ.get(self.config.api_key_env or "") if self.config.api_key_env else None
        return text.replace(key, "***") if key else text

    def _complete(self, arguments: dict[str, Any], *, probe: bool = False) -> dict[str, Any]:
        """One ``chat.completions.create`` (the SDK retries) as the reply's JSON dict. A probe
        retries at most once (``PROBE_RETRIES``): a dead or hung server fails the run's start
        in one try's time or two, not ``max_retries + 1``."""
        import openai
        from openai.types.chat import ChatCompletion

        client = self._client()
        retries = self.config.max_retries
        if probe and retries > PROBE_RETRIES:
            client, retries = client.with_options(max_retries=PROBE_RETRIES), PROBE_RETRIES
        notice = self._notice(retries + 1)
        try:
            raw = client.chat.completions.with_raw_response.create(**arguments)
        except openai.OpenAIError as error:
            raise self._error(error) from None  # the SDK's chain repeats the reply, key included
        finally:
            notice.cancel()
        try:
            reply = raw.parse()
        except ValueError:  # labelled JSON but not JSON (JSONDecodeError), or not UTF-8 text:
            raise self._unreadable(raw.http_response.content) from None  # a proxy, a bad server
        if not isinstance(reply, ChatCompletion):  # the SDK hands back a body it cannot decode
            raise EfficientEQAError(f"model server at {self.url} sent a reply that is not JSON: "
                                    f"{self._redact(_one_line(str(reply), 120))}", fix="check base_url")
        return reply.to_dict(mode="json")

    def _unreadable(self, body: bytes) -> EfficientEQAError:
        """A 2xx body that is not JSON, in one line saying what came instead: the SDK raises
        ``JSONDecodeError`` from its own parser for a body labelled JSON (a login page from a
        proxy, an empty body, bytes it decodes as UTF-16), with the body out of reach."""
        where, fix = f"model server at {self.url}", "check base_url and the server's log"
        if not body.strip():
            return EfficientEQAError(f"{where} sent an empty reply", fix=fix)
        try:
            text = body.decode("utf-8")
        except UnicodeDecodeError as error:
            return EfficientEQAError(f"{where} sent a reply that is not UTF-8 (byte {error.start}):"
                                     f" {body[:24]!r}", fix=fix)
        return EfficientEQAError(f"{where} sent a reply that is not JSON: "
                                 f"{self._redact(_one_line(text, 120))}", fix=fix)

    def _error(self, error: openai.OpenAIError) -> EfficientEQAError:
        """The SDK's error as one line naming the server, the tries and what to do."""
        import openai

        request = getattr(error, "request", None)
        retries = request.headers.get("x-stainless-retry-count") if request is not None else None
        tries = int(retries) + 1 if retries and retries.isdigit() else self.config.max_retries + 1
        where = f"model server at {self.url}"
        if isinstance(error, openai.APITimeoutError):
            return EfficientEQAError(f"{where} did not answer within {self.config.timeout_s:g} s "
                                     f"({tries} tries)",
                                     fix="raise --backends.timeout-s (each try's limit) or lower "
                                         "--backends.retries, or check that the server is not "
                                         "stuck")
        if isinstance(error, openai.APIConnectionError):
            cause = error.__cause__ or error
            detail = self._redact(_one_line(f"{type(cause).__name__}: {cause}", 200))
            return EfficientEQAError(f"{where} unreachable after {tries} tries: {detail}",
                                     fix=self.config.unreachable_fix)
        if isinstance(error, openai.APIStatusError):
            status = error.status_code
            detail = self._redact(_one_line(_error_text(error), 200))
            if status >= 500:  # the SDK retried these
                return ServerFailed(f"{where} still answered HTTP {status} after {tries} tries: "
                                    f"{detail}", status, fix=self._fix_for(status))
            if status in (408, 409, 429):  # the SDK retried these too
                return EfficientEQAError(f"{where} still answered HTTP {status} after {tries} tries: "
                                         f"{detail}", fix=self._fix_for(status))
            return RequestRejected(f"{where} rejected the request: HTTP {status} {detail}", status,
                                   fix=self._fix_for(status))
        detail = self._redact(_one_line(str(error), 200))
        return EfficientEQAError(f"{where}: {type(error).__name__}: {detail}",
                                 fix="check base_url and the model name")

    def _fix_for(self, status: int) -> str:
        if status in (401, 403):
            if self.config.api_key_env is None:
                return "no key was sent: name the variable holding this server's key with " \
                       "--backends.api-key-env NAME"
            return f"check the API key in ${self.config.api_key_env} (--backends.api-key-env names another)"
        if status == 404:
            return "check base_url (it usually ends in /v1) and the model name"
        if status == 429:
            return "wait, or send fewer requests at once (fewer workers)"
        if status >= 500:
            return "the server failed; see its log, or retry later"
        return "check the model name and the request parameters the server supports"

    def _parse(self, data: dict[str, Any], latency_s: float) -> ChatResponse:
        choices = data.get("choices") or []
        if not choices or not isinstance(choices[0], dict):
            raise EfficientEQAError(f"model server at {self.url} sent no choices: "
                                    f"{self._redact(_one_line(str(data), 120))}",
                                    fix="check base_url and model")
        choice = choices[0]
        usage = data.get("usage") or {}
        finish = choice.get("finish_reason")
        return ChatResponse(
            text=(choice.get("message") or {}).get("content") or "",
            model=data.get("model") or self.name,
            prompt_tokens=int(usage.get("prompt_tokens") or 0),
            completion_tokens=int(usage.get("completion_tokens") or 0),
            latency_s=latency_s,
            logprobs=parse_logprobs(choice),
            raw=data,
            finish_reason=finish if isinstance(finish, str) else None,
        )


def _refusal(error: RequestRejected | ServerFailed) -> str:
    """What a feature probe's refusal says in ``capabilities.probed``."""
    if isinstance(error, ServerFailed):
        return f"failed: HTTP {error.status}, read as not supported"
    return f"rejected: HTTP {error.status}"


def _read_json(path: Path) -> dict[str, Any] | None:
    """A kept probe, or None when absent or unreadable (it is then probed again)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or "logprobs" not in data:
        return None
    return data


def _error_text(error: openai.APIStatusError) -> str:
    """What the server said: the ``error.message`` of an OpenAI-style body, else its text."""
    body = error.body
    if isinstance(body, dict):
        inner = body.get("error", body)
        message = inner.get("message") if isinstance(inner, dict) else inner
        if isinstance(message, str) and message:
            return message
    try:
        return error.response.text
    except Exception:  # a streamed body that was never read
        return error.message


def _is_wrapper(schema: dict[str, Any]) -> bool:
    """OpenAI's ``{"name", "schema", "strict"?}`` wrapper rather than a bare JSON schema."""
    return "schema" in schema and "name" in schema and set(schema) <= {
        "name", "schema", "strict", "description"}
