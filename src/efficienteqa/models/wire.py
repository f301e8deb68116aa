"""The chat request and reply as the OpenAI-compatible API has them: the arguments of
``chat.completions.create`` built from messages and the server's capabilities, and the reply's
JSON read back into a ``ChatResponse`` (logprobs in either of the two shapes servers send).

Apart from the client because it is pure: dicts in, dicts out, no SDK, no network, no cache.
"""

from __future__ import annotations

import math
from typing import Any

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import Capabilities, ChatResponse, Message, TokenLogprob
from efficienteqa.models.client_config import ClientConfig
from efficienteqa.models.client_errors import one_line, redact_key
from efficienteqa.models.images import encode_image


def chat_message(message: Message, model: str, caps: Capabilities,
                 config: ClientConfig) -> dict[str, Any]:
    """One message as the request carries it (images as ``data:`` URLs, ``encode_image``)."""
    if not message.images:
        return {"role": message.role, "content": message.text}
    if not caps.images:
        raise EfficientEQAError(f"model {model!r} does not accept images",
                                fix="use a vision model or set capabilities.images")
    parts: list[dict[str, Any]] = [{"type": "text", "text": message.text}]
    for image in message.images:
        url: dict[str, Any] = {"url": encode_image(image, config.image_max_side,
                                                   config.image_format)}
        if config.image_detail is not None:
            url["detail"] = config.image_detail
        parts.append({"type": "image_url", "image_url": url})
    return {"role": message.role, "content": parts}


def request_arguments(messages: list[Message], model: str, caps: Capabilities,
                      config: ClientConfig, *, max_tokens: int, temperature: float,
                      logprobs: int | None, json_schema: dict[str, Any] | None,
                      seed: int | None) -> dict[str, Any]:
    """The arguments of ``chat.completions.create`` for these (only fields the capabilities
    allow; server extensions in ``extra_body``)."""
    arguments: dict[str, Any] = {"model": model,
                                 "messages": [chat_message(m, model, caps, config) for m in messages],
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


def chat_response(data: dict[str, Any], latency_s: float, model: str, url: str,
                  config: ClientConfig) -> ChatResponse:
    """The reply's JSON dict as a ``ChatResponse`` (``model`` where the reply names none)."""
    choices = data.get("choices") or []
    if not choices or not isinstance(choices[0], dict):
        raise EfficientEQAError(f"model server at {url} sent no choices: "
                                f"{redact_key(one_line(str(data), 120), config)}",
                                fix="check base_url and model")
    choice = choices[0]
    usage = data.get("usage") or {}
    finish = choice.get("finish_reason")
    return ChatResponse(
        text=(choice.get("message") or {}).get("content") or "",
        model=data.get("model") or model,
        prompt_tokens=int(usage.get("prompt_tokens") or 0),
        completion_tokens=int(usage.get("completion_tokens") or 0),
        latency_s=latency_s,
        logprobs=parse_logprobs(choice),
        raw=data,
        finish_reason=finish if isinstance(finish, str) else None,
    )


def _is_wrapper(schema: dict[str, Any]) -> bool:
    """OpenAI's ``{"name", "schema", "strict"?}`` wrapper rather than a bare JSON schema."""
    return "schema" in schema and "name" in schema and set(schema) <= {
        "name", "schema", "strict", "description"}
