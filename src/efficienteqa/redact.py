"""Passwords written into URLs (``openai:MODEL@http://user:PASSWORD@host/v1``) kept out of
everything the project writes or prints: run records, episode lines and records, reports, kept
probes, error lines. The password becomes ``***``; the scheme, user, host and path stay, so a
run's record still tells one server from another (and resumes with the command that made it)."""

from __future__ import annotations

import re
from typing import Any

# scheme://user:password@ : the userinfo ends at the authority's last "@" (a password may hold
# one), and the authority at the first "/", "?", "#" or space.
_PASSWORD = re.compile(r"(?P<head>\b[A-Za-z][A-Za-z0-9+.-]*://[^/?#@\s:]*):[^/?#\s]*@")


def redact_urls(text: str) -> str:
    """``text`` with the password of every URL in it replaced by ``***``."""
    return _PASSWORD.sub(lambda m: f"{m['head']}:***@", text) if "://" in text else text


def redacted(value: Any) -> Any:
    """``value`` (JSON-like: dicts, lists, tuples, strings) with ``redact_urls`` applied to
    every string in it, keys included."""
    if isinstance(value, str):
        return redact_urls(value)
    if isinstance(value, dict):
        return {redacted(k): redacted(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [redacted(v) for v in value]
    return value
