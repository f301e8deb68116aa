"""A deterministic ``ChatModel`` for tests: scripted replies, recorded requests, fake logprobs."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import Capabilities, ChatResponse, Message, TokenLogprob, Usage

Script = Sequence[str] | Callable[[list[Message]], str]
LogprobFn = Callable[[str, int], list[TokenLogprob]]


class StubScriptExhausted(RuntimeError):
    """More calls than scripted replies. Deliberately not an ``EfficientEQAError``: code that
    turns model failures into a failed episode must not hide a test that is wrong."""


@dataclass(frozen=True)
class StubRequest:
    """One recorded ``chat`` call."""

    messages: list[Message]
    max_tokens: int
    temperature: float
    logprobs: int | None
    json_schema: dict[str, Any] | None
    seed: int | None


def confident_logprobs(text: str, top: int, p: float = 0.9) -> list[TokenLogprob]:
    """Each whitespace-separated word of ``text`` with probability ``p``; the remaining mass is
    split evenly over ``top - 1`` alternatives named ``<alt1>``, ``<alt2>``, ..."""
    alternatives = max(top - 1, 0)
    rest = math.log((1 - p) / alternatives) if alternatives else -math.inf
    return [TokenLogprob(token=word, logprob=math.log(p),
                         top=((word, math.log(p)),
                              *((f"<alt{i + 1}>", rest) for i in range(alternatives)))[:max(top, 0)])
            for word in text.split()]


class StubChatModel:
    """Replies from ``script``: a list of strings (one per call, in order) or a function of the
    messages. Tokens are whitespace-separated words. ``logprob_fn(text, top)`` makes the logprobs
    returned when a call asks for them and ``capabilities.logprobs`` is set (default:
    :func:`confident_logprobs`). Messages with images need ``capabilities.images``."""

    def __init__(self, script: Script, *, name: str = "stub",
                 capabilities: Capabilities | None = None,
                 logprob_fn: LogprobFn | None = None, finish_reason: str = "stop") -> None:
        """``finish_reason``: what every reply says of its end ("length": cut at max_tokens)."""
        self.name = name
        self.finish_reason = finish_reason
        self.capabilities = capabilities or Capabilities(images=True, logprobs=True, json_schema=True)
        self.usage = Usage()
        self.requests: list[StubRequest] = []
        self._script = script
        self._logprob_fn = logprob_fn or confident_logprobs

    def __repr__(self) -> str:
        return f"StubChatModel(name={self.name!r}, calls={len(self.requests)})"

    def chat(self, messages: list[Message], *, max_tokens: int = 256, temperature: float = 0.0,
             logprobs: int | None = None, json_schema: dict[str, Any] | None = None,
             seed: int | None = None) -> ChatResponse:
        if any(m.images for m in messages) and not self.capabilities.images:
            raise EfficientEQAError(f"model {self.name!r} does not accept images",
                                    fix="use a vision model or set capabilities.images")
        self.requests.append(StubRequest(list(messages), max_tokens, temperature, logprobs,
                                         json_schema, seed))
        text = self._reply(messages)
        response = ChatResponse(
            text=text,
            model=self.name,
            prompt_tokens=sum(len(m.text.split()) for m in messages),
            completion_tokens=len(text.split()),
            logprobs=(self._logprob_fn(text, logprobs)
                      if logprobs is not None and self.capabilities.logprobs else None),
            finish_reason=self.finish_reason,
        )
        self.usage.add(response)
        return response

    def _reply(self, messages: list[Message]) -> str:
        if callable(self._script):
            return self._script(messages)
        call = len(self.requests)
        if call > len(self._script):
            raise StubScriptExhausted(f"stub model {self.name!r} has {len(self._script)} scripted "
                                      f"replies but was called {call} times; add replies to its script")
        return self._script[call - 1]
