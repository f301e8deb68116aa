"""The canonical category vocabulary: Sweet Home 3D catalogue names -> house object categories."""

from __future__ import annotations

# canonical category -> lower-cased catalogue names. Anything not listed is left out (vehicles,
# people, doors/windows, outdoor things, sockets...). Catalogue *source* categories in
# EXCLUDED_SOURCE_CATEGORIES are dropped even when the name matches ("Chair" under "Exterior").
_NAMES: dict[str, tuple[str, ...]] = {
    "sofa": ("couch", "sofa", "corner sofa", "winchester sofa", "clear sofa", "sofa 2 seats",
             "sofa 3 seats", "burlap sofa", "futon couch", "convertible sofa bz"),
    "armchair": ("armchair", "winchester armchair", "modern armchair", "armchair ottoman"),
    "chair": ("chair", "oak chair", "chair with cushion", "osaka chair", "folding chair",
              "plastic chair", "class seat", "child chair", "children chair", "ryokan chair"),
    "stool": ("stool", "bar stool", "bar chair", "piano bench"),
    "ottoman": ("puff",),
    "table": ("table", "oak table", "table with tablecloth", "round table", "glass table",
              "black table", "bar table", "folding table", "table on trestles", "wooden table",
              "wooden alder table", "wooden teak table", "children table"),
    "coffee table": ("coffee table",),
    "desk": ("desk", "wooden desk", "desk table", "technical table"),
    "bed": ("bed", "iron bed", "bunk bed", "child bed", "captain's bed", "mezzanine bed",
            "day bed", "futon"),
    "crib": ("baby bed", "crib"),
    "nightstand": ("bedside table",),
    "wardrobe": ("wardrobe",),
    "dresser": ("dresser with drawers", "chest", "dressing table"),
    "cabinet": ("cupboard", "filing cabinet"),
    "bookshelf": ("bookcase", "shelves", "vertical shelves", "full bookcase"),
    "tv stand": ("television cabinet", "tv stand"),
    "tv": ("tv", "tv 16:9", "wall flat tv"),
    "piano": ("grand piano", "upright piano"),
    "refrigerator": ("refrigerator", "large fridge", "fridge"),
    "freezer": ("chest freezer",),
    "stove": ("stove", "cooktop", "large stove", "propane stove", "induction cooker 2 zones",
              "induction cooker 4 zones"),
    "oven": ("oven", "double oven", "small oven"),
    "microwave": ("microwave",),
    "range hood": ("range hood", "hood"),
    "kitchen cabinet": ("drawers cabinet", "lower cabinet", "lower corner cabinet", "island",
                        "small lower cabinet", "island extension", "high cabinet"),
    "wall cabinet": ("upper cabinet", "upper corner cabinet", "small upper cabinet",
                     "upper shelves cabinet", "glass door cabinet"),
    "sink": ("washbasin", "sink", "sink cabinet", "small lavatory", "vanity", "double vanity"),
    "washing machine": ("washing machine", "clothes washing machine"),
    "dryer": ("dryer machine",),
    "toilet": ("toilets unit",),
    "bidet": ("bidet",),
    "bathtub": ("bath", "corner bathtub", "island bath"),
    "shower": ("shower stall",),
    "towel rack": ("towel rack",),
    "radiator": ("radiator",),
    "fireplace": ("fireplace",),
    "plant": ("plant", "decorative plant", "indoor plant", "spathiphyllum", "yucca", "ficus",
              "spider plant", "little plant", "bamboo", "bonsai tree"),
    "flowers": ("orchids", "tulips", "white lily", "flowers"),
    "cactus": ("cactus", "succulent plant"),
    "christmas tree": ("christmas tree",),
    "lamp": ("lamp", "little lamp", "pedestal vase lamp", "japanese lantern"),  # split by size
    "desk lamp": ("desk lamp",),
    "ceiling lamp": ("ceiling lamp", "hanging light", "pendant lamp", "chandelier lamp"),
    "wall lamp": ("wall light",),
    "ceiling fan": ("ceiling fan",),
    "fan": ("table fan", "rigged fan"),
    "rug": ("round carpet", "oriental rug", "bathmat"),
    "pool table": ("pool table",),
    "foosball table": ("football table",),
    "treadmill": ("treadmill",),
    "aquarium": ("aquarium",),
    "whiteboard": ("white board",),
    "guitar": ("electric guitar",),
    "trash can": ("dustbin", "bullet trash can", "recycling bin"),
    "suitcase": ("suitcase", "briefcase"),
    "bag": ("handbag", "backpack"),
    "clock": ("cuckoo clock", "clock"),
    "cup": ("coffee cup", "plastic cup", "cup", "coffee mug"),
    "glass": ("beer glass", "glass", "cocktail glass"),
    "bottle": ("wine bottle", "beer bottle", "bottle", "yogurt bottle", "milk", "baby bottle"),
    "book": ("book",),
    "laptop": ("laptop", "apple ibook"),
    "computer": ("apple imac 1998", "apple imac 2004"),
    "phone": ("apple iphone", "mobile phone"),
    "telephone": ("wireless phone", "phone"),
    "tablet": ("tablet",),
    "vase": ("vase",),
    "bowl": ("bowl", "bowl with fruits", "bowl with salad"),
    "fruit": ("apples",),
    "bread": ("bread",),
    "cake": ("cup cake", "birthday cake"),
    "teapot": ("teapot", "espresso kettle"),
    "coffee maker": ("coffee brewer", "coffee maker", "coffee machine", "coffee press"),
    "blender": ("mixer", "blender"),
    "toaster": ("toaster",),
    "plate": ("plate", "oval plate"),
    "candle": ("candle",),
    "teddy bear": ("teddy bear",),
    "toy": ("rocking horse", "toy train", "wood toy", "puzzle", "rubik's cube", "xylophone",
            "car model", "biplane"),
    "ball": ("basketball", "soccer ball"),
    "headphones": ("headphones",),
    "speaker": ("speaker",),
    "radio": ("radio", "mini stereo"),
    "remote control": ("tv remote control",),
    "game console": ("playstation",),
    "printer": ("inkjet printer and scanner",),
    "towel": ("towel",),
    "shoes": ("slippers", "sneakers", "woman shoes", "bootie", "mocassin"),
    "scissors": ("scissors",),
    "keyboard": ("keyboard",),
}
VOCABULARY: dict[str, str] = {n: cat for cat, names in _NAMES.items() for n in names}
EXCLUDED_SOURCE_CATEGORIES = frozenset(
    {"Exterior", "Vehicles", "Characters", "Staircases", "Doors and windows"})
SMALL_CATEGORIES: frozenset[str] = frozenset({
    "cup", "glass", "bottle", "book", "laptop", "computer", "phone", "telephone", "tablet",
    "vase", "bowl", "fruit", "bread", "cake", "teapot", "coffee maker", "blender", "toaster",
    "microwave", "plate", "candle", "flowers", "cactus", "potted plant", "table lamp",
    "desk lamp", "teddy bear", "toy", "headphones", "speaker", "radio", "remote control",
    "game console", "printer", "scissors", "clock", "fan", "keyboard"})
# Categories whose top surface holds things even without dropOnTopElevation (top = height).
SURFACE_CATEGORIES = frozenset({"table", "coffee table", "desk", "nightstand", "dresser", "cabinet",
                       "tv stand", "kitchen cabinet", "bookshelf", "freezer"})
LAMP_CATEGORIES = frozenset({"floor lamp", "table lamp", "desk lamp", "ceiling lamp", "wall lamp"})


def canonical_category(name: str, height_m: float = 1.0, elevation_m: float = 0.0) -> str | None:
    """The canonical category of a catalogue name, or None when it does not belong in a house.

    A few names are split by size (metres): lamps by height/mounting; low "tables" are coffee
    tables; small "plants" are potted plants that stand on surfaces.
    """
    cat = VOCABULARY.get(name.strip().lower())
    if cat == "lamp":  # "Lamp" covers chandeliers, floor lamps and bedside lamps alike
        cat = "ceiling lamp" if elevation_m > 1.2 else "floor lamp" if height_m >= 1.0 \
            else "table lamp"
    elif cat == "table" and height_m < 0.6:
        cat = "coffee table"
    elif cat == "plant" and height_m < 0.45:
        cat = "potted plant"
    return cat
