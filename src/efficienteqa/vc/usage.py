"""The usage record kept with every VC result: which model, how many tokens, how long."""

from __future__ import annotations

from typing import Any

from efficienteqa.models.base import ChatResponse


def usage_of(resp: ChatResponse) -> dict[str, Any]:
    """Model id, prompt/completion tokens, latency (s) and whether the reply came from the cache;
    missing fields (a minimal stub) read as empty or zero."""
    return {"model": getattr(resp, "model", ""), "prompt_tokens": getattr(resp, "prompt_tokens", 0),
            "completion_tokens": getattr(resp, "completion_tokens", 0),
            "latency_s": getattr(resp, "latency_s", 0.0), "cached": getattr(resp, "cached", False)}
