"""The answer module's model calls (``calls``: what it asks a model; apart from the ``vc`` package).

The answer with its confidence (DESIGN 3.5, 3.6): the prompt with its hint for the question's
form, then M guesses with verbalized confidences -> normalise -> group -> argmax, or, for the
white-box baseline, one greedy answer whose confidence is its token probability. ``evidence``
is the top-K frame descriptions (best first) or the top-K RGB frames.

The direct answer reads text views cut to what the question names (``focus_views``: one view
for a count, the views that show the object for a location, the object's own colour) and, for
an existence question no view answers, a sentence saying so (``absence_note``); a count
question is told its view's count as a number (``count_note``). All read the
frame text of ``perception.semantic``, which the labels and the pixel perception share. A VLM
over images gets the image hints instead (count each object once, the colour of that object):
the views are pictures, and the VLM does the focusing itself."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from efficienteqa.models.base import ChatModel, ChatResponse, Message
from efficienteqa.question import Target, parse_question, singular
from efficienteqa.vc.grouping import Grouper, argmax, group_answers, normalise
from efficienteqa.vc.logprobs import require_logprobs
from efficienteqa.vc.numbers import to_float
from efficienteqa.vc.parse import (
    AnswerClass,
    AnswerResult,
    Candidate,
    M,
    clean_answer,
    parse_candidates,
)
from efficienteqa.vc.prompts import load_prompt
from efficienteqa.vc.usage import usage_of

PROMPTS = "efficienteqa.answer"  # answer/prompts/*.txt

# One worked example per question form, in the reply format: small models copy the kind of
# answer in the example (a place for "where", a number for "how many") more than they follow
# an instruction. The examples are about objects no synthetic question asks about.
_EXAMPLES = (
    (r"^how many\b", "How many cups are on the table?", ("2; 60", "3; 30", "1; 10")),
    (r"^what colou?r\b", "What colour is the rug in the hallway?", ("red; 60", "brown; 30",
                                                                      "beige; 10")),
    (r"^where\b", "Where is the kettle?", ("in the kitchen; 70", "in the dining room; 20",
                                           "in the hallway; 10")),
    (r"^(is|are|was|were|does|do|did|can|could|has|have)\b", "Is the window in the kitchen open?",
     ("yes; 70", "no; 30")),
    # The catch-all: "" matches every question, the empty one too ("." did not, and an empty
    # question reached the assertion below).
    (r"", "What is on the shelf in the office?", ("a book; 60", "a vase; 30", "a plant; 10")),
)


# The direct answer's one-line hint per question form (first match wins; none for other forms).
# Written on training houses 0-3 from the wrong answers of the other answer prompts: a small
# model answers a "where" with a direction, counts repeated lines as one, and names the furniture
# when asked what stands on it.
_HINTS = (
    (r"^how many\b", "A number word before that object is its count (\"three chairs\" is 3, "
                     "\"a chair\" is 1); add up the entries in that place. Answer with one "
                     "number."),
    (r"^what colou?r\b", "Answer with the colour word written just before that object's name."),
    (r"^where\b", "Answer with the room the object is in: the room named after it, or else the "
                  "room the robot is in. Not a direction."),
    (r"^is there\b", "Answer yes only if an object of that kind is listed in that room; "
                     "otherwise no."),
    (r"^(is|are)\b", "Answer yes or no from the state in brackets after that object: (on) or "
                     "(open) means yes, (off) or (closed) means no."),
    (r"^what is on\b", "Find \"on the\" or \"in the\" and that furniture in what it saw, and "
                       "answer with the object written just before those words, never the "
                       "furniture itself."),
)


# The same hints for a VLM that reads the retrieved frames as images: nothing about entries,
# brackets or words written before a name, which only the text descriptions have.
_IMAGE_HINTS = (
    (r"^how many\b", "Count that object in the images, each one once: the same object may "
                     "appear in more than one image. Answer with one number."),
    (r"^what colou?r\b", "Answer with the colour of that object as the images show it."),
    (r"^where\b", "Answer with the room the object is in (such as the kitchen or a bedroom). "
                  "Not a direction."),
    (r"^is there\b", "Answer yes only if the images show an object of that kind in that room; "
                     "otherwise no."),
    (r"^(is|are)\b", "Answer yes or no from what the images show: a lamp or screen that is lit, "
                     "or a door that stands open, means yes."),
    (r"^what is on\b", "Name the object standing on that furniture in the images, never the "
                       "furniture itself."),
)


def question_hint(question: str, modality: str = "text") -> str:
    """The direct answer's hint for the form of ``question`` ("" when no form matches), written
    for the evidence's ``modality``: "text" (frame descriptions) or "image" (RGB frames)."""
    q = question.strip().lower()
    hints = _IMAGE_HINTS if modality == "image" else _HINTS
    return next((hint for pattern, hint in hints if re.search(pattern, q)), "")


def answer_example(question: str) -> str:
    """A worked example of the reply for a question of the same form as ``question``."""
    q = question.strip().lower()
    for pattern, example, lines in _EXAMPLES:
        if re.search(pattern, q):
            return f'Example, for "{example}":\n' + "\n".join(lines)
    raise AssertionError("the last pattern matches every question")


# Words of a question that name no object: what is left names what the question is about.
_FUNCTION_WORDS = frozenset((
    "a", "an", "the", "is", "are", "was", "were", "there", "what", "which", "who", "whose", "how",
    "many", "much", "where", "when", "why", "do", "does", "did", "can", "could", "has", "have",
    "of", "on", "in", "at", "to", "from", "by", "for", "with", "around", "near", "next",
    "inside", "under", "above", "below", "this", "that", "these", "those", "it", "its", "any",
    "some", "colour", "color", "kind", "type", "room", "rooms", "house", "home"))
_ROOM_WORDS = frozenset(("kitchen", "bedroom", "bathroom", "hallway", "office", "dining",
                         "living", "guest", "laundry", "garage", "study", "corridor", "hall"))


def _words(text: str) -> set[str]:
    return {singular(w) for w in re.findall(r"[a-z]+", text.lower())}


def _stands_on(entry: str, surface: str) -> bool:
    """Whether a view entry is something standing on or in ``surface`` ("a lamp on the brown
    desk, ahead, 1.2 m", "a vase in the white bookshelf, ..."), not the surface's own entry
    ("a brown desk, ..., with a lamp on it")."""
    support = parse_entry(entry).support
    return support is not None and bool(_words(surface) & _words(support))


_BEARING = r"(?:ahead|slightly left|slightly right|on the left|on the right)"
_NUMBERS = {w: n for n, w in enumerate(("zero", "one", "two", "three", "four", "five", "six",
                                        "seven", "eight", "nine"))} | {"a": 1, "an": 1}


@dataclass(frozen=True)
class Entry:
    """One "; "-separated entry of a frame text (``perception.semantic``'s format): ``noun`` the
    object's own words without count, article or state ("white cabinet"), ``count`` the number
    before it, ``support`` what it stands on or in, ``room`` the room it is in (the robot's
    when it names none), ``text`` the entry without its "with ... on it" clause."""

    noun: str
    count: int
    support: str | None
    room: str | None
    text: str


def parse_entry(entry: str, robot_room: str | None = None) -> Entry:
    parts = entry.strip().rstrip(".").split(", ")
    head, support = parts[0], None
    bearing = re.search(rf" {_BEARING}(?: to {_BEARING})?$", head)
    if bearing:
        head = head[:bearing.start()]
    else:  # "a cup on the brown table, ahead, ...": the bearing follows the support
        rel = re.search(r" (?:on|in) the ([a-z' ]+)$", head)
        if rel:
            support, head = rel.group(1), head[:rel.start()]
    head = re.sub(r" \((?:on|off|open|closed)\)$", "", head)
    first, _, rest = head.partition(" ")
    counted = first.lower() in _NUMBERS or first.isdigit()
    count = _NUMBERS.get(first.lower(), int(first) if first.isdigit() else 1)
    rooms = [p[len("in the "):] for p in parts[1:] if p.startswith("in the ")]
    return Entry(rest if counted else head, count, support, rooms[0] if rooms else robot_room,
                 ", ".join(p for p in parts if not p.startswith("with ")))


def _robot_room(head: str) -> str | None:
    m = re.match(r"you are in the ([a-z ]+)\.?$", head.strip().lower())
    return m.group(1) if m else None


def focus_views(question: str, views: Sequence[str], target: Target | None = None) -> list[str]:
    """Each text view cut to what the question names: its first sentence (where the robot is)
    and the "; "-separated entries whose own object the question names (``Target.is_a`` on
    the entry's words, not the furniture it stands on nor what stands on it), without their
    "with ... on it" clause, so the colour word before the object's name is its own. A small
    model reads a long list of objects badly ("a yellow refrigerator" among twelve entries is
    answered "grey"). Beyond the entries:

    - a question that names a room keeps the entries in that room when any is;
    - "What is on the X?": only entries of things standing on or in X;
    - "Where is X?": only the views that show X (one view of the lamp is not outvoted by four
      views of the room the robot stood in);
    - "How many X?": only the view that shows the most X (the same chairs are seen again from
      every pose; adding views up counts them twice).

    Views are returned unchanged when no entry of any view matches, or the question names no
    object (an existence question then gets ``absence_note``). ``target``: the question's
    target (default: ``parse_question``; an agent passes its own, with resolved aliases)."""
    target = target or parse_question(question)
    wanted = _words(question) - {singular(w) for w in _FUNCTION_WORDS | _ROOM_WORDS}
    things = target.things or tuple(sorted(wanted))
    if not wanted and not target.things:
        return list(views)
    q = question.strip().lower()
    surface = target.support if target.kind == "identification" else None
    room = target.room if len(target.rooms) == 1 else None
    kept: list[tuple[str, list[Entry]]] = []
    for view in views:
        head, _, rest = view.partition(". ")
        listed = rest.split(". ")[0]  # not "Through a doorway: ..."
        listed = listed.removeprefix("Visible: ").removeprefix("Seen: ")  # focused already
        entries = [parse_entry(e, _robot_room(head)) for e in listed.split("; ") if e]
        if surface:  # what stands on X, not X itself (a small model names the furniture)
            entries = [e for e in entries if e.support is not None
                       and (target.is_a(surface, e.support) or bool(_words(surface)
                                                                    & _words(e.support)))]
        else:
            entries = [e for e in entries if any(target.is_a(t, e.noun) for t in things)
                       or (not target.things and wanted & _words(e.noun))]
        kept.append((head, entries))
    if room is not None and any(e.room == room for _, es in kept for e in es):
        kept = [(h, [e for e in es if e.room in (room, None)]) for h, es in kept]
    if not any(es for _, es in kept):
        return list(views)
    if re.match(r"^where\b", q):
        kept = [(h, es) for h, es in kept if es]
    elif re.match(r"^how many\b", q) and target.object:
        def counted(es: list[Entry]) -> int:
            return sum(e.count for e in es if target.is_a(target.object, e.noun))
        best = max(range(len(kept)), key=lambda i: (counted(kept[i][1]), -i))
        kept = [kept[best]]
    return [head + "." + (" Seen: " + "; ".join(e.text for e in es) + "." if es
                          else " Nothing the question names.") for head, es in kept]


def absence_note(question: str, views: Sequence[str], target: Target | None = None) -> str:
    """For an existence question whose object no view lists in the room it names (or in any
    room, when it names none), a plain sentence that says so ("The robot looked in the living
    room and saw no armchair there: the answer is no."), so that a small model answers "no" (it
    said "Yes" to a prompt listing the room without the object, and to one listing a sofa of
    the room next door); "" otherwise. When the views never show the named room, the sentence
    says that instead and leaves the answer to the model. ``target`` as in ``focus_views``."""
    target = target or parse_question(question)
    if target.kind != "existence" or not target.object or len(target.rooms) > 1:
        return ""
    entries = [parse_entry(e, _robot_room(head)) for head, _, rest in
               (v.partition(". ") for v in views)
               for e in rest.split(". ")[0].removeprefix("Visible: ").split("; ") if e]
    room = target.room
    if any(target.is_a(target.object, e.noun) and (room is None or e.room == room)
           for e in entries):
        return ""
    if room is None:
        return f"The robot saw no {target.object}: the answer is no."
    seen = {_robot_room(v.partition(". ")[0]) for v in views} | {e.room for e in entries}
    if room in seen:
        return (f"The robot looked in the {room} and saw no {target.object} there: "
                f"the answer is no.")
    return f"The views do not show the {room}, and no {target.object} in it."


def count_note(question: str, views: Sequence[str], target: Target | None = None,
               counted: int | None = None) -> str:
    """For a count question, the count its one focused view lists, said as a number ("The
    view lists 5 chairs: the answer is 5."): the 1.5B model read "five blue chairs" as 4 and
    "a grey chair" as 2 (syn-107-02, syn-101-02). Entries in the named room only, when the
    question names one; "" when the views list none. ``target`` as in ``focus_views``.

    ``counted``: the count of the episode's instance map (``mapping.instances.asked_count``:
    each object once over all views, around the support asked about), which the note says
    instead where the view lists another number, or none (views that are images)."""
    target = target or parse_question(question)
    if target.kind != "count" or not target.object:
        return ""
    n = _view_count(question, views, target) if views else 0
    if counted is not None and counted > 0 and counted != n:
        place = f" around the {target.support}" if target.support else (
            f" in the {target.room}" if len(target.rooms) == 1 else "")
        return (f"Counting each one once over all its views, the robot saw {counted} "
                f"{_plural(target.object, counted)}{place}: the answer is {counted}.")
    if not n:
        return ""
    return f"The view lists {n} {_plural(target.object, n)}: the answer is {n}."


def _plural(noun: str, n: int) -> str:
    if n == 1:
        return noun
    return noun + ("es" if noun.endswith(("s", "sh", "ch", "x")) else "s")


def _view_count(question: str, views: Sequence[str], target: Target) -> int:
    """The count of the question's object that its one focused view lists (0: none)."""
    focused = focus_views(question, views, target)
    if len(focused) != 1:  # nothing matched: the views were left alone
        return 0
    head, _, rest = focused[0].partition(". ")
    entries = [parse_entry(e, _robot_room(head))
               for e in rest.removeprefix("Seen: ").rstrip(".").split("; ") if e]
    room = target.room if len(target.rooms) == 1 else None
    return sum(e.count for e in entries if target.is_a(target.object or "", e.noun)
               and (room is None or e.room in (room, None)))


def evidence_text(evidence: Sequence[str | np.ndarray]) -> tuple[str, tuple[np.ndarray, ...]]:
    """The evidence as prompt text, and the images to attach (for VLMs)."""
    items = list(evidence)
    if items and all(isinstance(e, str) for e in items):
        return "\n".join(f"view {i + 1}: {e}" for i, e in enumerate(items)), ()
    images = tuple(e for e in items if isinstance(e, np.ndarray))
    if not images:
        return "nothing", images
    return ("the attached image" if len(images) == 1 else f"the {len(images)} attached images"), images


def vc_answer(model: ChatModel, prompt: str, images: tuple[np.ndarray, ...], question: str,
              grouper: Grouper, m: int, max_tokens: int) -> AnswerResult:
    """One VC call: the reply's M candidates -> normalise -> group -> argmax ``(R*, C*)``."""
    resp = model.chat([Message("user", prompt, images)], max_tokens=max_tokens, temperature=0.0)
    raw = resp.text or ""
    parsed = parse_candidates(raw, m)
    problems = list(parsed.problems)
    classes = group_answers(question, parsed.candidates, grouper, problems)
    answer, confidence = argmax(classes)
    if m == 1 and len(parsed.candidates) == 1:
        # One guess (ExploreEQA's per-step answer): normalising would make every confidence 1,
        # so its own verbalized confidence (0-100) is the confidence.
        confidence = min(max(parsed.candidates[0].confidence / 100.0, 0.0), 1.0)
    return AnswerResult(answer, confidence, classes, normalise(parsed.candidates), problems, raw,
                        usage_of(resp))


def answer_with_confidence(model: ChatModel, question: str, evidence: Sequence[str | np.ndarray],
                           grouper: Grouper, *, m: int = M, max_tokens: int = 96) -> AnswerResult:
    """The RAG answer (DESIGN 3.5): M guesses -> normalise -> group -> argmax."""
    prompt, images = _verbalized_prompt(question, evidence, m)
    return vc_answer(model, prompt, images, question, grouper, m, max_tokens)


def _verbalized_prompt(question: str, evidence: Sequence[str | np.ndarray],
                       m: int) -> tuple[str, tuple[np.ndarray, ...]]:
    """DESIGN 3.5's answer prompt for ``m`` guesses, with a worked example of the question's form."""
    text, images = evidence_text(evidence)
    prompt = load_prompt("answer", PROMPTS).format(question=question, evidence=text, m=m,
                                                   example=answer_example(question))
    return prompt, images


# How an answer's token probabilities make its confidence: "product", the probability of the
# whole answer (the default), or "per-token", their geometric mean (length-normalised: a long
# answer is not less sure for having more tokens).
ANSWER_PROBABILITY = "product"  # the default, AgentConfig.answer_probability's
ANSWER_PROBABILITIES = (ANSWER_PROBABILITY, "per-token")
# The prompt of a token-probability answer that is not the direct one (white-box ExploreEQA's
# per-frame answer): "short", one line (``answer_token``), or "verbalized", DESIGN 3.5's prompt
# with one guess, the black-box answer's (``verbalized_token_probability``).
TOKEN_ANSWER = "short"  # the default, AgentConfig.token_answer's
TOKEN_ANSWERS = (TOKEN_ANSWER, "verbalized")


def answer_token_probability(model: ChatModel, question: str,
                             evidence: Sequence[str | np.ndarray], *, hinted: bool = False,
                             max_tokens: int = 24, how: str = ANSWER_PROBABILITY,
                             target: Target | None = None,
                             counted: int | None = None) -> AnswerResult:
    """A short greedy answer; its confidence (0-1, as VC's after normalising) is the model's
    probability of that answer: the product of its tokens' probabilities, first line only
    (``how="per-token"``: their geometric mean, ``ANSWER_PROBABILITIES``). A token at -inf or
    with an unreadable (NaN) logprob makes it 0; positive logprobs (rounding) count as
    probability 1. ``hinted``: the direct answer (DESIGN 8), whose prompt adds the hint of the
    question's form (``question_hint``) and reads text views cut to what the question names
    (``focus_views``); ``target``: the agent's reading of the question, so the notes match its
    words as the gate and the steering do (an alias: "couch" is the sofa the views list);
    ``counted``: a count question's count from the episode's instance map (``count_note``),
    told to the direct answer over text views and images alike."""
    _check_how(how)
    require_logprobs(model)
    note = ""
    if hinted and evidence and all(isinstance(e, str) for e in evidence):
        views = [str(e) for e in evidence]
        note = (absence_note(question, views, target)
                or count_note(question, views, target, counted))
        evidence = focus_views(question, views, target)
    elif hinted and counted is not None:  # images: the map's count, said as a number
        note = count_note(question, [], target, counted)
    text, images = evidence_text(evidence)
    template = load_prompt("answer_direct" if hinted else "answer_token", PROMPTS)
    hint = question_hint(question, "image" if images else "text")
    prompt = template.format(question=question, evidence=text,
                             hint=f"{note}\n{hint}" if note else hint)
    if images:  # a VLM server may write a sentence or a code fence before the answer
        max_tokens = max(max_tokens, IMAGE_ANSWER_TOKENS)
    resp = model.chat([Message("user", prompt, images)], max_tokens=max_tokens, temperature=0.0,
                      logprobs=1)
    answer, line = reply_answer(resp.text or "")
    return _token_answer(resp, answer, how, end="\n", skip_lines=line)


# Room for a chatty VLM's preamble or code fence before a one-line answer over images.
IMAGE_ANSWER_TOKENS = 96
# A line that introduces the answer rather than giving it ("Sure! Here is my answer.").
_PREAMBLE = re.compile(r"^(?:sure|okay|ok|certainly|of course|here\b|based on|looking at|let me|"
                       r"from (?:the|what)|i (?:can|see|think|looked|will))", re.IGNORECASE)
_INTRODUCES = re.compile(r"\b(?:(?:let me|i will|i'll) answer|here is (?:my|the) answer|"
                         r"requested format)\b", re.IGNORECASE)
_ANSWER_LINE = re.compile(r"^(?:final )?answer\s*[:\-]\s*(.+)$", re.IGNORECASE)


def reply_answer(raw: str) -> tuple[str, int]:
    """The answer of a reply to a one-line answer prompt, cleaned of markup
    (``vc.parse.clean_answer``), and the index of the reply's line that holds it: an "answer"
    field of a JSON object, an "Answer: ..." line, else the first line that does not introduce
    the answer ("Sure! Here is my answer.", "... Let me answer in the requested format.") when
    more lines follow. A one-line reply is its own answer."""
    lines = raw.split("\n")
    body = [(i, line.strip()) for i, line in enumerate(lines)
            if line.strip() and not line.strip().startswith("```")]
    if not body:
        return "", 0
    if "{" in raw:
        try:
            data = json.loads(raw[raw.index("{"):raw.rindex("}") + 1])
        except ValueError:
            data = None
        if isinstance(data, dict) and isinstance(data.get("answer"), str):
            line = next((i for i, text in body if '"answer"' in text), body[0][0])
            return clean_answer(data["answer"]), line
    for i, text in body:
        said = _ANSWER_LINE.match(text)
        if said:
            return clean_answer(said.group(1)), i
    for n, (i, text) in enumerate(body):
        if n == len(body) - 1 or not (_PREAMBLE.match(text) or _INTRODUCES.search(text)
                                      or text.endswith(":")):
            return clean_answer(text), i
    raise AssertionError("the last line is always taken")


def verbalized_token_probability(model: ChatModel, question: str,
                                 evidence: Sequence[str | np.ndarray], *, how: str = ANSWER_PROBABILITY,
                                 max_tokens: int = 96) -> AnswerResult:
    """DESIGN 3.5's prompt with one guess ("answer; confidence", the black-box per-frame answer),
    read white-box: its confidence is the token probability of the answer before the ';'
    (``how`` as in ``answer_token_probability``), not the number the model wrote. The two
    ExploreEQA baselines then differ only in how they read confidence."""
    _check_how(how)
    require_logprobs(model)
    prompt, images = _verbalized_prompt(question, evidence, 1)
    resp = model.chat([Message("user", prompt, images)], max_tokens=max_tokens, temperature=0.0,
                      logprobs=1)
    parsed = parse_candidates(resp.text or "", 1)
    answer = parsed.candidates[0].text if parsed.candidates else ""
    result = _token_answer(resp, answer, how, end="\n;")
    return replace(result, problems=[*parsed.problems, *result.problems])


def _check_how(how: str) -> None:
    """Before any call: a reading of token probabilities that ``_token_answer`` knows."""
    if how not in ANSWER_PROBABILITIES:
        raise ValueError(f"how must be one of {ANSWER_PROBABILITIES}, not {how!r}")


def _token_answer(resp: ChatResponse, answer: str, how: str, end: str,
                  skip_lines: int = 0) -> AnswerResult:
    """``answer`` with the probability of the reply's first tokens up to one holding a character
    of ``end`` (leading whitespace skipped), after the tokens of the first ``skip_lines`` lines
    (a preamble). A token at -inf or with an unreadable (NaN) logprob makes it 0; positive
    logprobs (rounding) count as probability 1."""
    problems: list[str] = []
    logprob, started, n_tokens, newlines = 0.0, False, 0, 0
    for token in resp.logprobs or []:
        if newlines < skip_lines:
            newlines += token.token.count("\n")
            continue
        if not started and not token.token.strip():
            continue  # leading whitespace is not part of the answer (``raw.strip()``)
        ends = [token.token.find(c) for c in end if c in token.token]
        if ends and (started or not token.token[:min(ends)].strip()):
            break  # the answer ends here ("\n": its first line; ";": before the confidence)
        started = True
        value = to_float(token.logprob)
        if value is None or math.isnan(value):
            problems.append(f"unreadable probability of token {token.token!r}: confidence 0")
            value = -math.inf
        logprob += min(value, 0.0)  # a probability is at most 1; -inf (probability 0) counts
        n_tokens += 1
        if ends:
            break  # the answer's first token also ends it ("no;")
    if not resp.logprobs:
        problems.append("no logprobs in the reply: confidence 0")
    if not answer:
        problems.append("empty answer")
    if how == "per-token" and n_tokens:
        logprob /= n_tokens
    confidence = math.exp(logprob) if resp.logprobs and answer else 0.0
    candidates = [Candidate(answer, confidence)] if answer else []
    classes = [AnswerClass(answer, candidates, confidence)] if answer else []
    return AnswerResult(answer, confidence, classes, candidates, problems, resp.text or "",
                        usage_of(resp))
