"""The explorer's constants as plain dataclasses, apart from the code that uses them: the
frontier detector and weights (``FrontierConfig``, DESIGN 3.2), the frontier explorer
(``SFEConfig``) and the steering by the question's target (``TargetConfig``), the named sets of
them (``EXPLORATIONS``, ``PROMPT_SETS``) and the re-plans after a refused move. Light to import
(no numpy): the configuration tree and the CLI read them to make their options
(``explore.config``); ``frontiers``, ``sfe``, ``target`` and ``module`` use them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

REFUSAL_RETRIES = 3  # re-plans within one step after a refused move
# Where lettered prompt points may lie (``explore.prompting.PROMPT_CONFIGS``): the defaults, or
# DESIGN 3.3's points 2-10 m away, 1 m apart.
PROMPT_SETS = ("default", "paper")

# DESIGN 3.2: the value terms are off for the first 2 steps (step 1 is the start view), in the
# frontier weights and in what the explore module hands the explorer.
VALUE_WARMUP_STEPS = 2


@dataclass(frozen=True)
class FrontierConfig:
    """Frontier detection and weighting constants (DESIGN 3.2 defaults; lengths in metres)."""

    # detection
    min_unexplored_neighbours: int = 3  # a frontier cell has 3-4 unexplored 8-neighbours
    max_unexplored_neighbours: int = 4
    cluster_above_cells: int = 10  # DBSCAN (min 2) only with more cells than this
    # DBSCAN eps in cells. ExploreEQA's is 1: then frontier cells along a diagonal (staircase)
    # boundary touch only corner to corner and are all dropped as noise; the edges of a view
    # wedge through a doorway are such boundaries, and 2 of 10 houses stopped exploring at
    # step 4 with most of the floor unexplored. 1.5 keeps them (8-connected groups).
    cluster_eps_cells: float = 1.5
    # Cells DBSCAN leaves isolated are noise only when alone on their stretch of the island's
    # boundary (False: all dropped, as ExploreEQA does). Along a boundary slanted at any angle but 0,
    # 45 or 90 deg (the edge of a view wedge, of the floor seen through a doorway) only one
    # cell per stair step has 3-4 unexplored neighbours, two or more cells apart, so no eps
    # below 2 links them: the whole boundary was dropped, and with nothing else left the
    # episode ended as "explored" with rooms unseen (DESIGN 3.2). Frontier-only to the
    # budget, explorer seeds house*1000+0..2: early "no frontier" stops with reachable floor
    # unseen 1/90 -> 0/90 (held-out houses 2000-2029), 1/63 -> 0/63 (training houses 0-20;
    # 2 new ones in house 11 end with all the floor reachable without passing a closed door
    # explored); explore_bench steering (held-out, 30 questions x 3) 13.28 -> 11.58 steps.
    isolated_along_boundary: bool = True
    normal_window_cells: int = 2  # half-size of the square window the outward normal averages
    # weight: exp(r_unexp/t_unexp) * exp(r_free/t_free) * exp(V/t_value) * exp(v_dir/t_dir) * exp(-d/d0)
    unexplored_ray_m: float = 3.0
    free_ray_m: float = 1.0
    value_ray_m: float = 3.0
    temp_unexplored: float = 0.2
    temp_free: float = 2.0
    temp_value: float = 0.5
    temp_dir_value: float = 0.5
    distance_scale_m: float = 10.0
    value_off_steps: int = VALUE_WARMUP_STEPS  # value terms are off while step <= this
    # close-and-facing penalty
    close_m: float = 0.5
    facing_deg: float = 30.0
    close_facing_factor: float = 1e-3


@dataclass(frozen=True)
class SFEConfig:
    """Frontier explorer constants (metres unless named otherwise)."""

    frontier: FrontierConfig = field(default_factory=FrontierConfig)
    use_values: bool = True  # False: the "frontier-only" baseline
    backoff_m: float = 1.5  # stand this far behind the frontier, against its normal
    # Planning clearance: a 0.2 m robot plus half a 0.1 m map cell, since the map cannot place
    # a wall more precisely (0.2 m ran into walls; blocked moves are reported back anyway).
    robot_radius_m: float = 0.25
    snap_m: float = 0.5  # robot off the navigable cells: snap this far, else plan at radius 0
    max_stand_shift_m: float = 1.0  # a standing point moved further than this: unreachable
    max_step_m: float = 3.0  # longest move per step, along the path
    reached_m: float = 0.3  # committed target reached within this
    vanish_m: float = 1.0  # committed frontier gone: no frontier cell within this
    face_min_m: float = 0.2  # closer to the frontier than this: keep the path direction
    # A frontier reached and looked at may keep its unexplored side (occluded behind a sofa,
    # or seen too obliquely). The close-and-facing rule cannot catch it at a 1.5 m back-off:
    # it gets a second look from the frontier itself, then is never chosen again.
    looked_m: float = 1.0
    looked_factor: float = 1e-3  # their weight, as reported
    max_looks: int = 2  # looked at this often (from the back-off, then up close): never again
    tight_radius_m: float = 0.1  # second try when nothing is reachable at robot_radius_m
    # Stop where the map leaves room: a move's end with less clearance than this is moved, by
    # at most settle_m, to a reachable cell that has it (0: stop where the path is cut). The
    # map's 0.1 m cells put a wall up to a cell nearer than it shows: ends at 0.25 m from the
    # mapped wall were refused by the environment in 7% of frontier-only steps (development
    # houses 0-9); 0.45 m left 1.3%, mostly objects the map had not seen.
    stop_clearance_m: float = 0.45
    settle_m: float = 0.25  # below reached_m: a settled end still reaches its target
    # Beyond the paper (DESIGN 8); PAPER_SFE turns every one off. Measured with explore_bench
    # steering on training houses 0-3 (12 questions x 2 explorer seeds, frontier-only / oracle
    # SFE mean steps until the evidence is in view): paper explorer 28.2 / 22.4; the defaults below
    # (skip_idle, approach_unreachable, view_gain) 22.3 / 18.0, floor covered 63% -> 79%.
    # Options measured and dropped: docs/exploration.md, "Tried and dropped".
    # When no frontier is left to choose (none has a reachable cell within max_stand_shift_m
    # of its standing point, as a sliver of floor seen through a doorway, or every one was
    # looked at max_looks times), head for the reachable cell nearest one's standing point,
    # however far, instead of ending the episode with budget left: going closer maps the way
    # in (False: "no reachable frontier" ends it, as in the paper).
    approach_unreachable: bool = True
    # Where a move ends, turn to the view wedge (the explored window: +-view_half_deg out to
    # view_range_m) with the most unexplored cells in sight, unless facing the frontier sees
    # at least view_keep_share of that (False: face the frontier, as the paper): on arrival the
    # robot looks into the unseen part of the room, not at a sliver behind a chair.
    view_gain: bool = True
    view_range_m: float = 5.0
    view_half_deg: float = 40.0
    view_keep_share: float = 0.8
    # A decision that would take the same view again (stay within reached_m, turn less than
    # idle_turn_deg) counts as a look at its frontier and is made again (False: such a step
    # is spent, as the paper's loop would).
    skip_idle: bool = True
    idle_turn_deg: float = 30.0
    idle_retries: int = 4
    # A standing point must see its frontier: no mapped obstacle on the straight line between
    # them. Backing off 1.5 m from a frontier in a 1.6 m hallway crosses its wall, and the
    # nearest reachable cell was then a room off the hallway, facing the wall (house 0's README
    # question spent 6 of its first 10 steps so). The longest clear back-off wins; a frontier
    # with none keeps the plain rule (False: the plain rule, as the paper).
    stand_in_sight: bool = True


# DESIGN 3.2's explorer: every SFEConfig option beyond it off (the paper preset; the stepping
# options stop_clearance_m and the refusal retries are set apart, by AgentConfig).
PAPER_SFE: dict[str, Any] = {"skip_idle": False, "approach_unreachable": False,
                             "view_gain": False, "stand_in_sight": False}

# The frontier explorer's constants that are ExploreEQA's SFE, as the paper uses it (DESIGN 3.2:
# frontier detection, the weight's rays and temperatures, the close-and-facing penalty, the
# 1.5 m back-off and the 3 m move); every other one is the project's (``--help-all`` says which).
PAPER_SFE_CONSTANTS = frozenset({
    "frontier.min_unexplored_neighbours", "frontier.max_unexplored_neighbours",
    "frontier.cluster_above_cells", "frontier.normal_window_cells", "frontier.unexplored_ray_m",
    "frontier.free_ray_m", "frontier.value_ray_m", "frontier.temp_unexplored",
    "frontier.temp_free", "frontier.temp_value", "frontier.temp_dir_value",
    "frontier.distance_scale_m", "frontier.value_off_steps", "frontier.close_m",
    "frontier.facing_deg", "frontier.close_facing_factor", "use_values", "backoff_m",
    "max_step_m"})

# The frontier explorer's named option sets: the defaults, or the paper's (every option beyond
# DESIGN 3.2 off).
EXPLORATIONS: dict[str, dict[str, Any]] = {"default": {}, "paper": PAPER_SFE}


@dataclass(frozen=True)
class TargetConfig:
    """``inspect_m``: the distance to stand from a thing to inspect it, by question kind
    (a count group must fit in one frame; a small item on a surface needs to be near);
    ``merge_m``: sightings of one category this close are one thing; ``room_tries``: steps
    spent heading for the named room without entering it before giving up on it for
    ``room_rest`` steps; ``inspect_tries``: steps spent on one inspection at most."""

    inspect: bool = True
    look_around: bool = True
    go_to_room: bool = True
    end_search: bool = True
    inspect_m: dict[str, float] = field(default_factory=lambda: {
        "identification": 1.3, "count": 2.4, "default": 1.8})
    merge_m: float = 0.6
    reached_m: float = 0.4
    room_tries: int = 6
    room_rest: int = 6
    inspect_tries: int = 4
    min_room_cells: int = 10
    # Frontier weights by the room the frontier lies in: x in_target in the named room,
    # x elsewhere in a room the frames named that is not it (a bathroom cannot hold the
    # office's desk), unchanged in connecting rooms (CONNECTORS) and where no frame named one.
    room_prior: bool = True
    in_target: float = 100.0
    elsewhere: float = 1e-6
    frontier_room_m: float = 0.5  # a frontier's room: the most seen floor this close
    # A frontier also has the room ahead_m beyond it on its unexplored side: none seen there
    # (a doorway into unseen rooms) keeps its weight where one inside a room seen is ruled
    # out (0: by the room it lies in alone, as before).
    ahead_m: float = 0.0
    here_m: float = 1.0  # the robot's room: the most seen floor this close (none under it)
    # While the named room is unseen, look around in a hallway (CONNECTORS), at points at
    # least scan_apart_m apart: doorways along it show the rooms they lead to. Off: on training
    # houses 0-20 (50 room-naming questions, explore_bench steering, one explorer seed, stop
    # off) first sight came at 2.70x the oracle without these look-arounds against 2.87x with
    # them (sooner in 20 questions, later in 3): the frontier moves along a hallway show its
    # doorways anyway.
    scan_connectors: bool = False
    scan_apart_m: float = 4.0
    # A room is searched once its views covered search_coverage of it (mapping.coverage: the
    # explored share of the hull of its seen floor; 0: after one look-around, as before), or
    # after search_moves further viewpoints, each search_view_m from the centre of the part
    # not yet covered; a viewpoint that raised the coverage by less than search_gain ends it
    # (the rest is out of sight, behind a bathtub). Training houses 0-20, 21 "no" existence
    # questions: one look-around covers 0.74-0.97 (median 0.87); 0.85 sends the rooms below
    # it to further viewpoints (mean steps 11.1 -> 11.9 before the gain rule).
    search_coverage: float = 0.85
    search_moves: int = 3
    search_view_m: float = 1.5
    search_gain: float = 0.02
    # Where the question names no room: search the rooms of Target.likely_rooms in their order
    # (``goal_room``) as a named room is searched (False: the frontiers alone).
    likely_rooms: bool = True
    # Look up (no tilt in this environment: from further back): for a thing hung from the
    # ceiling the move into the named room ends overhead_view_m from its middle, facing it,
    # where the top of the view (TOP_OF_VIEW_DEG) reaches a ceiling 1.1 m above the camera.
    look_up: bool = True
    overhead_view_m: float = 2.8
    # Glance through doors: while the room to search is unseen, walk to the nearest door whose
    # far side no frame has shown (``Sightings.doors``, merged within door_merge_m) and stand
    # glance_m before it, facing it, so that the frame names the room beyond before any step is
    # spent in it; a door is glanced once the robot stood so (or after glance_tries moves), or
    # once floor of two rooms was seen within door_side_m of it.
    glance: bool = False
    glance_m: float = 1.2
    glance_tries: int = 3
    door_merge_m: float = 1.0
    door_side_m: float = 1.2
    # Rooms next to the named one: while it is unseen, a frontier in a room the language model
    # says is usually next to it (``Target.near_rooms``, ``reading.adjacency``: one call per
    # room type) is not ruled out (weight 1, as in a hallway): the way there may lead through
    # it (False: only hallways lead on).
    near_rooms: bool = False
    # After a move of the steering's own, the frontier explorer chooses afresh instead of
    # keeping the frontier it committed to before (False: it keeps it, as before).
    fresh_frontier: bool = True
