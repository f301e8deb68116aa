"""Reading one JSON object out of a model's reply, in bounded time whatever the reply.

The reading back-ends (sightings, room adjacency, the reader) ask for a JSON object and use
``json_reply``; it is apart from ``parse`` because it reads no confidences, only a bounded
object. Like ``parse`` it is light: the standard library only, no numpy, no model back-end.
"""

from __future__ import annotations

import json
import math
from typing import Any

# A JSON reply is read in bounded time whatever its size or shape (``json_reply``): at most
# MAX_JSON_CHARS characters (a reply that asks for one JSON object of a few fields is some
# hundred), MAX_JSON_TRIES places where an object may start, values nested at most
# MAX_JSON_DEPTH deep and MAX_JSON_VALUES values in all; numbers must be finite.
MAX_JSON_CHARS = 100_000
MAX_JSON_TRIES = 64
MAX_JSON_DEPTH = 16
MAX_JSON_VALUES = 2_000
NO_JSON = "no JSON object"


class _Refused(Exception):
    """A JSON reply read no further: why (``json_reply``)."""


def _constant(name: str) -> Any:
    raise _Refused(f"a JSON number that is not finite ({name})")


def _float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise _Refused(f"a JSON number that is not finite ({text[:20]})")
    return value


def _int(text: str) -> int:
    if len(text) > 300:  # beyond any float, and Python's int() of over 4300 digits raises
        raise _Refused(f"a JSON number of {len(text)} digits")
    return int(text)


_DECODER = json.JSONDecoder(parse_float=_float, parse_int=_int, parse_constant=_constant)


def _bounded(value: Any) -> str | None:
    """Why ``value`` (a parsed reply) is refused: nested too deep or too many values; None when
    it is within the bounds."""
    stack, seen = [(value, 1)], 0
    while stack:
        item, depth = stack.pop()
        seen += 1
        if seen > MAX_JSON_VALUES:
            return f"a JSON object of over {MAX_JSON_VALUES} values"
        if depth > MAX_JSON_DEPTH:
            return f"a JSON object nested over {MAX_JSON_DEPTH} deep"
        if isinstance(item, dict):
            stack += [(v, depth + 1) for v in item.values()]
        elif isinstance(item, list):
            stack += [(v, depth + 1) for v in item]
    return None


def json_reply(reply: str) -> tuple[dict[str, Any] | None, str]:
    """The first JSON object in ``reply`` (a model may wrap it in prose or a code fence) and "",
    or None and why not (``NO_JSON`` when there is none, or the first JSON value found is not
    an object). Never raises, in time bounded whatever the reply: one longer than
    ``MAX_JSON_CHARS``, an object nested deeper than ``MAX_JSON_DEPTH`` or of more than
    ``MAX_JSON_VALUES`` values, or one holding a number that is not finite (``NaN``,
    ``Infinity``, ``1e999``) is refused whole, and said so."""
    if not isinstance(reply, str):
        return None, NO_JSON
    if len(reply) > MAX_JSON_CHARS:
        return None, f"a reply of {len(reply)} characters (over {MAX_JSON_CHARS})"
    start = reply.find("{")
    for _ in range(MAX_JSON_TRIES):
        if start < 0:
            break
        try:
            value, _end = _DECODER.raw_decode(reply, start)
        except _Refused as refused:
            return None, str(refused)
        except RecursionError:
            return None, f"a JSON object nested over {MAX_JSON_DEPTH} deep"
        except ValueError:
            start = reply.find("{", start + 1)
            continue
        if not isinstance(value, dict):
            return None, NO_JSON
        beyond = _bounded(value)
        return (None, beyond) if beyond else (value, "")
    return None, NO_JSON
