"""The chat-model contract shared by every back-end: GPT-4o, vLLM, Ollama, llama.cpp, stubs."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

import numpy as np


@dataclass(frozen=True)
class Message:
    """One chat message. ``images``: RGB uint8 arrays (H, W, 3), sent after the text."""

    role: str  # "system" | "user" | "assistant"
    text: str
    images: tuple[np.ndarray, ...] = ()


@dataclass(frozen=True)
class TokenLogprob:
    """A generated token, its log-probability and the top alternatives (token, logprob)."""

    token: str
    logprob: float
    top: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class Capabilities:
    """What a server can do; callers check flags instead of assuming.

    ``max_images``: the most images one request may carry (None: no known cap).
    ``source``: how the flags were obtained: "declared" (configured, e.g. the local llama.cpp
    server's known ones), "probed" (asked the server this run) or "probe cache" (an earlier run's
    probe of the same base URL and model, ``models/probe.py``). ``probed``: what each probe
    found, e.g. ``{"logprobs": "returned" | "ignored" | "rejected", "images": "5 accepted"}``;
    empty when declared. ``to_dict()`` is the form for a run's record of its back-ends.
    """

    images: bool = False
    logprobs: bool = False
    json_schema: bool = False  # response_format={"type": "json_schema", ...}
    grammar: bool = False  # llama.cpp GBNF grammars
    max_images: int | None = None
    source: str = "declared"
    probed: Mapping[str, str] = field(default_factory=dict, compare=False, hash=False)

    def to_dict(self) -> dict[str, Any]:
        return {"images": self.images, "max_images": self.max_images, "logprobs": self.logprobs,
                "json_schema": self.json_schema, "grammar": self.grammar, "source": self.source,
                "probed": dict(self.probed)}


@dataclass
class ChatResponse:
    text: str
    model: str
    prompt_tokens: int = 0
    completion_tokens: int = 0
    latency_s: float = 0.0
    cached: bool = False
    logprobs: list[TokenLogprob] | None = None
    raw: dict[str, Any] = field(default_factory=dict)
    # "stop", "length" (cut at max_tokens: the reply may be unreadable), ...; None: not given
    # (e.g. a cache entry written before this field existed)
    finish_reason: str | None = None


@dataclass
class Usage:
    """Running totals of one client (or one episode): calls, tokens, seconds, dollars.

    ``cost_usd``: the dollars of the calls that reached the server (cache hits cost 0), at the
    back-end's prices (``models/backends.PRICES``; 0 for unknown and local models).
    ``dataclasses.asdict(usage)`` (or ``to_dict()``) gives every field, ``cost_usd`` included."""

    calls: int = 0
    cached_calls: int = 0
    prompt_tokens: int = 0
    completion_tokens: int = 0
    latency_s: float = 0.0
    cost_usd: float = 0.0

    def add(self, response: ChatResponse, cost_usd: float = 0.0) -> None:
        self.calls += 1
        self.cached_calls += int(response.cached)
        self.prompt_tokens += response.prompt_tokens
        self.completion_tokens += response.completion_tokens
        self.latency_s += response.latency_s
        self.cost_usd += cost_usd

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class ChatModel(Protocol):
    """A chat model. ``logprobs``: number of top alternatives per token (needs the capability);
    ``json_schema``: constrain the reply to this JSON schema where the server supports it.

    ``name``, ``capabilities`` and ``usage`` are read by callers, never assigned: a plain
    attribute or a property serves (wrappers forward them as properties)."""

    @property
    def name(self) -> str: ...

    @property
    def capabilities(self) -> Capabilities: ...

    @property
    def usage(self) -> Usage: ...

    def chat(self, messages: list[Message], *, max_tokens: int = 256, temperature: float = 0.0,
             logprobs: int | None = None, json_schema: dict[str, Any] | None = None,
             seed: int | None = None) -> ChatResponse: ...
