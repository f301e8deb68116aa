"""Persistent chat-response cache: one sqlite file shared by every worker on a machine.

The key is a sha256 over what determines a reply: model name, messages (each image replaced by
the sha256 of its pixels, shape and dtype), ``max_tokens``, ``temperature``, ``logprobs``,
``json_schema``, ``seed``, the image encoding (format, size, detail) and, for a server named by
URL (kind "openai"), that server's base URL: two servers serving the same model name are two
servers, and an ``ask`` against a dead server must not "succeed" from another's replies. The
embedded local model (kind "local", on a loopback port that changes between sessions) is keyed
without its URL, exactly as before the URL was added, so its existing cache still hits. The key
never includes the API key, and the database holds no secret.

Requests with ``temperature > 0`` are cached too, with the seed in the key: we prefer
reproducible episodes over sampling diversity. To draw several samples, vary the seed.
"""

from __future__ import annotations

import hashlib
import json
import logging
import sqlite3
import threading
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.cache import cache_dir
from efficienteqa.models.base import ChatResponse, Message, TokenLogprob

log = logging.getLogger(__name__)

_SCHEMA = """CREATE TABLE IF NOT EXISTS responses (
    key TEXT PRIMARY KEY, model TEXT NOT NULL, created REAL NOT NULL, response TEXT NOT NULL)"""


def image_sha256(image: np.ndarray) -> str:
    """Hash of an image's pixels, shape and dtype (two crops with equal bytes differ)."""
    array = np.ascontiguousarray(image)
    digest = hashlib.sha256(f"{array.shape}|{array.dtype.str}|".encode())
    digest.update(array.tobytes())
    return digest.hexdigest()


def request_key(model: str, messages: list[Message], *, max_tokens: int, temperature: float,
                logprobs: int | None, json_schema: dict[str, Any] | None, seed: int | None,
                image_encoding: str = "", server: str | None = None) -> str:
    """The cache key of one chat request (hex sha256); see the module docstring. ``server``:
    the base URL of a server named by URL; None (the embedded local model) leaves it out of
    the key, which is then the key of the releases before it existed."""
    payload = {
        "model": model,
        "messages": [{"role": m.role, "text": m.text, "images": [image_sha256(i) for i in m.images]}
                     for m in messages],
        "max_tokens": max_tokens,
        "temperature": float(temperature),
        "logprobs": logprobs,
        "json_schema": json_schema,
        "seed": seed,
        "image_encoding": image_encoding if any(m.images for m in messages) else "",
    }
    if server is not None:
        payload["server"] = server.rstrip("/")
    blob = json.dumps(payload, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(blob.encode()).hexdigest()


def response_to_json(response: ChatResponse) -> str:
    return json.dumps(asdict(response), ensure_ascii=False)


# The JSON types of a stored response's fields. An entry of another type (a null token count,
# a text that is an object) is refused here: served, it would fail every episode that hits it,
# far from the cache (the usage sum, a parser), and every resume the same way.
_NUMBER = (int, float)
FIELD_TYPES: dict[str, tuple[type, ...]] = {
    "text": (str,), "model": (str,), "prompt_tokens": (int,), "completion_tokens": (int,),
    "latency_s": _NUMBER, "cached": (bool,), "logprobs": (list, type(None)), "raw": (dict,),
    "finish_reason": (str, type(None))}


def _typed(name: str, value: Any, types: tuple[type, ...]) -> Any:
    """``value`` when it is of ``types`` (a bool is no number here), else a ``TypeError``."""
    if not isinstance(value, types) or (isinstance(value, bool) and bool not in types):
        raise TypeError(f"{name} is {type(value).__name__}: {str(value)[:40]!r}")
    return value


def _token_logprob(entry: Any) -> TokenLogprob:
    """A stored ``TokenLogprob``: ``{"token": str, "logprob": number, "top": [[str, number]]}``."""
    entry = _typed("a logprob", entry, (dict,))
    top = _typed("top", entry.get("top", []), (list,))
    pairs = [_typed("an alternative", pair, (list,)) for pair in top]
    if any(len(pair) != 2 for pair in pairs):
        raise TypeError("an alternative is not a (token, logprob) pair")
    return TokenLogprob(token=_typed("token", entry.get("token"), (str,)),
                        logprob=_typed("logprob", entry.get("logprob"), _NUMBER),
                        top=tuple((_typed("token", a, (str,)), _typed("logprob", b, _NUMBER))
                                  for a, b in pairs))


def response_from_json(blob: str) -> ChatResponse:
    """A stored response; fields it lacks (an entry older than them, e.g. ``finish_reason``)
    take their defaults, and fields this version does not know are dropped. ``ValueError`` or
    ``TypeError`` for an entry that is not JSON or has a field of another type
    (``FIELD_TYPES``)."""
    data = _typed("the entry", json.loads(blob), (dict,))
    data = {k: _typed(k, v, FIELD_TYPES[k]) for k, v in data.items() if k in FIELD_TYPES}
    if data.get("logprobs") is not None:
        data["logprobs"] = [_token_logprob(t) for t in data["logprobs"]]
    return ChatResponse(**data)


class ResponseCache:
    """sqlite (WAL, busy timeout) at ``path`` or ``cache_dir("responses")/responses.sqlite``.

    One connection per thread, opened on first use; several processes may share the file.
    """

    def __init__(self, path: str | Path | None = None, *, busy_timeout_s: float = 30.0) -> None:
        self._path = Path(path) if path is not None else None
        self._busy_timeout_s = busy_timeout_s
        self._local = threading.local()
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    @property
    def path(self) -> Path:
        if self._path is None:
            self._path = self.default_path()
        return self._path

    @staticmethod
    def default_path() -> Path:
        """``cache_dir("responses")/responses.sqlite``, its folder created (an
        ``EfficientEQAError`` when it cannot be)."""
        return cache_dir("responses") / "responses.sqlite"

    def _connection(self) -> sqlite3.Connection:
        conn = getattr(self._local, "conn", None)
        if conn is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            conn = sqlite3.connect(self.path, timeout=self._busy_timeout_s, isolation_level=None)
            conn.execute(f"PRAGMA busy_timeout = {int(self._busy_timeout_s * 1000)}")
            conn.execute("PRAGMA journal_mode = WAL")
            conn.execute("PRAGMA synchronous = NORMAL")
            conn.execute(_SCHEMA)
            self._local.conn = conn
        return conn

    def get(self, key: str) -> ChatResponse | None:
        """The stored response with ``cached=True`` and the lookup time as latency, or None."""
        start = time.perf_counter()
        # fetchall, not fetchone: the statement runs to its end, so no read transaction stays
        # open to be upgraded by the next put (SQLITE_BUSY at once, whatever the busy timeout,
        # when another process wrote in between)
        rows = self._connection().execute("SELECT response FROM responses WHERE key = ?",
                                          (key,)).fetchall()
        row = rows[0] if rows else None
        try:
            response = response_from_json(row[0]) if row is not None else None
        except (ValueError, TypeError, KeyError, AttributeError) as error:  # a bad entry, e.g.
            # written by another version of the code into the shared cache: a miss, dropped
            log.warning("dropped an unreadable response-cache entry (%s: %s) from %s",
                        type(error).__name__, str(error)[:80], self.path)
            self._connection().execute("DELETE FROM responses WHERE key = ?", (key,))
            response = None
        with self._lock:
            if response is None:
                self.misses += 1
                return None
            self.hits += 1
        response.cached = True
        response.latency_s = time.perf_counter() - start
        return response

    def put(self, key: str, response: ChatResponse) -> None:
        stored = response_to_json(replace(response, cached=False))
        self._connection().execute(
            "INSERT OR REPLACE INTO responses (key, model, created, response) VALUES (?, ?, ?, ?)",
            (key, response.model, time.time(), stored))

    def clear(self) -> None:
        self._connection().execute("DELETE FROM responses")

    def stats(self) -> dict[str, Any]:
        """Entries and size on disk, and this object's hits and misses."""
        (entries,) = self._connection().execute("SELECT COUNT(*) FROM responses").fetchone()
        size = sum(p.stat().st_size for p in self.path.parent.glob(self.path.name + "*"))
        return {"path": str(self.path), "entries": entries, "bytes": size,
                "hits": self.hits, "misses": self.misses}

    def close(self) -> None:
        """Close this thread's connection (others close when their threads end)."""
        conn = getattr(self._local, "conn", None)
        if conn is not None:
            conn.close()
            self._local.conn = None
