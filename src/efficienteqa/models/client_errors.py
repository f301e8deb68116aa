"""The model client's errors: what the server or the ``openai`` SDK said, as one line naming
the server, the tries and what to do, with the API key never in it.

Apart from the client because the probe reads these errors too (``RequestRejected``,
``ServerFailed``), and the wording of every failure and its fix is kept in one place.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.client_config import ClientConfig

if TYPE_CHECKING:
    import openai


def one_line(text: str, limit: int = 300) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


class RequestRejected(EfficientEQAError):
    """The server answered with a 4xx that retrying will not fix (``status``: the HTTP code)."""

    def __init__(self, message: str, status: int, fix: str | None = None) -> None:
        super().__init__(message, fix=fix)
        self.status = status


class ServerFailed(EfficientEQAError):
    """The server still answered with a 5xx after its retries (``status``: the HTTP code). Some
    servers answer 500 to a request option they do not know (llama-cpp-python to a JSON-schema
    ``response_format``), so the capability probe reads it as "not supported"."""

    def __init__(self, message: str, status: int, fix: str | None = None) -> None:
        super().__init__(message, fix=fix)
        self.status = status


def redact_key(text: str, config: ClientConfig) -> str:
    """``text`` with the configured API key as ``***``."""
    key = os.environ.get(config.api_key_env or "") if config.api_key_env else None
    return text.replace(key, "***") if key else text


def unreadable(body: bytes, url: str, config: ClientConfig) -> EfficientEQAError:
    """A 2xx body that is not JSON, in one line saying what came instead: the SDK raises
    ``JSONDecodeError`` from its own parser for a body labelled JSON (a login page from a
    proxy, an empty body, bytes it decodes as UTF-16), with the body out of reach."""
    where, fix = f"model server at {url}", "check base_url and the server's log"
    if not body.strip():
        return EfficientEQAError(f"{where} sent an empty reply", fix=fix)
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as error:
        return EfficientEQAError(f"{where} sent a reply that is not UTF-8 (byte {error.start}):"
                                 f" {body[:24]!r}", fix=fix)
    return EfficientEQAError(f"{where} sent a reply that is not JSON: "
                             f"{redact_key(one_line(text, 120), config)}", fix=fix)


def sdk_error(error: openai.OpenAIError, url: str, config: ClientConfig) -> EfficientEQAError:
    """The SDK's error as one line naming the server, the tries and what to do."""
    import openai

    request = getattr(error, "request", None)
    retries = request.headers.get("x-stainless-retry-count") if request is not None else None
    tries = int(retries) + 1 if retries and retries.isdigit() else config.max_retries + 1
    where = f"model server at {url}"
    if isinstance(error, openai.APITimeoutError):
        return EfficientEQAError(f"{where} did not answer within {config.timeout_s:g} s "
                                 f"({tries} tries)",
                                 fix="raise --backends.timeout-s (each try's limit) or lower "
                                     "--backends.retries, or check that the server is not "
                                     "stuck")
    if isinstance(error, openai.APIConnectionError):
        cause = error.__cause__ or error
        detail = redact_key(one_line(f"{type(cause).__name__}: {cause}", 200), config)
        return EfficientEQAError(f"{where} unreachable after {tries} tries: {detail}",
                                 fix=config.unreachable_fix)
    if isinstance(error, openai.APIStatusError):
        status = error.status_code
        detail = redact_key(one_line(_error_text(error), 200), config)
        if status >= 500:  # the SDK retried these
            return ServerFailed(f"{where} still answered HTTP {status} after {tries} tries: "
                                f"{detail}", status, fix=fix_for(status, config))
        if status in (408, 409, 429):  # the SDK retried these too
            return EfficientEQAError(f"{where} still answered HTTP {status} after {tries} tries: "
                                     f"{detail}", fix=fix_for(status, config))
        return RequestRejected(f"{where} rejected the request: HTTP {status} {detail}", status,
                               fix=fix_for(status, config))
    detail = redact_key(one_line(str(error), 200), config)
    return EfficientEQAError(f"{where}: {type(error).__name__}: {detail}",
                             fix="check base_url and the model name")


def fix_for(status: int, config: ClientConfig) -> str:
    """What to do about an HTTP ``status`` from the server."""
    if status in (401, 403):
        if config.api_key_env is None:
            return "no key was sent: name the variable holding this server's key with " \
                   "--backends.api-key-env NAME"
        return f"check the API key in ${config.api_key_env} (--backends.api-key-env names another)"
    if status == 404:
        return "check base_url (it usually ends in /v1) and the model name"
    if status == 429:
        return "wait, or send fewer requests at once (fewer workers)"
    if status >= 500:
        return "the server failed; see its log, or retry later"
    return "check the model name and the request parameters the server supports"


def _error_text(error: openai.APIStatusError) -> str:
    """What the server said: the ``error.message`` of an OpenAI-style body, else its text."""
    body = error.body
    if isinstance(body, dict):
        inner = body.get("error", body)
        message = inner.get("message") if isinstance(inner, dict) else inner
        if isinstance(message, str) and message:
            return message
    try:
        return error.response.text
    except Exception:  # a streamed body that was never read
        return error.message
