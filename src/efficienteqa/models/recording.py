"""A ``ChatModel`` wrapper that keeps every exchange, for the episode record and report."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from typing import Any

from efficienteqa.models.base import Capabilities, ChatModel, ChatResponse, Message, Usage


@dataclass(frozen=True)
class Exchange:
    """One call: what was asked (``prompt``: the messages' text; ``images``: how many), what came
    back, and its cost. ``phase`` says what the agent was doing ("step 12", "answer")."""

    index: int
    phase: str
    model: str
    prompt: str
    images: int
    reply: str
    prompt_tokens: int
    completion_tokens: int
    latency_s: float
    cached: bool

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class RecordingChatModel:
    """Forwards to ``inner`` and appends an ``Exchange`` per call. Failed calls are recorded
    with the error as the reply and re-raised."""

    def __init__(self, inner: ChatModel) -> None:
        self.inner = inner
        self.exchanges: list[Exchange] = []
        self.phase = ""

    @property
    def name(self) -> str:
        return self.inner.name

    @property
    def capabilities(self) -> Capabilities:
        return self.inner.capabilities

    @property
    def usage(self) -> Usage:
        return self.inner.usage

    @contextmanager
    def in_phase(self, phase: str) -> Iterator[None]:
        previous, self.phase = self.phase, phase
        try:
            yield
        finally:
            self.phase = previous

    def chat(self, messages: list[Message], **kwargs: Any) -> ChatResponse:
        prompt = "\n\n".join(m.text for m in messages)
        images = sum(len(m.images) for m in messages)
        start = time.perf_counter()
        try:
            response = self.inner.chat(messages, **kwargs)
        except Exception as exc:
            self._add(prompt, images, f"<error: {exc}>", 0, 0, time.perf_counter() - start, False)
            raise
        self._add(prompt, images, response.text or "", response.prompt_tokens,
                  response.completion_tokens, response.latency_s, response.cached)
        return response

    def _add(self, prompt: str, images: int, reply: str, prompt_tokens: int,
             completion_tokens: int, latency_s: float, cached: bool) -> None:
        self.exchanges.append(Exchange(len(self.exchanges), self.phase, self.name, prompt, images,
                                       reply, prompt_tokens, completion_tokens, latency_s, cached))
