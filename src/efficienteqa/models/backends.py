"""Chat back-ends by configuration: the embedded local model and any OpenAI-compatible server
share one client (``OpenAIChatClient``); only the URL, the model and the capabilities differ."""

from __future__ import annotations

from dataclasses import dataclass

from efficienteqa.models.base import Capabilities, ChatModel
from efficienteqa.models.client import ClientConfig, OpenAIChatClient
from efficienteqa.registry import Registry

OPENAI_URL = "https://api.openai.com/v1"
# USD per 1k tokens (prompt, completion); unknown models cost 0 in the accounting.
PRICES = {"gpt-4o": (0.0025, 0.01), "gpt-4o-2024-05-13": (0.005, 0.015),
          "gpt-4o-mini": (0.00015, 0.0006)}


@dataclass(frozen=True)
class ChatBackend:
    """``kind``: "local" (llama.cpp on loopback, started on demand; text only), "openai" (any
    OpenAI-compatible server: GPT-4o, vLLM, Ollama; ``images`` for VLMs). Tests build
    ``StubChatModel`` directly."""

    kind: str = "local"
    model: str = "qwen2.5-coder-1.5b"
    base_url: str | None = None
    api_key_env: str | None = None
    images: bool = False
    logprobs: bool = True
    cache: bool = True
    timeout_s: float = 120.0
    temperature: float | None = None  # None: each call's own (0 for every call of the agent)


def _local(backend: ChatBackend) -> ChatModel:
    from efficienteqa.models.local import ensure_server

    base_url = backend.base_url or ensure_server(backend.model)
    capabilities = Capabilities(images=False, logprobs=backend.logprobs, grammar=True)
    return OpenAIChatClient(ClientConfig(
        base_url=base_url, model=backend.model, capabilities=capabilities,
        cache=backend.cache, timeout_s=backend.timeout_s, temperature=backend.temperature))


def _openai(backend: ChatBackend) -> ChatModel:
    prompt_price, completion_price = PRICES.get(backend.model, (0.0, 0.0))
    return OpenAIChatClient(ClientConfig(
        base_url=backend.base_url or OPENAI_URL, model=backend.model,
        api_key_env=backend.api_key_env or "OPENAI_API_KEY",
        capabilities=Capabilities(images=backend.images, logprobs=backend.logprobs,
                                  json_schema=True),
        price_prompt_per_1k=prompt_price, price_completion_per_1k=completion_price,
        cache=backend.cache, timeout_s=backend.timeout_s, temperature=backend.temperature))


CHAT_BACKENDS: Registry[ChatModel] = Registry("chat back-end")
CHAT_BACKENDS.register("local", _local)
CHAT_BACKENDS.register("openai", _openai)


def build_chat_model(backend: ChatBackend) -> ChatModel:
    return CHAT_BACKENDS.build(backend.kind, backend=backend)
