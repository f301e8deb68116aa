"""What a model server can do, asked with a few one-token requests, and kept on disk.

Logprobs (returned, ignored or rejected), JSON schemas and how many images one request may
carry; the client's ``probe`` runs these once per (base URL, model) and keeps the result in
``cache_dir("probes")``. Apart from the client because it is one question asked of the server
through the client's own request (``complete``), with its own file and its own wording.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.cache import cache_path
from efficienteqa.models.base import Capabilities, Message
from efficienteqa.models.client_config import ClientConfig
from efficienteqa.models.client_errors import RequestRejected, ServerFailed, one_line
from efficienteqa.models.wire import parse_logprobs
from efficienteqa.redact import redact_urls

# The probe: as many top alternatives as the agent asks for (vc.logprobs.TOP_LOGPROBS), and as
# many images as one request of the agent carries at most (the answer's K = 5 frames).
PROBE_TOP_LOGPROBS = 10
PROBE_IMAGES = 5
PROBE_RETRIES = 1

# One probe request: the arguments of ``chat.completions.create`` in, the reply's JSON out.
Complete = Callable[[dict[str, Any]], dict[str, Any]]


def probe_path(config: ClientConfig, model: str) -> Path:
    """Where this server's probe is kept; the folder is made only when it is written, so a
    read-only cache costs the keeping, not the run."""
    ident = f"{redact_urls(config.base_url.rstrip('/'))}|{model}"
    folder = Path(config.probe_dir) if config.probe_dir else cache_path("probes")
    return folder / f"{hashlib.sha256(ident.encode()).hexdigest()[:24]}.json"


def applied(declared: Capabilities, found: dict[str, Any], source: str) -> Capabilities:
    """The declared capabilities, each flag the server lacks turned off (see ``probe``)."""
    notes = {k: str(found[k + "_probe"]) for k in ("logprobs", "json_schema", "images")
             if k + "_probe" in found}
    return replace(
        declared, logprobs=declared.logprobs and bool(found.get("logprobs")),
        json_schema=declared.json_schema and bool(found.get("json_schema", True)),
        images=declared.images and bool(found.get("images", True)),
        max_images=found.get("max_images") if declared.images else declared.max_images,
        source=source, probed=notes)


def probe_text(complete: Complete, model: str, json_schema: bool) -> dict[str, Any]:
    """Logprobs, and JSON schemas where ``json_schema`` is declared (see the client's
    ``probe_capabilities``), as the kept probe's fields."""
    found: dict[str, Any] = {}
    plain = {"model": model, "messages": [{"role": "user", "content": "Say yes."}],
             "max_tokens": 1, "temperature": 0.0}
    try:
        data = complete({**plain, "logprobs": True, "top_logprobs": PROBE_TOP_LOGPROBS})
        choices = data.get("choices") or [{}]
        found["logprobs"] = bool(parse_logprobs(choices[0]))
        found["logprobs_probe"] = "returned" if found["logprobs"] else "ignored"
    except (RequestRejected, ServerFailed) as error:
        if error.status in (401, 403, 404):
            raise
        complete(plain)  # the server answers a plain request, or this raises
        found["logprobs"] = False
        found["logprobs_probe"] = refusal(error)
    if json_schema:
        schema = {"name": "probe", "schema": {"type": "object", "properties": {
            "ok": {"type": "boolean"}}, "required": ["ok"]}}
        try:
            complete({**plain, "max_tokens": 8, "response_format": {
                "type": "json_schema", "json_schema": schema}})
            found["json_schema"], found["json_schema_probe"] = True, "accepted"
        except (RequestRejected, ServerFailed) as error:
            if isinstance(error, ServerFailed):  # a failing server, or one failing on this?
                complete(plain)
            found["json_schema"] = False
            found["json_schema_probe"] = refusal(error)
    return found


def probe_images(complete: Complete, message: Callable[[Message], dict[str, Any]],
                 model: str) -> dict[str, Any]:
    """How many images one request may carry (see the client's ``probe_capabilities``);
    ``message`` turns a message into the request's form."""
    tiny = np.zeros((32, 32, 3), np.uint8)
    tiny[8:24, 8:24] = (200, 60, 40)

    def request(n: int) -> dict[str, Any]:
        said = message(Message("user", "How many images are there?", (tiny,) * n))
        return {"model": model, "messages": [said], "max_tokens": 1, "temperature": 0.0}

    try:
        complete(request(PROBE_IMAGES))
        return {"images": True, "max_images": None,
                "images_probe": f"{PROBE_IMAGES} accepted"}
    except (RequestRejected, ServerFailed) as error:
        said = re.search(r"at most (\d+) image", str(error), re.IGNORECASE)
        fewer = int(said.group(1)) if said else 1
        fewer = fewer if 1 <= fewer < PROBE_IMAGES else 1
        try:
            complete(request(fewer))
        except (RequestRejected, ServerFailed) as again:
            return {"images": False, "max_images": None,
                    "images_probe": f"rejected: {one_line(str(again), 200)}"}
        return {"images": True, "max_images": fewer,
                "images_probe": f"{fewer} accepted, {PROBE_IMAGES} rejected: HTTP {error.status}"}


def refusal(error: RequestRejected | ServerFailed) -> str:
    """What a feature probe's refusal says in ``capabilities.probed``."""
    if isinstance(error, ServerFailed):
        return f"failed: HTTP {error.status}, read as not supported"
    return f"rejected: HTTP {error.status}"


def read_probe(path: Path) -> dict[str, Any] | None:
    """A kept probe, or None when absent or unreadable (it is then probed again)."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or "logprobs" not in data:
        return None
    return data
