"""The room programme of the synthetic houses: what each room type holds and where (``Rule``),
and the surfaces small objects stand on. Data only; ``furnish`` places it in a layout. Kept
apart from the placement code so the programme reads as one table.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Rule:
    """Place one of ``categories`` (first available) ``placement``-wise, relative to ``anchor``.

    placement: "wall", "centre", "front" (in front of the anchor, same yaw), "faces" (in front,
    turned towards it), "opposite" (on the wall the anchor faces), "beside" (next to it on the
    same wall), "around" (chairs around a table), "on" (on top of the anchor), "above" (mounted
    over the anchor at the model's elevation), "ceiling" (hanging at the room centre).
    """

    categories: tuple[str, ...]
    placement: str = "wall"
    anchor: str | None = None
    count: tuple[int, int] = (1, 1)
    p: float = 1.0


R = Rule
# Alternatives cover both asset sets: the CC0 catalogue has no floor lamp, coffee table or
# bathtub (the CC-BY ones and the built-in boxes do); its stoves are hobs that sit on counters.
ROOM_RULES: dict[str, tuple[Rule, ...]] = {
    "living room": (
        R(("sofa",)), R(("coffee table",), "front", "sofa"), R(("tv stand",), "opposite", "sofa"),
        R(("tv",), "on", "tv stand"), R(("armchair",), count=(0, 2)), R(("bookshelf",), p=0.6),
        R(("floor lamp",), "beside", "sofa", p=0.8), R(("ceiling lamp",), "ceiling", p=0.6),
        R(("plant",), count=(1, 2)), R(("piano",), p=0.25),
    ),
    "kitchen": (
        R(("refrigerator",)), R(("kitchen cabinet",)),
        R(("kitchen cabinet",), "beside", "kitchen cabinet", count=(1, 3)),
        R(("stove",), "on", "kitchen cabinet"), R(("oven",), p=0.6), R(("sink",)),
        R(("wall cabinet",), "above", "kitchen cabinet", count=(1, 2)),
        R(("stool",), count=(0, 2), p=0.5), R(("plant",), p=0.3),
    ),
    "dining room": (
        R(("dining table", "table"), "centre"), R(("chair",), "around", "dining table"),
        R(("ceiling lamp",), "ceiling", "dining table", p=0.7),
        R(("cabinet", "bookshelf"), p=0.6), R(("plant",), p=0.7), R(("floor lamp",), p=0.5),
    ),
    "bedroom": (
        R(("bed",)), R(("nightstand",), "beside", "bed", count=(1, 2)),
        R(("desk lamp", "table lamp"), "on", "nightstand", p=0.8), R(("wardrobe",)),
        R(("armchair", "chair"), p=0.4), R(("plant",), p=0.5), R(("tv",), "opposite", "bed", p=0.3),
    ),
    "bathroom": (
        R(("toilet",)), R(("washbasin", "sink")), R(("shower", "bathtub")),
        R(("towel rack",), p=0.5), R(("plant",), p=0.3),
    ),
    "office": (
        R(("desk",)), R(("office chair", "chair"), "faces", "desk"),
        R(("desk lamp", "table lamp"), "on", "desk", p=0.8), R(("bookshelf",)),
        R(("whiteboard",), p=0.3), R(("armchair",), p=0.5), R(("plant",), p=0.6),
    ),
    "hallway": (
        R(("plant",), count=(1, 2)), R(("cabinet", "bookshelf"), p=0.5), R(("floor lamp",), p=0.4),
        R(("wall lamp",), p=0.5),
    ),
}
# Surfaces that get small objects, with how many.
SURFACES = ("coffee table", "dining table", "table", "kitchen cabinet", "nightstand", "desk",
            "cabinet", "tv stand", "bookshelf")
SMALL_PER_SURFACE = (0, 2)
