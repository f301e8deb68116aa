"""A ``ChatModel`` wrapper that keeps every exchange, for the episode record and report.

Which images went to a call is kept as references, not pixels: ``image_digest`` of each image
as sent (a short hash of its shape and bytes). The episode's frames are kept by the report
(``report.frames.FrameCollector``, as plain and lettered thumbnails with the same digests), so
``report.html`` shows each call's images and ``episode.json`` stays small.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from efficienteqa.models.base import Capabilities, ChatModel, ChatResponse, Message, Usage


@dataclass(frozen=True)
class Exchange:
    """One call: what was asked (``prompt``: the messages' text; ``images``: how many;
    ``image_refs``: their ``image_digest``, in the order sent), what came back, and its cost.
    ``phase`` says what the agent was doing ("step 12", "answer")."""

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
    image_refs: tuple[str, ...] = ()
    cost_usd: float = 0.0  # at the back-end's prices (0 for local and unknown models, and hits)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def image_digest(image: np.ndarray) -> str:
    """A 12-hex-digit reference to an image: the same pixels (shape, dtype and bytes) give the
    same reference, so a call's images can be matched with the frames the report keeps."""
    array = np.ascontiguousarray(image)
    h = hashlib.blake2b(digest_size=6)
    h.update(f"{array.shape}{array.dtype}".encode())
    h.update(array.data)
    return h.hexdigest()


def image_refs(messages: Sequence[Message]) -> tuple[str, ...]:
    return tuple(image_digest(np.asarray(im)) for m in messages for im in m.images)


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
        refs = image_refs(messages)
        start = time.perf_counter()
        spent = self.inner.usage.cost_usd
        try:
            response = self.inner.chat(messages, **kwargs)
        except Exception as exc:
            self._add(prompt, refs, f"<error: {exc}>", 0, 0, time.perf_counter() - start, False)
            raise
        self._add(prompt, refs, response.text or "", response.prompt_tokens,
                  response.completion_tokens, response.latency_s, response.cached,
                  self.inner.usage.cost_usd - spent)
        return response

    def _add(self, prompt: str, refs: tuple[str, ...], reply: str, prompt_tokens: int,
             completion_tokens: int, latency_s: float, cached: bool, cost_usd: float = 0.0) -> None:
        self.exchanges.append(Exchange(len(self.exchanges), self.phase, self.name, prompt,
                                       len(refs), reply, prompt_tokens, completion_tokens,
                                       latency_s, cached, refs, round(cost_usd, 8)))
