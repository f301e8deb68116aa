"""Every way to say a synthetic question's answer, and the values that compete with it.

The generator knows its answers exactly, so it can list what a grader must accept: category
synonyms ("tv", "television"), a number as digits or words, colour names (grey/gray), room
names, and for yes/no questions the state words ("on", "open") that mean yes. ``accepted``
gives those forms for one question; ``lexicon`` gives every value of a kind of answer, so a
grader can tell a contradicting value ("red" where the answer is blue) from a harmless word.

Kinds are the question categories (``questions.CATEGORIES``); ``location`` answers name a room
and, for objects standing on furniture, the surface.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable

from efficienteqa.envs.synthetic.colours import PALETTE
from efficienteqa.envs.synthetic.layout import ROOM_PROGRAM, SECOND_NAMES
from efficienteqa.envs.synthetic.vocabulary import LAMP_CATEGORIES, VOCABULARY

NUMBER_WORDS = ("zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine",
                "ten", "eleven", "twelve", "thirteen", "fourteen", "fifteen", "sixteen",
                "seventeen", "eighteen", "nineteen", "twenty")
YES, NO = "yes", "no"

# Other words for a category, beyond its catalogue names (vocabulary.py). A word may serve
# several categories ("lamp"): it is accepted for each and contradicts none of them.
CATEGORY_SYNONYMS: dict[str, tuple[str, ...]] = {
    "sofa": ("couch", "settee"),
    "armchair": ("arm chair", "easy chair"),
    "coffee table": ("low table", "cocktail table"),
    "bed": ("double bed", "single bed"),
    "nightstand": ("bedside table", "night table", "night stand", "bedside cabinet"),
    "wardrobe": ("closet", "armoire"),
    "dresser": ("chest of drawers",),
    "bookshelf": ("bookcase", "book shelf", "shelf", "shelves", "shelving unit"),
    "tv stand": ("tv cabinet", "tv unit", "television stand", "television cabinet", "media console"),
    "tv": ("television", "tv set", "television set", "telly"),
    "refrigerator": ("fridge",),
    "stove": ("cooker", "hob", "cooktop"),
    "microwave": ("microwave oven",),
    "range hood": ("extractor hood", "cooker hood", "extractor fan"),
    "wall cabinet": ("upper cabinet",),
    "sink": ("basin", "washbasin", "wash basin"),
    "washing machine": ("washer",),
    "dryer": ("tumble dryer", "clothes dryer"),
    "toilet": ("wc", "lavatory"),
    "bathtub": ("bath", "tub", "bath tub"),
    "shower": ("shower stall", "shower cubicle"),
    "plant": ("houseplant", "house plant"),
    "potted plant": ("plant", "houseplant", "house plant", "pot plant"),
    "flowers": ("flower", "bouquet"),
    "ceiling lamp": ("ceiling light", "pendant lamp", "pendant light", "chandelier"),
    "wall lamp": ("wall light", "sconce"),
    "ceiling fan": ("fan",),
    "rug": ("carpet", "mat"),
    "trash can": ("bin", "dustbin", "garbage can", "waste bin", "wastebasket", "trash bin"),
    "cup": ("mug",),
    "phone": ("mobile phone", "cell phone", "smartphone"),
    "telephone": ("phone",),
    "computer": ("desktop computer", "pc"),
    "laptop": ("notebook computer",),
    "coffee maker": ("coffee machine",),
    "teapot": ("kettle", "tea pot"),
    "remote control": ("remote", "tv remote"),
    "speaker": ("loudspeaker",),
    "radio": ("stereo",),
    "toy": ("toys",),
    "clock": ("wall clock",),
    "game console": ("console", "games console"),
    "headphones": ("headset",),
}
# Lamps are lamps: "a lamp" is a less precise but right name for any of them.
for _lamp in LAMP_CATEGORIES:
    CATEGORY_SYNONYMS[_lamp] = (*CATEGORY_SYNONYMS.get(_lamp, ()), "lamp")

COLOUR_SYNONYMS: dict[str, tuple[str, ...]] = {
    "grey": ("gray",), "purple": ("violet",), "beige": ("cream", "tan"),
}
# Colour words outside the palette: they contradict a palette answer ("navy" is not "grey").
OTHER_COLOURS = ("gold", "golden", "silver", "navy", "teal", "turquoise", "maroon", "ivory",
                 "cyan", "magenta", "khaki", "olive", "lavender", "burgundy", "crimson", "lilac")

ROOM_SYNONYMS: dict[str, tuple[str, ...]] = {
    "living room": ("lounge", "sitting room", "living area", "family room"),
    "kitchen": (),
    "bedroom": ("main bedroom", "master bedroom"),
    "guest bedroom": ("second bedroom", "spare bedroom", "guest room", "spare room"),
    "bathroom": ("washroom", "restroom", "bath room"),
    "guest bathroom": ("second bathroom", "guest bath"),
    "dining room": ("dining area",),
    "office": ("study", "home office", "study room"),
    "hallway": ("hall", "corridor", "entrance hall", "entryway"),
}
STATE_WORDS = {"on": ("on", "off"), "open": ("open", "closed")}  # state: (yes word, no word)


def number_forms(n: int) -> list[str]:
    """A count as digits and as a word ("2", "two")."""
    return [str(n), *([NUMBER_WORDS[n]] if 0 <= n < len(NUMBER_WORDS) else [])]


def category_forms(category: str, *names: str) -> list[str]:
    """A category's names: itself, its synonyms, its catalogue names and the given ones (the
    object's own catalogue name)."""
    return unique([category, *CATEGORY_SYNONYMS.get(category, ()), *_catalogue_names(category),
                   *names])


@functools.cache
def _catalogue_names(category: str) -> tuple[str, ...]:
    return tuple(n for n, c in VOCABULARY.items() if c == category and not any(d.isdigit() for d in n))


def room_forms(room: str) -> list[str]:
    return [room, *ROOM_SYNONYMS.get(room, ())]


def colour_forms(colour: str) -> list[str]:
    return [colour, *COLOUR_SYNONYMS.get(colour, ())]


def polarity_forms(answer: str, state: str | None = None) -> list[str]:
    """"yes"/"no", with the state word that says the same when the question asks about a state
    ("Is the lamp on?": yes = "on", no = "off"; doors: "open"/"closed")."""
    forms = [answer]
    if state in STATE_WORDS:
        yes_word, no_word = STATE_WORDS[state]
        forms.append(yes_word if answer == YES else no_word)
        if state == "open" and answer == NO:
            forms.append("shut")
    return forms


@functools.cache
def _object_names() -> tuple[str, ...]:
    names: set[str] = set(VOCABULARY.values()) | set(CATEGORY_SYNONYMS)
    names |= {s for synonyms in CATEGORY_SYNONYMS.values() for s in synonyms}
    names |= {n for n in VOCABULARY if not any(c.isdigit() for c in n)}
    names |= {"floor lamp", "table lamp", "potted plant", "door"}
    return tuple(sorted(names))


@functools.cache
def _room_names() -> tuple[str, ...]:
    rooms = {*ROOM_PROGRAM, *SECOND_NAMES.values(), "hallway"}
    return tuple(sorted({f for r in rooms for f in room_forms(r)}))


def lexicon(kind: str) -> tuple[str, ...]:
    """Every value an answer of this kind could take, in every form (for ``location``: the
    rooms; surfaces are in ``lexicon("object")``)."""
    if kind == "colour":
        return tuple(sorted({f for c in PALETTE for f in colour_forms(c)} | set(OTHER_COLOURS)))
    if kind in ("identification", "object"):
        return _object_names()
    if kind in ("location", "room"):
        return _room_names()
    if kind in ("existence", "state"):
        return (YES, NO, "on", "off", "open", "closed", "shut")
    if kind == "count":
        return tuple(f for n in range(len(NUMBER_WORDS)) for f in number_forms(n))
    raise ValueError(f"no lexicon for answers of kind {kind!r}")


def unique(forms: Iterable[str]) -> list[str]:
    return list(dict.fromkeys(f.strip().lower() for f in forms if f and f.strip()))
