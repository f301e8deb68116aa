"""The question's target, parsed once per episode: the room it names, the object it asks about,
what that object stands on or around, and the kind of question.

"What is on the nightstand in the bedroom?" -> kind "identification", object None (it is what the
robot must find), support "nightstand", room "bedroom". "How many chairs are around the table in
the dining room?" -> kind "count", object "chair", support "table", room "dining room".

The parse is rules over the question's words, written for the generator's forms and for the
way people ask (HM-EQA: typos, several sentences, "I'm looking for my X. Where is it?", room
words as modifiers). It reads the question alone, never a frame, so it serves every perception
alike (labels as text, pixels, a VLM over images); where it finds nothing, the target is empty
and every mechanism that reads it falls back to the paper's behaviour. Room names are canonical
(``ROOMS``; "study" -> "office"). ``reading/`` holds the model's reading, checked against these
rules, and the match of the target's words to what a perception names.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass
from typing import Any

# Canonical room names and the other words people use for them; the synthetic houses and
# HM-EQA's scenes name their rooms with these.
ROOMS: dict[str, tuple[str, ...]] = {
    "living room": ("lounge", "sitting room", "living area", "family room"),
    "kitchen": (),
    "dining room": ("dining area", "dining space"),
    "guest bedroom": ("second bedroom", "spare bedroom", "guest room", "spare room"),
    "bedroom": ("main bedroom", "master bedroom"),
    "guest bathroom": ("second bathroom", "guest bath"),
    "bathroom": ("washroom", "restroom", "bath room"),
    "office": ("study", "home office", "study room"),
    "hallway": ("hall", "corridor", "entrance hall", "entryway", "foyer"),
    "laundry room": ("laundry",),
    "garage": (),
    "closet": (),
}
KINDS = ("identification", "count", "existence", "state", "location", "colour", "other")

_ROOM_WORDS = sorted(((w, room) for room, words in ROOMS.items() for w in (room, *words)),
                     key=lambda t: -len(t[0]))  # longest first: "guest bedroom" before "bedroom"
_ROOM_RE = re.compile(r"\b(?:the|a|an|my|our)?\s*(" + "|".join(re.escape(w) for w, _ in _ROOM_WORDS)
                      + r")\b")


@dataclass(frozen=True)
class Target:
    """What a question points at. ``rooms``: the rooms it names (a door names two); ``object``:
    the thing asked about (None when the answer is the thing, "What is on the X?");
    ``support``: what it stands on or around ("on the X", "around the X"); ``kind``: one of
    ``KINDS``."""

    kind: str = "other"
    object: str | None = None
    support: str | None = None
    rooms: tuple[str, ...] = ()
    # (the question's words, a perception's category) pairs known to name the same thing,
    # resolved once per episode by meaning ("couch" -> "sofa"); ``is_a`` reads them.
    aliases: tuple[tuple[str, str], ...] = ()
    # Where no room is named: the rooms such an object is usually in, most likely first (a
    # prior from the language model, never from the generator's catalogue); () when unknown.
    likely_rooms: tuple[str, ...] = ()
    # Where a room is named: the rooms it is usually next to, most likely first (a prior from
    # the language model, ``reading.adjacency``, never from the generator's layouts); () when
    # not asked.
    near_rooms: tuple[str, ...] = ()

    @property
    def room(self) -> str | None:
        return self.rooms[0] if self.rooms else None

    @property
    def things(self) -> tuple[str, ...]:
        """The object categories a view must show: the object, then its support."""
        return tuple(t for t in (self.object, self.support) if t)

    def is_a(self, thing: str | None, category: str) -> bool:
        """Whether the question's words ``thing`` (its object or support) name a perceived
        object of ``category``: by the words themselves (``names``) or by a resolved alias.
        The one match the gate, the steering, the sightings and the hints all use."""
        if not thing:
            return False
        if names(thing, category):
            return True
        # an alias's category names the perceived one as words do ("sofa" -> "blue sofa")
        return any(a.lower() == thing.lower() and names(b, category) for a, b in self.aliases)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"kind": self.kind, "object": self.object,
                               "support": self.support, "rooms": list(self.rooms)}
        if self.aliases:
            out["aliases"] = [list(a) for a in self.aliases]
        if self.likely_rooms:
            out["likely_rooms"] = list(self.likely_rooms)
        if self.near_rooms:
            out["near_rooms"] = list(self.near_rooms)
        return out


def canonical_room(words: str) -> str | None:
    """The canonical name of a room word ("study" -> "office"), None if it names no room."""
    words = words.strip().lower()
    return next((room for w, room in _ROOM_WORDS if w == words), None)


def singular(noun: str) -> str:
    """A plain singular of an English noun phrase's last word ("chairs" -> "chair",
    "boxes" -> "box", "shelves" -> "shelf")."""
    head, _, last = noun.strip().rpartition(" ")
    if last.endswith("ves") and len(last) > 4:
        last = last[:-3] + "f"
    elif re.search(r"(ches|shes|xes|sses)$", last):
        last = last[:-2]
    elif last.endswith("s") and not last.endswith("ss") and len(last) > 3:
        last = last[:-1]
    return f"{head} {last}".strip()


def parse_question(question: str) -> Target:
    """The target of ``question`` (see the module docstring); an empty ``Target`` when no
    sentence of it names a thing.

    People's words, not only the generator's: typos, chat-speak and contractions are mended
    (``_TYPOS``), and one slip of the keyboard in a question or room word (``_SLIPS``: "wher",
    "dinning room"); the sentence that asks is read (the one with "?", or one with a question
    cue), less an opening ("Hey, ...", "Quick question: ...") and a request around it ("could
    you tell me ..."), and the others fill what it leaves to a pronoun ("I'm looking for my
    bag. Where is it?"; "The lamp by the bed, is it on?"), room words are taken out wherever
    they stand ("the living room TV" -> "tv" in the living room), and the things are the runs
    of content words that are left: the first is the object, the first after a place word
    ("on", "at", "next to") its support."""
    text = _normalise(question)
    rooms = tuple(dict.fromkeys(room for _, room in
                                ((m.group(1), canonical_room(m.group(1)))
                                 for m in _ROOM_RE.finditer(text)) if room))
    sentences = _sentences(text)
    asked = [s for s, q in sentences if q] or [s for s, _ in sentences if _kind(s) != "other"]
    order = asked + [s for s, _ in sentences if s not in asked]
    if not order:
        return Target("other", None, None, rooms)
    kind = _kind(order[0])
    obj, support = _things(order[0], kind)
    for s in order[1:]:  # a pronoun in the asking sentence: the thing is named elsewhere
        more = _things(s, _kind(s))
        if kind == "identification" and obj is None and support is None:
            support = more[1] or more[0]
        elif kind != "identification" and obj is None:
            obj, support = more[0], support or more[1]
    if kind == "other" and len(order) > 1:
        kind = next((k for k in map(_kind, order[1:]) if k != "other"), "other")
    if obj is None and kind != "identification":  # "is it on the X", nothing else named
        obj, support = support, None
    if kind == "identification" and obj is not None:  # "what is the TV showing": its state
        kind = "state"
    if kind == "count" and obj is not None:
        obj = singular(obj)
    return Target(kind, obj, support, rooms)


def _words(text: str, sep: str) -> list[str]:
    return text.split(sep)


# Mended before reading: contractions, and typos seen in people's questions (a wrong letter
# that makes a word of the question unreadable: "where id the stool").
_TYPOS = {"where id": "where is", "what id": "what is", "is is": "is", "bathrub": "bathtub",
          "bookselves": "bookshelves", "lefting": "leaving", "ieave": "leave", "ihow": "how",
          "entrace": "entrance", "ths": "the", "wanna": "want to", "gonna": "going to",
          "colour": "color", "can't": "cannot", "don't": "do not", "didn't": "did not",
          "i'm": "i am", "what's": "what is", "where's": "where is", "it's": "it is",
          "there's": "there is", "where it is": "where is it",
          # chat-speak
          "r": "are", "u": "you", "ur": "your", "wat": "what", "whats": "what is",
          "pls": "please", "plz": "please"}
_TYPO_RE = re.compile(r"(?<![\w'-])(" + "|".join(re.escape(k) for k in sorted(
    _TYPOS, key=len, reverse=True)) + r")(?![\w'-])")  # "u-shaped" is no "you"
# Things named with a room word ("kitchen island", "laundry basket"): kept whole, the room
# word is no room there. Other room words before a thing are where it is ("living room TV").
_ROOM_THINGS = re.compile(
    r"\b(kitchen|bathroom|office|laundry|study) (island|counter|countertop|cabinet|sink|table|"
    r"chair|stool|basket|machine|desk|lamp|vanity|mirror|item)(s?)\b")
_CLOSET_ROOM = re.compile(r"(?<![\w-])(?:in|into|inside|outside|from|to) (?:the |a |my |our )?$")
# "X has any Y": "is there Y on X" (the thing asked about is Y).
_HAS_RE = re.compile(r"\b(?:does|do|if|whether) ((?:the|this|my|our) [a-z'_ -]+?) (?:have|has) "
                     r"(?:any |some |a |an )?([a-z'_ -]+?)(?= on it\b| for\b| that\b| "
                     r"arranged\b|[,.?!;]|$)")
_ROOM_PLACE = "\x00"  # where a room phrase was: ends a thing's words
# Places that are no canonical room ("the kid's room", "the porch"): not a thing either.
_OTHER_ROOMS = re.compile(r"\b(?:the |a |my |our )?(?:[a-z]+'s room|[a-z]+ room|room|rooms|"
                          r"porch|patio|basement|attic|nursery|playroom|yard|backyard|garden)\b")
_DETERMINERS = _words("the a an any some my your his her our their its this that these those "
                "another each every all both no one ones kid's son's daughter's", " ")
_PRONOUNS = _words("it they them he she we i you me us him something anything everything nothing "
             "someone anyone somebody anybody stuff what which who whom whose where when why "
             "how there here house home apartment elsewhere", " ")
_PLACES = sorted(_words(
    "on|onto|on top of|at the top of|at|under|underneath|beneath|below|near|nearby|by|"
    "next to|beside|besides|around|above|over|behind|in front of|inside|outside|in|into|"
    "against|along|across|at the foot of|at the corner of|on the edge of|in the middle of|"
    "at the right side of|at the left side of|on the left of|on the right of|"
    "to the left of|to the right of|to the left or right of|on the left top of", "|"),
    key=len, reverse=True)  # the longest first: "on top of" before "on"
_PLACE_RE = re.compile(r"(?<![\w'-])(?:" + "|".join(re.escape(p) for p in _PLACES)
                       + r")(?![\w'-])")
# People and pets, when they do something ("my husband left", not "the dog bed").
_PEOPLE = frozenset(_words("husband wife kid kids son daughter child children dog cat friend friends "
                    "guest guests housekeeper hotel family mom dad", " "))
_ING_NOUNS = frozenset(_words("painting ceiling clothing bedding conditioning railing building ring "
                       "string swing wing lighting seating flooring", " "))
_LY_NOUNS = frozenset(_words("telly jelly belly doily lily holly butterfly assembly supply", " "))
_COLOURS = ("red|orange|yellow|green|blue|purple|pink|brown|black|white|gray|grey|beige|"
            "silver|gold|golden|navy|teal")
# Words that end or are not part of a thing's name: verbs, auxiliaries, adverbs, quantities,
# conjunctions and the conversational words around a question.
_FUNCTION = frozenset(_words(
    "is are was were be been being am do does did done have has had having can could should "
    "would will shall may might must need needs needed want wants wanted to of for from with "
    "without and or but not if so then than as about up down out away off open closed "
    "after before during since until while cannot seem seems say says "
    "leave left leaving put putting placed place placing keep kept store stored hung hang "
    "hanging moved move moving see seen saw find found locate located location look looking "
    "remember forgot forget recall trying try tried think know wonder sure check checking "
    "tell show showing help get grab retrieve bring take make made use using used going go "
    "come coming fall fell positioned installed "
    "please now currently still already again exactly right usually last recently ever yet "
    "anywhere somewhere everywhere around here there today tonight yesterday week night "
    "many much more most less few several how status color colour kind type sort side "
    "turned switched set cleaned covered pulled pushed tucked mounted leaning "
    "lying sitting ready available missing full empty clean dirty clear cleared folded "
    "fold turn unplug plug wash cook practice replace sorting bought "
    "expecting waiting playing played sleeping delivered arrived mean like also just only "
    "pieces piece pair pairs set sets stack stacks bunch pile piles couple lot lots number "
    "time day upright position top bottom left right "
    "two three four five six seven eight nine ten eleven twelve twenty dozen "
    "hey hi hello ok okay oh um uh hmm quick question", " "
) + _DETERMINERS + _PRONOUNS)


def mend(text: str) -> str:
    """``text`` in lower case with its known typos and contractions mended (``_TYPOS``), and
    a slip of the keyboard in a question or room word read as that word (``_SLIPS``)."""
    return _TYPO_RE.sub(lambda m: _TYPOS[m.group(1)], _mend_slips(text))


def _mend_slips(text: str) -> str:
    """``text`` in lower case, its words one keyboard slip from a question or room word read as
    that word (``_SLIPS``)."""
    return re.sub(r"(?<![\w'-])[a-z]+(?![\w'-])", lambda m: _SLIPS.get(m.group(0), m.group(0)),
                  " ".join(text.lower().split()))


def slips(word: str) -> set[str]:
    """How ``word`` comes out with one slip: two neighbouring letters swapped (four letters or
    more), one letter dropped or doubled (five or more)."""
    out = {word[:i] + word[i + 1] + word[i] + word[i + 2:] for i in range(len(word) - 1)}
    if len(word) >= 5:
        out |= {word[:i] + word[i + 1:] for i in range(len(word))}
        out |= {word[:i] + word[i] + word[i:] for i in range(len(word))}
    return out - {word} if len(word) >= 4 else set()


# The words a slip is read for: the question words the kind and the relations hang on, and the
# distinctive room words. Never read for a word the rules know, nor for the real words a slip of
# these spells ("round", "close"), nor where one slip fits two words; an object's name is never
# "corrected" (the rules hold no list of objects).
_SLIP_WORDS = (*_words("where which there color colour between around open closed", " "),
               *_words("living dining kitchen bedroom bathroom office hallway laundry garage "
                       "closet corridor entrance entryway foyer washroom restroom", " "))
_REAL_WORDS = frozenset(_words("round close lunge", " "))
_known = (_FUNCTION | _ING_NOUNS | _PEOPLE | _REAL_WORDS | set(_TYPOS)
          | {w for p in _PLACES for w in p.split()} | {w for t, _ in _ROOM_WORDS for w in t.split()})
_slipped = [(typed, word) for word in _SLIP_WORDS for typed in slips(word) if typed not in _known]
_fits = Counter(typed for typed, _ in _slipped)
_SLIPS = {typed: word for typed, word in _slipped if _fits[typed] == 1}


def _normalise(question: str) -> str:
    q = mend(question.replace("\u2019", "'").replace(",", " , "))
    q = re.sub(rf"\b({_COLOURS}) (and|or) ({_COLOURS})\b", r"\1_\2_\3", q)  # one thing
    q = re.sub(r"\b(trash|garbage|waste|watering) can\b", r"\1_can", q)
    q = _HAS_RE.sub(r"is there \2 on \1", q)
    q = _ROOM_THINGS.sub(lambda m: f"{m.group(1)}_{m.group(2)}{m.group(3)}", q)
    return re.sub(r"\bclosets?\b", lambda m: m.group(0) if _CLOSET_ROOM.search(q[:m.start()])
                  else m.group(0) + "_", q)  # a closet is a room only where one goes in


def thing_name(phrase: str) -> str | None:
    """The name of the first thing in ``phrase``, as the rules read one: "the bed with green
    bedding" -> "bed", "window next to dining table" -> "window"; None when it names none."""
    obj, support = _things(_normalise(phrase), "other")
    return obj or support


_ASKS = (r"(?:what|where|which|who|whose|when|why|how|is|are|was|were|do|does|did|have|has|can|"
         r"could|would|will|should)\b")
# An opening before the question ("hey, where ...", "quick question: what ...", "i need plates,
# is there ..."): a sentence of its own, which asks nothing but may name what "it" is.
_OPENING = re.compile(rf"^(?!{_ASKS})(.+?)\s*[,:]\s*(?={_ASKS})")
# A request around the question: "could you tell me what ...", "do you know which room ...".
_REQUEST = re.compile(r"^(?:please )?(?:(?:(?:can|could|would|will) you (?:please )?(?:go and )?)?"
                      r"(?:tell me|show me|let me know|find out|count(?= how\b)|(?:check|see|look)"
                      r"(?= if| whether))|(?:do|does) (?:you|anyone) know)(?: if| whether)?\s*")


def _sentences(text: str) -> list[tuple[str, bool]]:
    """The sentences of ``text`` without their end mark, each with whether it asks ("?"); an
    opening is a sentence of its own, and a request around the question is left out."""
    out = []
    for part in re.findall(r"[^.?!]+[.?!]*", text):
        asks, s = part.rstrip().endswith("?"), part.rstrip(".?! ").strip()
        if opening := _OPENING.match(s):
            out.append((opening.group(1), False))
            s = s[opening.end():]
        out.append((_REQUEST.sub("", s), asks))
    return [(s, asks) for s, asks in out if s.strip(".?! ")]


_KIND_CUES: tuple[tuple[str, str], ...] = (
    ("count", r"\bhow many\b|\bnumber of\b"),
    ("color", r"\b(?:what|which) color\b|\bcolor of\b"),
    ("location", r"^which room\b|\bin which room\b|\bwhat room\b"),
    ("state", r"^what (?:kind|type|sort) of\b|^what is the (?:status|state|condition) of\b"),
    ("identification", r"^what (?:is|are|was|did (?:\w+ ){1,2}(?:leave|put)|do we have)\b(?! it\b)"
                       r"|\banything\b|\bsomething (?:on|in|at)\b"),
    ("state", r"^what \w+ (?:is|are|do|did)\b"),
    ("location", r"\bwhere\b|\blocate\b"),
    ("state", r"\b(?:on|off|open|closed|turned on|turned off|switched on|switched off)$"
              r"|\bopen or closed\b|\bon or off\b"
              r"|\b(?:left|leave|turned|turn|switched) (?:(?:the |my )?[a-z ]+? )?(?:on|off)\b"
              r"(?! (?:the|a|an|my|top|one|any)\b)"
              r"|\bwhich\b"),
    ("existence", r"^(?:is|are|did|have|has|do|does)\b|\bthere (?:is|are)\b"),
    ("location", r"\blooking for\b|\bfind\b|\bmisplaced\b|\banywhere\b|\bsomewhere\b"),
)


def _kind(sentence: str) -> str:
    s = " ".join(_ROOM_RE.sub(" ", sentence).replace(" ,", ",").split())
    for kind, cue in _KIND_CUES:
        if re.search(cue, s):
            return "colour" if kind == "color" else kind
    return "other"


def _content(word: str, previous: str, following: str) -> bool:
    """Whether ``word`` can be part of a thing's name, knowing its neighbours."""
    if not word or word in _FUNCTION or word.startswith("@") or word == _ROOM_PLACE \
            or not re.fullmatch(r"[a-z][a-z'_-]*", word):
        return False
    if previous == "to":  # "I want to shower": a verb
        return False
    if len(word) > 4 and word.endswith("ly") and word not in _LY_NOUNS:  # "fully", "properly"
        return False
    ends = following.startswith("@") or following in (*_DETERMINERS, "and", "or", ",",
                                                       _ROOM_PLACE)
    if word.endswith("ing") and ends and word not in _ING_NOUNS:  # "covering the door"
        return False
    if len(word) > 5 and word.endswith("ed") and (ends or not following):  # "is it installed"
        return False
    return not (word in _PEOPLE and following in _FUNCTION)  # "my husband left the bag"


def _things(sentence: str, kind: str) -> tuple[str | None, str | None]:
    """The object and support of one sentence: runs of content words, the first an object,
    the first after a place word its support ("what is on the X": the support only)."""
    s = _ROOM_RE.sub(f" {_ROOM_PLACE} ", sentence)
    s = re.sub(rf"\bbetween\s+{_ROOM_PLACE}\s+and\s+{_ROOM_PLACE}", _ROOM_PLACE, s)
    s = re.sub(r"\b(?:which|what) room (?:has|is|holds|contains|should i go to)\b", "", s)
    s = re.sub(rf"(?:\broom|{_ROOM_PLACE})\s*,?\s*(?:with|where|that)\b.*$|, the ones? with\b.*$",
               f" {_ROOM_PLACE}", s)
    s = _OTHER_ROOMS.sub(f" {_ROOM_PLACE} ", s)
    s = _PLACE_RE.sub(lambda m: " @" + m.group(0).replace(" ", "_") + " ", s)
    tokens = [t for t in (w.strip(";:\"()") for w in s.split()) if t]
    runs: list[tuple[bool, str]] = []  # (after a place word, the thing's words)
    words: list[str] = []
    placed = after_place = False
    for i, w in enumerate([*tokens, _ROOM_PLACE]):
        previous = tokens[i - 1] if i else ""
        following = tokens[i + 1] if i + 1 < len(tokens) else ""
        if _content(w, previous, following):
            if not words:
                placed = after_place
            words.append(w)
            continue
        if w == _ROOM_PLACE and words and _content(following, w, ""):
            continue  # a room word inside a thing's name: "the red kitchen mat"
        if words:
            runs.append((placed, " ".join(" ".join(words).replace("_", " ").split())))
            words, after_place = [], False
        if w.startswith("@"):
            after_place = True
    objects = [t for p, t in runs if not p]
    supports = [t for p, t in runs if p]
    if kind == "identification" and supports:
        return None, supports[0]
    return (objects[0] if objects else None), (supports[0] if supports else None)


def names(thing: str, category: str) -> bool:
    """Whether the question's words ``thing`` ("red sofa", "tv", "chairs") name an object of
    ``category`` ("sofa", "TV", "chair"): equal after case and plural, or one ends with the
    other as a whole word."""
    a, b = singular(thing.lower()), singular(category.lower())
    return a == b or a.endswith(" " + b) or b.endswith(" " + a)


def perceived_words(question: str, target: Target) -> str:
    """``question`` in the words the perception uses, for the relevancy's Sim: slips of the
    keyboard in question and room words mended (``_SLIPS``), each room named by its canonical
    name ("the lounge" -> "the living room"), and each phrase the target resolved to a category
    (``Target.aliases``: "couch" -> "sofa", "tabel" -> "table") replaced by it. ``question``
    itself where that changes nothing but case: the generator's own words score as they
    always did."""
    text = _mend_slips(question.replace("\u2019", "'"))
    text = re.sub(r"\b(" + "|".join(re.escape(w) for w, room in _ROOM_WORDS if w != room)
                  + r")\b", lambda m: canonical_room(m.group(1)) or m.group(1), text)
    for words, category in sorted(target.aliases, key=lambda a: -len(a[0])):
        name = category.lower()
        many = name + ("es" if name.endswith(("s", "x", "ch", "sh")) else "s")
        text = re.sub(rf"\b{re.escape(words.lower())}(s|es)?\b",
                      lambda m: many if m.group(1) else name, text)  # noqa: B023 - used at once
    return question if text == question.lower() else text

