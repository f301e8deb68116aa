"""The chat-model contract shared by every back-end: GPT-4o, vLLM, Ollama, llama.cpp, stubs."""

from __future__ import annotations

from dataclasses import dataclass, field
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
    """What a server can do; callers check flags instead of assuming."""

    images: bool = False
    logprobs: bool = False
    json_schema: bool = False  # response_format={"type": "json_schema", ...}
    grammar: bool = False  # llama.cpp GBNF grammars


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


@dataclass
class Usage:
    """Running totals of one client (or one episode): calls, tokens, seconds, dollars."""

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
