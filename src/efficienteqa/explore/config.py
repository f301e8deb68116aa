"""The explore module's knobs (DESIGN 3.2-3.3, and the steering beyond the paper), a section of
the run's configuration tree (``config.run.RunConfig.explore``; fields declared with
``knobs.knob``). ``sfe`` and ``target`` hold overrides of the frontier explorer's and the
steering's constants (``SFEConfig``, ``TargetConfig``), so each is reachable by name
(``--explore.sfe.view-gain``) while those dataclasses keep their defaults in one place."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from efficienteqa.config.knobs import knob, make
from efficienteqa.explore.settings import (
    EXPLORATIONS,
    PROMPT_SETS,
    REFUSAL_RETRIES,
    SFEConfig,
    TargetConfig,
)
from efficienteqa.mapping.extent import MAP_SIZE_M, check_map_size
from efficienteqa.reading.aliases import MATCHINGS
from efficienteqa.reading.reader import READINGS

EXPLORERS = ("sfe", "frontier-only", "random")
STEERINGS = ("none", "target")
MAP_EXTENTS = ("start", "scene")


@dataclass(frozen=True)
class ExploreConfig:
    """Where the robot goes next. ``max_steps`` None: the budget the evaluation gives (DESIGN
    3.1's ``int(sqrt(floor area) * 3)``, a number only a simulated scene knows), else, on a
    robot, the same rule on the floor the map has seen so far."""

    explorer: str = knob("sfe", help="sfe (semantic frontier exploration) | frontier-only | "
                         "random; set by the method.")
    seed: int = knob(0, help="Seed of the explorer's frontier sampling.")
    max_steps: int | None = knob(None, help="Step budget (default: int(sqrt(floor area) * 3) "
                                 "of the scene's floor in evaluation; of the floor seen so far "
                                 "where the environment knows no area, as on a robot).")
    map_extent: str = knob("start", beyond=True, help="Where the map lies: start (a square of "
                           "explore.map-size-m around the start: all a robot can know) | scene "
                           "(the simulated scene's box, as runs recorded before run format 4; "
                           "needs a simulator).")
    map_size_m: float = knob(MAP_SIZE_M, beyond=True, help="Side (m) of the square map around "
                             "the start: the robot knows no house box, so its map must hold "
                             "whatever it may reach.")
    exploration: str = knob("default", beyond=True, help="The frontier explorer's options "
                            "beyond the paper: default (on) | paper (DESIGN 3.2's explorer, every "
                            "one off); explore.sfe.* sets them one by one.")
    prompts: str = knob("default", beyond=True, help="Where lettered prompt points may lie: "
                        "default (from 1 m away, so more steps ask) | paper (2-10 m, DESIGN "
                        "3.3).")
    refusal_retries: int = knob(REFUSAL_RETRIES, beyond=True, help="Re-plans within one step "
                                "after the environment refuses a move (0: a refused move spends "
                                "the step, as in the paper's set-up).")
    stop_clearance_m: float = knob(SFEConfig.stop_clearance_m, beyond=True, help="Clearance (m) "
                                   "the planner wants where a move ends (0: stop where the 3 m "
                                   "cut falls, as in the paper's set-up).")
    steering: str = knob("target", beyond=True, help="target (go to the room the question "
                         "names, inspect what it asks about, look around on entering) | none "
                         "(the paper's exploration).")
    reading: str = knob("rules+rooms", beyond=True, help="How the question's target is read: "
                        "rules (no call) | model (one call to the VLM, checked against the "
                        "question's words) | rules+rooms (the rules' target, the VLM's likely "
                        "rooms for a question naming none). Read only where the steering or a "
                        "gate reads it.")
    matching: str = knob("meaning", beyond=True, help="How the question's words match the "
                         "perception's categories: words | meaning (embeddings, and one yes/no "
                         "call to the VLM for unsure pairs).")
    sfe: Mapping[str, Any] = knob(of=SFEConfig, skip=("use_values", "stop_clearance_m"),
                                  default_factory=dict, beyond=True,
                                  help="Overrides of the frontier explorer's constants.")
    target: Mapping[str, Any] = knob(of=TargetConfig, default_factory=dict, beyond=True,
                                     help="Overrides of the steering's constants.")

    def __post_init__(self) -> None:
        if self.max_steps is not None and self.max_steps < 1:
            raise ValueError(f"max_steps must be at least 1 (or left out for the default "
                             f"budget), not {self.max_steps}")
        check_map_size(self.map_size_m)  # before any map is allocated
        if self.seed < 0:
            raise ValueError(f"seed must be 0 or more, not {self.seed}")
        if self.refusal_retries < 0:
            raise ValueError(f"refusal_retries must be 0 or more, not {self.refusal_retries}")
        if not self.stop_clearance_m >= 0:
            raise ValueError(f"stop_clearance_m must be 0 or more, not {self.stop_clearance_m}")
        for name, allowed in (("explorer", EXPLORERS), ("steering", STEERINGS),
                              ("map_extent", MAP_EXTENTS),
                              ("exploration", tuple(EXPLORATIONS)),
                              ("prompts", PROMPT_SETS), ("reading", READINGS),
                              ("matching", MATCHINGS)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"{name} must be one of {allowed}, not {getattr(self, name)!r}")

    def explorer_options(self) -> dict[str, Any]:
        """The explorer's config fields: ``exploration``'s set, the clearance, then ``sfe``'s
        overrides (frontier explorers only)."""
        if self.explorer not in ("sfe", "frontier-only"):
            return {}
        base = SFEConfig(**EXPLORATIONS[self.exploration])
        sfe = make(SFEConfig, {"stop_clearance_m": self.stop_clearance_m, **self.sfe}, base)
        return {f: getattr(sfe, f) for f in SFEConfig.__dataclass_fields__ if f != "use_values"}

    def target_config(self) -> TargetConfig:
        """The steering's constants with ``target``'s overrides."""
        return make(TargetConfig, self.target)
