"""An OpenAI-compatible chat server with real servers' habits, for the test suite (docs/servers.md).

It runs on 127.0.0.1 (on a free port unless one is given) in a thread, answers
``POST /v1/chat/completions`` and ``GET /v1/models``, checks every image it is sent and records
every request. It answers the project's prompts (explore, worth exploring, relevancy match, the
gate, the sightings, the answers, grouping, the judge in each mode, the probe) in the format
they ask for, in one of several ``STYLES``, deterministically (the same request gets the same
reply). ``Options`` says how it behaves, e.g. like GPT-4o (logprobs returned, any number of
images), like vLLM with ``--limit-mm-per-prompt image=1`` (``max_images=1``), like a server
that ignores or rejects logprobs, hangs, or cuts replies at ``max_tokens``, or like a broken
server or proxy, or one whose reply to one kind of call is odd (``Options.misbehave``:
``MISBEHAVIOURS``, the fault trials' modes).

In a test::

    from vlm_server import Options, servers

    @pytest.fixture
    def vlm():
        with servers() as start:       # every server started is stopped after the test
            yield start

    def test_something(vlm):
        server = vlm(Options(logprobs="ignore", style="markdown"))
        ... ChatBackend(kind="openai", model="test-vlm", base_url=server.base_url) ...
        assert server.requests[-1].images == 1 and not server.image_errors

Only the standard library, numpy and Pillow.
"""

from __future__ import annotations

import base64
import hashlib
import io
import json
import math
import re
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

from PIL import Image

STYLES = ("exact", "markdown", "preamble", "json", "reasoning", "refuse")
# vLLM's answer to more images than --limit-mm-per-prompt allows (HTTP 400).
VLLM_IMAGE_LIMIT = "At most {n} image(s) may be provided in one request."
# Bodies sent as "200 application/json" that are no JSON (``Options.misbehave``): bytes that a JSON
# reader takes for UTF-16 (a byte-order mark, then no JSON), a login page, nothing.
BROKEN = {"garbage": b"\xfe\xff\x00\x7b\x9c\x80\x00\x7d",
          "html200json": b"<!DOCTYPE html><html><body><h1>Sign in</h1></body></html>",
          "empty200": b""}
BAD_GATEWAY = (b"<html><head><title>502 Bad Gateway</title></head><body><center><h1>502 Bad "
               b"Gateway</h1></center><hr><center>nginx</center></body></html>")
XSS = "<script>alert(1)</script><img src=x onerror=alert(5)> "
CONTROL = "\x1b[31m\x07\x08\x00\x0b\r"  # ESC (a colour), BEL, BS, NUL, VT, CR
HUGE_CHARS = 2_400_000
_SIGHTING = ('{{"room": "bedroom", "doorways": [], "things": [{{"name": "bed", "item": {item}, '
             '"box": [{box}, 100, 500, 600]}}]}}')
_JUDGE = ("judge", "judge-openeqa")
# ``Options.misbehave`` modes that replace the reply to one kind of call (``classify``) only, as
# the second fault trials' test server did (every other call is answered as usual): kinds,
# what, the reply.
REPLACED: dict[str, tuple[tuple[str, ...], str, str]] = {
    "sightnan": (("sightings",), "NaN for the item and in the box",
                 _SIGHTING.format(item="NaN", box="NaN")),
    "sightinf": (("sightings",), "Infinity for the item and 1e999 in the box",
                 _SIGHTING.format(item="Infinity", box="1e999")),
    "sightdeep": (("sightings",), '{"room": and 200,000 "["', '{"room": ' + "[" * 200_000),
    "sighthuge": (("sightings",), "100,000 things (2.7 MB)",
                  '{"room": "bedroom", "doorways": [], "things": ['
                  + ", ".join(['{"name": "bed", "item": 1}'] * 100_000) + "]}"),
    "judgesup": (_JUDGE, "a superscript two", "\u00b2"),
    "judgesup5": (_JUDGE, "5 and a superscript two", "5\u00b2"),
    "judgeempty": (_JUDGE, "nothing", ""),
    "judgejunk": (_JUDGE, "control characters, brackets and 999...", "\x00\x07 <<>> 999..."),
    "judgedeep": (_JUDGE, '"Your mark: " and 100,000 "["', "Your mark: " + "[" * 100_000),
    "judgearabic": (_JUDGE, "an Arabic-Indic three", "\u0663"),
}
# ``Options.misbehave``: what every request after the first ``misbehave_after`` gets (the names
# of the fault trials' misbehaving server, docs/fault-trials.md). Statuses, then 200s whose body is
# not a chat completion, then replies that are one but odd. (Slow and hung servers are
# ``hang_s``/``hang_after``: "slowN" is hang_s=N, "hangafter" hang_after=2.)
MISBEHAVIOURS = {
    "html": "HTTP 502 with nginx's text/html error page (a proxy whose upstream is down)",
    "html200": "HTTP 200 with a text/html login page (a proxy's sign-in)",
    **{name: f"HTTP 200 labelled application/json: {what}" for name, what in (
        ("garbage", "bytes that are not UTF-8 (read as UTF-16 by a JSON reader)"),
        ("html200json", "a login page"), ("empty200", "no body"))},
    "e500": "HTTP 500 with an OpenAI-style error",
    "e401": "HTTP 401 (a wrong key)",
    "e429": "HTTP 429 with Retry-After: retry_after seconds",
    "echokey401": "HTTP 401 whose message repeats the request's Authorization header",
    "echokey500": "HTTP 500 whose message repeats the request's Authorization header",
    "nochoices": "a chat completion with an empty choices list",
    "wrongshape": "a JSON object of another shape (no choices)",
    "listbody": "a JSON list, [1, 2, 3]",
    "nullcontent": "a choice whose message content is null",
    "badlogprobs": "the reply with logprobs NaN, 1e308 and -Infinity (JSON extensions)",
    "underflow": "the reply with every logprob at -1000 or below (exp() is 0.0)",
    "lengthcut": "the reply cut to its first token, finish_reason length, whatever max_tokens",
    "truncated": "the reply's headers and half its body, then the connection closed",
    "huge": f"a reply of {HUGE_CHARS / 1e6:g} M characters (the reply, then filler)",
    "xss": f"the reply after HTML that runs script in a page: {XSS.strip()}",
    "ctrl": "the reply wrapped in control characters (ESC, BEL, BS, NUL, VT, CR)",
    **{name: f"the reply to {' and '.join(kinds)} calls: {what}"
       for name, (kinds, what, _) in REPLACED.items()},
}


@dataclass
class Options:
    """How the server behaves.

    ``style``: how replies are written: "exact" (the asked format), "markdown" (bold, ``%``),
    "preamble" (a sentence before), "json" (JSON in a code fence), "reasoning" (a few sentences
    of reasoning, then the asked format), "refuse" (a refusal to every request but the probes).
    ``logprobs``: "return" (chat-style ``content`` with ``top_logprobs``), "ignore" (a reply
    without them), "reject" (HTTP 400, as a server without logprobs support).
    ``json_schema``: "accept" (the reply is a JSON instance of the schema) or "reject" (400).
    ``images``: accepts images at all; ``max_images``: HTTP 400 with vLLM's message above it.
    ``max_side``: an image whose longer side exceeds it is an error (recorded, HTTP 400).
    ``fail``: the first ``fail`` requests get ``fail_status`` (429 with ``Retry-After:
    retry_after`` seconds, or e.g. 500). ``hang_s``: every request waits this long first
    (beyond a client's timeout: a hung server); ``hang_after``: only requests after that many.
    ``cut``: a reply longer than ``max_tokens`` tokens is cut there with finish_reason
    "length". ``api_key``: when set, any other ``Authorization`` gets HTTP 401.
    ``models``: when set, another model name gets HTTP 404.
    ``misbehave``: a broken server or proxy (``MISBEHAVIOURS``: a status with an error page, a
    200 that is no chat completion, an odd reply, a cut connection; or, ``REPLACED``, the reply
    to one kind of call only, e.g. the sighting call's or the judge's), to every request after
    the first ``misbehave_after`` (0: every request; 2: the capability probe passes, as the
    fault trials' "e500after" or "garbageafter").
    """

    style: str = "exact"
    logprobs: str = "return"
    json_schema: str = "accept"
    images: bool = True
    max_images: int | None = None
    max_side: int = 512
    fail: int = 0
    fail_status: int = 429
    retry_after: float = 0.01
    hang_s: float = 0.0
    hang_after: int = 0
    cut: bool = False
    api_key: str | None = None
    models: tuple[str, ...] | None = None
    misbehave: str | None = None
    misbehave_after: int = 0

    def __post_init__(self) -> None:
        if self.style not in STYLES:
            raise ValueError(f"style {self.style!r} is not one of {STYLES}")
        if self.misbehave is not None and self.misbehave not in MISBEHAVIOURS:
            raise ValueError(f"misbehave {self.misbehave!r} is not one of {tuple(MISBEHAVIOURS)}")
        if self.logprobs not in ("return", "ignore", "reject"):
            raise ValueError(f"logprobs {self.logprobs!r}")


@dataclass
class Seen:
    """One request: its headers (lower-case names), body, the kind of prompt it was, how many
    images it carried (format, width, height, detail of each) and the status answered."""

    headers: dict[str, str]
    body: dict[str, Any]
    kind: str = ""
    images: int = 0
    image_info: list[tuple[str, int, int, str | None]] = field(default_factory=list)
    status: int = 200
    reply: str = ""

    @property
    def authorization(self) -> str | None:
        return self.headers.get("authorization")


# ---------------------------------------------------------------- what a prompt asks

def classify(text: str, images: int = 0) -> str:
    """The kind of a request from its prompt text (see the prompt files named)."""
    t = text
    if t.strip() == "Say yes.":
        return "probe"
    if t.startswith("How many images are there?"):
        return "probe-images"
    if "Which directions should it explore" in t and "worth exploring" in t:
        return "explore"  # explore/prompts/explore.txt
    if "which directions should it explore" in t:
        return "explore-letters"  # explore_letters.txt
    if "reply with exactly two lines" in t:
        return "explore-token"  # explore_token.txt
    if "reply with the single letter of the direction" in t:
        return "explore-choice"  # explore_choice.txt
    if "One direction the robot can walk to" in t:
        return "explore-direction"  # explore_direction.txt
    if t.startswith("Is this view worth exploring"):
        return "worth-token" if "Reply with yes or no only" in t else "worth"
    if "Say what one view shows, as one JSON object" in t:
        return "sightings"  # perception/prompts/sightings.txt
    if "Are you confident about answering the question with the current view?" in t:
        return "confident-token" if "Reply with yes or no only" in t else "confident"
    if "Does this view of a home show what the question asks about" in t:
        return "match"  # relevancy/prompts/match.txt (also the model gate)
    if "Do these two answers mean the same thing" in t:
        return "group"  # vc/prompts/group.txt
    if "Reply with the letter of one choice" in t:
        return "blind-choice"
    if "best guesses" in t:
        return "answer"  # answer.txt, blind.txt
    if "Reply with the answer only" in t:
        return "answer-short"  # answer_direct.txt, answer_token.txt
    if "Reply with the score only" in t:
        return "judge"
    if t.startswith("You help me evaluate a response"):
        return "judge-openeqa"  # eval/prompts/judge_openeqa.txt: the mark alone
    if "Does the given answer say the same thing" in t or t.rstrip().endswith("Correct?"):
        return "judge-same"  # eval/prompts/judge_same.txt (two versions)
    return "other"


def _field(text: str, name: str) -> str:
    """The last ``name: value`` line (a few-shot prompt's own question comes after its
    examples)."""
    found = re.findall(rf"^{name}:[ \t]*(.*)$", text, re.MULTILINE)
    return found[-1].strip() if found else ""


def _letters(text: str) -> list[str]:
    """The lettered directions a prompt offers ("A: ..." lines, or "A, B (the lettered ...")."""
    block = text.split("Directions:", 1)[1] if "Directions:" in text else ""
    letters = re.findall(r"^([A-H]):", block, re.MULTILINE)
    if not letters:
        first = block.strip().splitlines()[0] if block.strip() else ""
        letters = re.findall(r"\b([A-H])\b", first.split("(")[0])
    return letters or ["A", "B"]


def plausible_answer(question: str, pick: int) -> str:
    """A short answer of the question's form."""
    q = question.lower()
    if q.startswith("how many"):
        return str(1 + pick % 3)
    if "colour" in q or "color" in q:
        return ("white", "brown", "blue")[pick % 3]
    if re.match(r"^(is|are|can|does|do|was|were|has|have)\b", q):
        return ("yes", "no")[pick % 2]
    if q.startswith("where"):
        return ("in the kitchen", "in the living room", "in the bedroom")[pick % 3]
    if q.startswith("which room"):
        return ("the kitchen", "the living room", "the bedroom")[pick % 3]
    return ("a lamp", "a book", "a plant")[pick % 3]


@dataclass
class Reply:
    """What the model 'says': ``exact`` is the reply in the asked format; ``data`` the same as
    a JSON object (for the json style); ``reasoning`` a sentence about it."""

    exact: str
    data: Any
    reasoning: str


def compose(kind: str, text: str, images: int, seed: int) -> Reply:
    """The reply to a prompt of ``kind`` (deterministic in ``seed``)."""
    question = _field(text, "Question")
    conf = 55 + seed % 40
    yes = seed % 4 != 0  # mostly yes: episodes find things
    yn = "yes" if yes else "no"
    if kind == "probe":
        return Reply("yes", {"answer": "yes"}, "The request asks me to say yes.")
    if kind == "probe-images":
        return Reply(str(images), {"images": images}, f"I count {images} images.")
    if kind in ("explore", "explore-letters"):
        letters = _letters(text)
        order = sorted(letters, key=lambda x: hashlib.sha256(f"{seed}{x}".encode()).digest())
        confs = [max(10, conf - 25 * i) for i in range(len(order))]
        lines = [f"{x}: {c}" for x, c in zip(order[:3], confs)]
        data: dict[str, Any] = {"directions": [{"letter": x, "confidence": c}
                                               for x, c in zip(order[:3], confs)]}
        if kind == "explore":
            lines.append(f"worth exploring: {yn} {conf}")
            data["worth_exploring"] = {"answer": yn, "confidence": conf}
        return Reply("\n".join(lines), data,
                     f"Direction {order[0]} seems to lead towards where the answer may be.")
    if kind in ("explore-token", "explore-choice"):
        letter = sorted(_letters(text), key=lambda x: hashlib.sha256(f"{seed}{x}".encode()).digest())[0]
        exact = f"{letter}\n{yn}" if kind == "explore-token" else letter
        return Reply(exact, {"letter": letter}, f"Direction {letter} looks most promising.")
    if kind in ("explore-direction", "worth-token", "group", "judge-same", "confident-token"):
        if kind == "group":
            first, second = _field(text, "Answer 1"), _field(text, "Answer 2")
            yn = "yes" if first.strip().lower() == second.strip().lower() else "no"
        return Reply(yn, {"answer": yn}, "I compared what is asked with what is there.")
    if kind == "worth":
        return Reply(f"worth exploring: {yn} {conf}", {"worth_exploring": yn, "confidence": conf},
                     "The view shows part of the home the question may concern.")
    if kind in ("match", "confident"):
        return Reply(f"{yn} {conf}", {"answer": yn, "confidence": conf},
                     "I looked for what the question names in the view.")
    if kind == "sightings":
        return _sightings(text, images, seed, question)
    if kind == "blind-choice":
        letters = re.findall(r"^([A-H])[.)]", text, re.MULTILINE) or ["A"]
        letter = letters[seed % len(letters)]
        return Reply(letter, {"letter": letter}, "The most likely choice in a typical home.")
    if kind == "answer":
        said = re.search(r"at most (\d+) lines", text)
        m = int(said.group(1)) if said else 3
        answers = []
        for i in range(m):
            a = plausible_answer(question, seed + i)
            if a not in answers:
                answers.append(a)
        confs = [max(5, conf - 20 * i) for i in range(len(answers))]
        return Reply("\n".join(f"{a}; {c}" for a, c in zip(answers, confs)),
                     {"answers": [{"answer": a, "confidence": c} for a, c in zip(answers, confs)]},
                     f"The question asks {question!r}; the views suggest an answer.")
    if kind == "answer-short":
        answer = plausible_answer(question, seed)
        return Reply(answer, {"answer": answer}, f"The question asks {question!r}.")
    if kind in ("judge", "judge-openeqa"):
        score = 1 + seed % 5
        return Reply(str(score), {"score": score}, "I compared the response with the answer.")
    return Reply("I don't know.", {"answer": "I don't know."}, "I am not sure what is asked.")


SIGHTING_ROOMS = ("living room", "kitchen", "dining room", "guest bedroom", "bedroom", "bathroom",
                  "hallway", "office")  # a longer name before the one it holds


def _sightings(text: str, images: int, seed: int, question: str) -> Reply:
    """A sighting reply: the room the question names two times in three (else another), the
    first of the target's names with a box (an image) or the first listed item (a text view),
    a doorway to another room every other time."""
    named = next((r for r in SIGHTING_ROOMS if r in question.lower()), None)
    others = [r for r in SIGHTING_ROOMS if r != named]
    room = named if named is not None and seed % 3 else others[seed % len(others)]
    listed = re.search(r"^Things to look for: (.*)$", text, re.MULTILINE)
    names = re.findall(r'"([^"]+)"', listed.group(1)) if listed else []
    where: dict[str, Any] = ({"box": [250 + seed % 200, 350, 650 + seed % 200, 950]} if images
                             else {"item": 1})
    data: dict[str, Any] = {"room": room, "doorways": [], "things": []}
    if names and seed % 5:
        data["things"].append({"name": names[0], **where})
    if seed % 2 and images:
        data["doorways"].append({"room": others[(seed // 2) % len(others)],
                                 "box": [800, 300, 1000, 900]})
    return Reply(json.dumps(data), data, "I looked at the floor, the walls and the furniture.")


def styled(reply: Reply, style: str, kind: str) -> str:
    """``reply`` written in ``style`` (see ``Options``). Probes are answered exactly: a server
    writes prose to a question, not to a one-token probe."""
    if style == "exact" or kind.startswith("probe"):
        return reply.exact
    if style == "refuse":
        return "I'm sorry, but I can't help with that."
    if style == "markdown" and kind == "sightings":  # JSON is written in a code fence
        return "```json\n" + reply.exact + "\n```"
    if style == "markdown":
        lines = []
        for line in reply.exact.splitlines():
            line = re.sub(r"\b(\d{1,3})$", r"\1%", line)  # a trailing confidence as a percentage
            head, sep, rest = line.partition(":")
            lines.append(f"- **{head}**:{rest}" if sep and len(head) <= 20 else f"**{line}**")
        return "\n".join(lines)
    if style == "preamble":
        return "Sure! Here is my answer.\n" + reply.exact
    if style == "json":
        return "```json\n" + json.dumps(reply.data) + "\n```"
    return reply.reasoning + " Let me answer in the requested format.\n\n" + reply.exact


def schema_instance(schema: dict[str, Any], seed: int) -> Any:
    """A valid JSON instance of a simple schema (objects, arrays, enums, scalars)."""
    if "schema" in schema and "name" in schema:
        schema = schema["schema"]
    if "enum" in schema:
        return schema["enum"][seed % len(schema["enum"])]
    kind = schema.get("type")
    if kind == "object":
        props = schema.get("properties", {})
        return {k: schema_instance(v, seed) for k, v in props.items()}
    if kind == "array":
        return [schema_instance(schema.get("items", {}), seed)
                for _ in range(max(1, schema.get("minItems", 1)))]
    if kind == "integer":
        low, high = schema.get("minimum", 1), schema.get("maximum", 5)
        return int(low + seed % (high - low + 1))
    if kind == "number":
        return float(schema.get("minimum", 0.5))
    if kind == "boolean":
        return True
    return "yes"


# ---------------------------------------------------------------- tokens and logprobs

_TOKEN = re.compile(r" ?[A-Za-z]+| ?[0-9]+|\n+|[ \t]+|[^\sA-Za-z0-9]")


def tokens_of(text: str) -> list[str]:
    """A GPT-like split: words and numbers with their leading space, newlines, punctuation."""
    return _TOKEN.findall(text)


def _alternatives(token: str) -> list[str]:
    lead = " " if token.startswith(" ") else ""
    core = token.strip()
    if len(core) == 1 and core.isupper():
        return [lead + x for x in "ABCD" if x != core]
    if core.lower() in ("yes", "no"):
        other = "no" if core.lower() == "yes" else "yes"
        return [lead + other, lead + other.capitalize(), lead + core.capitalize()]
    if core.isdigit():
        return [lead + str(int(core) + d) for d in (1, -1, 10) if int(core) + d >= 0]
    return [lead + "the", lead + "a", "\n"]


def logprobs_content(text: str, top: int, seed: int) -> list[dict[str, Any]]:
    """Chat-style logprobs: each token's logprob and ``top`` alternatives, the token first."""
    content = []
    for i, token in enumerate(tokens_of(text)):
        h = hashlib.sha256(f"{seed}:{i}".encode()).digest()
        lp = -0.02 - 0.6 * h[0] / 255.0
        alts = [(token, lp)]
        for j, alt in enumerate(_alternatives(token)):
            if alt != token:
                alts.append((alt, math.log(max(1e-6, 1 - math.exp(lp))) - 0.7 * (j + 1)))
        content.append({"token": token, "logprob": lp, "bytes": list(token.encode()),
                        "top_logprobs": [{"token": t, "logprob": p, "bytes": list(t.encode())}
                                         for t, p in alts[:max(top, 0)]]})
    return content


# ---------------------------------------------------------------- the server

class ImageError(ValueError):
    pass


class Truncated(bytes):
    """A body of which the server sends half, then closes the connection ("truncated")."""


def check_image(part: dict[str, Any], max_side: int) -> tuple[str, int, int, str | None]:
    """An ``image_url`` part: a valid base64 PNG/JPEG data URL no larger than ``max_side``."""
    image_url = part.get("image_url")
    if not isinstance(image_url, dict) or not isinstance(image_url.get("url"), str):
        raise ImageError("image_url must be an object with a url")
    head, sep, payload = image_url["url"].partition(",")
    found = re.fullmatch(r"data:image/(png|jpeg);base64", head)
    if not sep or not found:
        raise ImageError(f"not a base64 PNG/JPEG data URL: {head[:40]!r}")
    try:
        data = base64.b64decode(payload, validate=True)
        with Image.open(io.BytesIO(data)) as image:
            image.load()
            fmt, (w, h) = (image.format or "").lower(), image.size
    except Exception as exc:
        raise ImageError(f"undecodable image: {exc}") from None
    if fmt != found.group(1):
        raise ImageError(f"data URL says {found.group(1)} but the image is {fmt}")
    if max(w, h) > max_side:
        raise ImageError(f"image {w}x{h} exceeds {max_side} px")
    detail = image_url.get("detail")
    if detail is not None and detail not in ("auto", "low", "high"):
        raise ImageError(f"unknown detail {detail!r}")
    return fmt, w, h, detail


class VLMServer:
    """The server (see the module docstring); ``options`` may be changed between requests."""

    def __init__(self, options: Options | None = None, port: int = 0) -> None:
        """``port`` 0: a free one."""
        self.options = options or Options()
        self.requests: list[Seen] = []
        self.image_errors: list[str] = []
        self._lock = threading.Lock()
        server = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def do_GET(self) -> None:
                if self.path.rstrip("/").endswith("/models"):
                    names = server.options.models or ("test-vlm",)
                    self._send(200, {"object": "list", "data": [
                        {"id": n, "object": "model", "owned_by": "test"} for n in names]})
                else:
                    self._send(404, {"error": {"message": f"no route {self.path}"}})

            def do_POST(self) -> None:
                length = int(self.headers.get("content-length") or 0)
                try:
                    body = json.loads(self.rfile.read(length) or b"{}")
                except ValueError:
                    self._send(400, {"error": {"message": "body is not JSON"}})
                    return
                headers = {k.lower(): v for k, v in self.headers.items()}
                status, payload, extra = server.answer(headers, body, self.path)
                self._send(status, payload, extra)

            def _send(self, status: int, payload: Any, extra: dict[str, str] | None = None
                      ) -> None:
                data = payload if isinstance(payload, bytes) else json.dumps(payload).encode()
                headers = {"content-type": "application/json", **(extra or {})}
                try:
                    self.send_response(status)
                    self.send_header("content-length", str(len(data)))
                    for name, value in headers.items():
                        self.send_header(name, value)
                    self.end_headers()
                    if isinstance(data, Truncated):  # half the body it announced, then closed
                        self.wfile.write(data[:len(data) // 2])
                        self.wfile.flush()
                        self.close_connection = True
                        return
                    self.wfile.write(data)
                except OSError:  # the client gave up (a hung-server test)
                    pass

            def log_message(self, *args: object) -> None:
                pass

        self._server = ThreadingHTTPServer(("127.0.0.1", port), Handler)
        self._server.daemon_threads = True
        self._thread = threading.Thread(target=self._server.serve_forever, args=(0.02,),
                                        daemon=True)
        self._thread.start()

    @property
    def base_url(self) -> str:
        return f"http://127.0.0.1:{self._server.server_port}/v1"

    def kinds(self) -> list[str]:
        return [r.kind for r in self.requests]

    def close(self) -> None:
        self._server.shutdown()
        self._server.server_close()

    # -- answering --

    @staticmethod
    def _error(status: int, message: str, kind: str = "invalid_request_error"
               ) -> tuple[int, dict[str, Any], dict[str, str]]:
        return status, {"error": {"message": message, "type": kind, "code": status}}, {}

    def answer(self, headers: dict[str, str], body: dict[str, Any], path: str
               ) -> tuple[int, Any, dict[str, str]]:
        o = self.options
        seen = Seen(headers, body)
        with self._lock:
            self.requests.append(seen)
            number = len(self.requests)
        mode = o.misbehave if o.misbehave is not None and number > o.misbehave_after else None
        if mode in BROKEN:
            return 200, BROKEN[mode], {}
        result = self._misbehave_status(mode, seen, path, o) if mode else None
        if result is None:
            result = self._answer(seen, body, path, number, o)
            if mode in REPLACED and result[0] == 200:
                kinds, _, text = REPLACED[mode]
                if seen.kind in kinds:
                    choice = result[1]["choices"][0]
                    choice["message"]["content"], choice["logprobs"] = text, None
                    seen.reply = text
            elif mode and result[0] == 200:
                result = 200, self._misbehave_reply(mode, result[1]), result[2]
        seen.status = result[0]
        return result

    def _misbehave_status(self, mode: str, seen: Seen, path: str, o: Options
                          ) -> tuple[int, Any, dict[str, str]] | None:
        """The answer of a misbehaviour that is an error or a page (``MISBEHAVIOURS``), or None
        for one that changes the reply."""
        html = {"content-type": "text/html; charset=utf-8"}
        if mode == "html":
            return 502, BAD_GATEWAY, html
        if mode == "html200":
            return 200, BROKEN["html200json"], html
        if mode == "e429":
            status, payload, _ = self._error(429, "Rate limit reached")
            return status, payload, {"Retry-After": f"{o.retry_after:g}"}
        said = f"Authorization: {seen.authorization}"
        errors = {"e500": (500, "Internal server error", "server_error"),
                  "e401": (401, "Incorrect API key provided.", "authentication_error"),
                  "echokey401": (401, f"Incorrect API key provided ({said}).",
                                 "authentication_error"),
                  "echokey500": (500, f"upstream failed on POST {path} with {said}",
                                 "server_error")}
        return self._error(*errors[mode]) if mode in errors else None

    @staticmethod
    def _misbehave_reply(mode: str, completion: dict[str, Any]) -> Any:
        """A chat completion changed as ``mode`` says (``MISBEHAVIOURS``)."""
        choice = completion["choices"][0]
        text = choice["message"]["content"]
        if mode == "listbody":
            return [1, 2, 3]
        if mode == "wrongshape":
            return {"id": completion["id"], "output": {"text": text}, "status": "ok"}
        if mode == "nochoices":
            return {**completion, "choices": []}
        if mode == "truncated":
            return Truncated(json.dumps(completion).encode())
        if mode == "nullcontent":
            choice["message"]["content"] = None
        elif mode == "lengthcut":
            choice["message"]["content"], choice["finish_reason"] = tokens_of(text)[0], "length"
        elif mode in ("huge", "xss", "ctrl"):
            changed = {"huge": text + "\n" + "filler " * ((HUGE_CHARS - len(text)) // 7),
                       "xss": XSS + text, "ctrl": CONTROL + text + "\x1b[0m\x07"}[mode]
            choice["message"]["content"] = changed
            if choice["logprobs"] and mode != "huge":
                choice["logprobs"] = {"content": logprobs_content(changed, 3, len(changed))}
        elif mode in ("badlogprobs", "underflow"):
            tokens = choice["logprobs"]["content"] if choice["logprobs"] else \
                logprobs_content(text, 3, len(text))
            odd = (math.nan, 1e308, -math.inf) if mode == "badlogprobs" else (-1000.0, -1000.5, -9999.0)
            for i, token in enumerate(tokens):
                token["logprob"] = odd[i % 3]
                for j, top in enumerate(token["top_logprobs"]):
                    top["logprob"] = odd[(i + j) % 3]
            choice["logprobs"] = {"content": tokens}
        return completion

    def _answer(self, seen: Seen, body: dict[str, Any], path: str, number: int, o: Options
                ) -> tuple[int, dict[str, Any], dict[str, str]]:
        if o.hang_s and number > o.hang_after:
            time.sleep(o.hang_s)
        if not path.rstrip("/").endswith("/chat/completions"):
            return self._error(404, f"no route {path}")
        if o.api_key is not None and seen.authorization != f"Bearer {o.api_key}":
            return self._error(401, "Incorrect API key provided.", "authentication_error")
        if number <= o.fail:
            extra = {"Retry-After": f"{o.retry_after:g}"} if o.fail_status == 429 else {}
            status, payload, _ = self._error(o.fail_status, "Rate limit reached" if
                                             o.fail_status == 429 else "Internal server error")
            return status, payload, extra
        model = str(body.get("model", ""))
        if o.models is not None and model not in o.models:
            return self._error(404, f"The model `{model}` does not exist.")
        texts, images, urls = [], [], []
        for message in body.get("messages") or []:
            content = message.get("content")
            if isinstance(content, str):
                texts.append(content)
                continue
            for part in content or []:
                if part.get("type") == "text":
                    texts.append(str(part.get("text", "")))
                elif part.get("type") == "image_url":
                    try:
                        images.append(check_image(part, o.max_side))
                        urls.append(part["image_url"]["url"])
                    except ImageError as exc:
                        self.image_errors.append(str(exc))
                        return self._error(400, f"invalid image: {exc}")
                else:
                    return self._error(400, f"unknown content part {part.get('type')!r}")
        text = "\n".join(texts)
        seen.kind, seen.images, seen.image_info = classify(text, len(images)), len(images), images
        if images and not o.images:
            return self._error(400, f"{model} is not a multimodal model")
        if o.max_images is not None and len(images) > o.max_images:
            return self._error(400, VLLM_IMAGE_LIMIT.format(n=o.max_images))
        if body.get("logprobs") and o.logprobs == "reject":
            return self._error(400, "logprobs is not supported by this model")
        top = int(body.get("top_logprobs") or 0)
        if top > 20:
            return self._error(400, "top_logprobs must be at most 20")
        fmt = body.get("response_format")
        # seeded by the request: the same prompt on another frame may get another reply
        seed = int.from_bytes(hashlib.sha256(json.dumps(
            [model, text, urls], sort_keys=True).encode()).digest()[:4], "big")
        if isinstance(fmt, dict) and fmt.get("type") == "json_schema":
            if o.json_schema == "reject":
                return self._error(400, "response_format json_schema is not supported")
            reply_text = (compose(seen.kind, text, len(images), seed).exact
                          if seen.kind == "sightings"  # an instance that says something
                          else json.dumps(schema_instance(fmt.get("json_schema") or {}, seed)))
        else:
            reply_text = styled(compose(seen.kind, text, len(images), seed), o.style, seen.kind)
        finish = "stop"
        tokens = tokens_of(reply_text)
        max_tokens = int(body.get("max_tokens") or body.get("max_completion_tokens") or 0)
        if o.cut and max_tokens and len(tokens) > max_tokens:
            reply_text, finish = "".join(tokens[:max_tokens]), "length"
        seen.reply = reply_text
        choice: dict[str, Any] = {"index": 0, "finish_reason": finish, "logprobs": None,
                                  "message": {"role": "assistant", "content": reply_text}}
        if body.get("logprobs") and o.logprobs == "return":
            choice["logprobs"] = {"content": logprobs_content(reply_text, top, seed)}
        prompt_tokens = len(tokens_of(text)) + 85 * len(images)
        return 200, {"id": f"chatcmpl-{seed:08x}", "object": "chat.completion",
                     "created": int(time.time()), "model": model, "choices": [choice],
                     "usage": {"prompt_tokens": prompt_tokens,
                               "completion_tokens": len(tokens_of(reply_text)),
                               "total_tokens": prompt_tokens + len(tokens_of(reply_text))}}, {}


@contextmanager
def servers() -> Iterator[Any]:
    """Yields ``start(options=None, **fields)``, which starts a ``VLMServer``; all are stopped
    on leaving (a pytest fixture wraps this in one ``yield``)."""
    started: list[VLMServer] = []

    def start(options: Options | None = None, **fields: Any) -> VLMServer:
        started.append(VLMServer(options or Options(**fields)))
        return started[-1]

    try:
        yield start
    finally:
        for server in started:
            server.close()
