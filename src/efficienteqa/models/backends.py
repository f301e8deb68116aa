"""Chat back-ends by configuration: the embedded local model and any OpenAI-compatible server
share one client (``OpenAIChatClient``); only the URL, the model and the capabilities differ."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from urllib.parse import urlsplit

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import Capabilities, ChatModel
from efficienteqa.models.client import OpenAIChatClient
from efficienteqa.models.client_config import ClientConfig
from efficienteqa.models.local.weights import DEFAULT_MODEL
from efficienteqa.records import read_json
from efficienteqa.redact import redact_urls
from efficienteqa.registry import Registry

OPENAI_URL = "https://api.openai.com/v1"
OPENAI_HOST = "api.openai.com"
OPENAI_KEY_ENV = "OPENAI_API_KEY"
# USD per 1k tokens (prompt, completion); unknown models cost 0 in the accounting.
PRICES = {"gpt-4o": (0.0025, 0.01), "gpt-4o-2024-05-13": (0.005, 0.015),
          "gpt-4o-mini": (0.00015, 0.0006)}
# The embedded llama.cpp server's capabilities are known: no probe.
LOCAL_CAPABILITIES = Capabilities(images=False, logprobs=True, grammar=True)


@dataclass(frozen=True)
class ChatBackend:
    """``kind``: "local" (llama.cpp on loopback, started on demand; text only), "openai" (any
    OpenAI-compatible server: GPT-4o, vLLM, Ollama; ``images`` for VLMs). Tests build
    ``StubChatModel`` directly.

    For kind "openai" the server is probed once per (base URL, model) (``probe``; the result is
    kept on disk, see ``OpenAIChatClient.probe``): logprobs, JSON schemas and, with ``images``,
    how many images a request may carry. The local server's capabilities are declared.

    ``api_key_env``: the environment variable whose key is sent; "none": no key; None (default):
    ``OPENAI_API_KEY`` for the official host (api.openai.com) only, no key for any other server
    (a vLLM server without auth needs none, and the user's OpenAI key must not reach another
    host unless the user names it for that host).

    ``timeout_s``/``retries``: each try's limit and the retries after the first try (a hung
    server costs ``timeout_s * (retries + 1)`` per call).

    Images (kind "openai"): ``image_format`` None is "jpeg" (quality 90): a 512x384 frame of a
    rendered house is 80-315 kB as PNG and about 6 times smaller as JPEG q90
    (measured: the first frames of synthetic houses 0 and 3, 185 and 161 kB as PNG, 29 and 27 kB
    as JPEG), a difference the model does not see but every request's upload (K = 5 frames in
    one answer) and the server's decoding do. The local back-end keeps PNG (it is text-only).
    ``image_max_side`` 512 px: OpenAI's low-detail tile and more than Qwen2.5-VL needs to read a
    room. ``image_detail`` None: not sent (the server's default, "auto" for OpenAI, which gives a
    512x384 frame one 512 px tile plus the base tokens); "low" costs GPT-4o 85 tokens an image.
    """

    kind: str = "local"
    model: str = DEFAULT_MODEL
    base_url: str | None = None
    api_key_env: str | None = None
    images: bool = False
    logprobs: bool = True
    cache: bool = True
    timeout_s: float = 120.0
    retries: int = 4
    temperature: float | None = None  # None: each call's own (0 for every call of the agent)
    image_format: str | None = None  # None: "jpeg" for kind openai
    image_max_side: int = 512
    image_detail: str | None = None
    probe: bool = True
    # a JSON file of what the server can do (``read_capabilities``), in place of the probe
    capabilities_file: str | None = None
    flag: str = "--backends.vlm"  # the option that named it, for the errors ("--eval.judge" for a
    # judge)

    @property
    def key_env(self) -> str | None:
        """The variable whose key is sent (see the class docstring), or None: no key."""
        if self.api_key_env is not None:
            return None if self.api_key_env.lower() == "none" else self.api_key_env
        if self.kind != "openai":
            return None
        return OPENAI_KEY_ENV if is_official(self.base_url or OPENAI_URL) else None


def is_official(base_url: str) -> bool:
    """Whether ``base_url`` is OpenAI's own API (https, host api.openai.com)."""
    parsed = urlsplit(base_url)
    return parsed.scheme == "https" and (parsed.hostname or "").lower() == OPENAI_HOST


def _local(backend: ChatBackend) -> ChatModel:
    from efficienteqa.models.local import ensure_server

    base_url = backend.base_url or ensure_server(backend.model)
    capabilities = replace(LOCAL_CAPABILITIES, logprobs=backend.logprobs)
    return OpenAIChatClient(ClientConfig(
        base_url=base_url, model=backend.model, capabilities=capabilities,
        api_key_env=backend.key_env, cache=backend.cache, timeout_s=backend.timeout_s,
        max_retries=backend.retries, temperature=backend.temperature,
        image_format=backend.image_format or "png", image_max_side=backend.image_max_side,
        image_detail=backend.image_detail))


def _openai(backend: ChatBackend) -> ChatModel:
    prompt_price, completion_price = PRICES.get(backend.model, (0.0, 0.0))
    base_url = backend.base_url or OPENAI_URL
    model_spec = f"openai:{backend.model}" + (f"@{redact_urls(base_url)}" if backend.base_url else "")
    client = OpenAIChatClient(ClientConfig(
        base_url=base_url, model=backend.model, api_key_env=backend.key_env,
        capabilities=Capabilities(images=backend.images, logprobs=backend.logprobs,
                                  json_schema=True),
        price_prompt_per_1k=prompt_price, price_completion_per_1k=completion_price,
        cache=backend.cache, timeout_s=backend.timeout_s, max_retries=backend.retries,
        temperature=backend.temperature, image_format=backend.image_format or "jpeg",
        image_max_side=backend.image_max_side, image_detail=backend.image_detail,
        cache_server=redact_urls(base_url),  # a password in the URL is no part of the server
        unreachable_fix=f"check that the server of {backend.flag} {model_spec} is running and "
                        "that the "
                        "URL is right (it usually ends in /v1)"))
    if backend.capabilities_file is not None:
        client.declare(read_capabilities(Path(backend.capabilities_file), backend.images))
    elif backend.probe:
        client.probe(images=backend.images)
    return client


CAPABILITY_FIELDS = ("logprobs", "json_schema", "images", "grammar", "max_images")


def read_capabilities(path: Path, images: bool = True) -> Capabilities:
    """What a server can do, as the user wrote it (``--capabilities FILE``: a JSON object of
    ``CAPABILITY_FIELDS``, e.g. ``{"logprobs": true, "json_schema": false}``; a flag left out is
    off, ``images`` only where the run reads images): for a server whose answers to the probe
    mislead. One-line errors for a file that cannot be read or holds anything else."""
    fix = ('write a JSON object such as {"logprobs": true, "json_schema": false, "images": true, '
           '"max_images": 1}')
    try:
        data = read_json(Path(path).read_bytes())
    except OSError as error:
        raise EfficientEQAError(f"cannot read the capabilities file {path}: "
                                f"{error.strerror or error}", fix=fix) from None
    except ValueError as error:
        raise EfficientEQAError(f"the capabilities file {path} is not JSON: {error}",
                                fix=fix) from None
    if not isinstance(data, dict):
        raise EfficientEQAError(f"the capabilities file {path} holds no JSON object", fix=fix)
    for key, value in data.items():
        ok = key in CAPABILITY_FIELDS and (
            isinstance(value, bool) if key != "max_images"
            else value is None or (isinstance(value, int) and not isinstance(value, bool)))
        if not ok:
            raise EfficientEQAError(f"the capabilities file {path} has a bad entry {key!r}: "
                                    f"{value!r}", fix=fix)
    max_images = data.get("max_images")
    if max_images is not None and max_images < 1:
        raise EfficientEQAError(f"the capabilities file {path} allows {max_images} images",
                                fix="give max_images 1 or more, or null for no cap")
    return Capabilities(images=images and bool(data.get("images", False)),
                        logprobs=bool(data.get("logprobs", False)),
                        json_schema=bool(data.get("json_schema", False)),
                        grammar=bool(data.get("grammar", False)), max_images=max_images,
                        source="file", probed={"file": str(path)})


CHAT_BACKENDS: Registry[ChatModel] = Registry("chat back-end")
CHAT_BACKENDS.register("local", _local)
CHAT_BACKENDS.register("openai", _openai)


def build_chat_model(backend: ChatBackend) -> ChatModel:
    return CHAT_BACKENDS.build(backend.kind, backend=backend)
