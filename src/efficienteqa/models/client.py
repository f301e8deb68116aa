"""OpenAI-compatible chat client (GPT-4o, vLLM, Ollama, the llama.cpp server) on the official
``openai`` SDK.

The SDK retries connection errors, timeouts, 408, 409, 429 and 5xx ``max_retries`` times with
exponential backoff (0.5 s doubling to 8 s, jittered), waiting what ``Retry-After`` asks where
the server sends it; other 4xx fail at once. A 5xx left after the retries is a ``ServerFailed``:
the capability probe reads one to a feature request as "not supported" (once a plain request has
passed). The SDK's typed errors become one-line ``EfficientEQAError``s (``client_errors``). Replies are cached
on disk (``models/cache.py``). The API key is read from the environment variable named in the
config and handed to the SDK only, which sends it in the ``Authorization`` header: it is never
in configs, reprs, logs, errors or the cache.

``openai`` is imported on the first request. The client is built from: ``client_config``
(``ClientConfig``), ``images`` (``encode_image``), ``wire`` (the request's arguments and the
reply's JSON), ``client_errors`` (the one-line errors) and ``probe`` (what the server can do).

``probe()`` asks the server what it can do (logprobs: returned, ignored or rejected; JSON
schemas; how many images one request may carry) with a few one-token requests, once per
(base URL, model): the result is kept in ``cache_dir("probes")`` and read back by later runs.
"""

from __future__ import annotations

import logging
import os
import sqlite3
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import Capabilities, ChatResponse, Message, Usage
from efficienteqa.models.cache import ResponseCache, request_key
from efficienteqa.models.client_config import ClientConfig
from efficienteqa.models.client_errors import (
    RequestRejected,
    one_line,
    redact_key,
    sdk_error,
    unreadable,
)
from efficienteqa.models.probe import (
    PROBE_RETRIES,
    applied,
    probe_images,
    probe_path,
    probe_text,
    read_probe,
)
from efficienteqa.models.wire import chat_message, chat_response, request_arguments
from efficienteqa.records import write_json
from efficienteqa.redact import redact_urls

if TYPE_CHECKING:
    import openai

log = logging.getLogger(__name__)

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
        """The arguments of ``chat.completions.create`` for these (``wire.request_arguments``)."""
        return request_arguments(messages, self.name, self._capabilities, self.config,
                                 max_tokens=max_tokens, temperature=temperature,
                                 logprobs=logprobs, json_schema=json_schema, seed=seed)

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
        stored = read_probe(path) if use_cache else None
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
        return probe_path(self.config, self.name)

    def _apply_probe(self, found: dict[str, Any], source: str) -> None:
        self._capabilities = applied(self._capabilities, found, source)

    def _probe_complete(self, arguments: dict[str, Any]) -> dict[str, Any]:
        return self._complete(arguments, probe=True)

    def _probe_text(self) -> dict[str, Any]:
        return probe_text(self._probe_complete, self.name, self._capabilities.json_schema)

    def _probe_images(self) -> dict[str, Any]:
        return probe_images(self._probe_complete, self._message, self.name)

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
            log.warning("response cache unavailable (%s); calling the model", one_line(str(error)))
            return None

    def _message(self, message: Message) -> dict[str, Any]:
        return chat_message(message, self.name, self._capabilities, self.config)

    def _redact(self, text: str) -> str:
        return redact_key(text, self.config)

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
            # the SDK's chain repeats the reply, key included
            raise sdk_error(error, self.url, self.config) from None
        finally:
            notice.cancel()
        try:
            reply = raw.parse()
        except ValueError:  # labelled JSON but not JSON (JSONDecodeError), or not UTF-8 text:
            # a proxy, a bad server
            raise unreadable(raw.http_response.content, self.url, self.config) from None
        if not isinstance(reply, ChatCompletion):  # the SDK hands back a body it cannot decode
            raise EfficientEQAError(f"model server at {self.url} sent a reply that is not JSON: "
                                    f"{self._redact(one_line(str(reply), 120))}", fix="check base_url")
        return reply.to_dict(mode="json")

    def _parse(self, data: dict[str, Any], latency_s: float) -> ChatResponse:
        return chat_response(data, latency_s, self.name, self.url, self.config)
