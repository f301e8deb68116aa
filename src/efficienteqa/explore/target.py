"""Steering by the question's target (beyond the paper, DESIGN 9): go where the question points,
look closely, and say when the named room is searched.

A frontier explorer chooses among the edges of the known map; nothing makes it enter the room a
question names or walk up to the shelf it asks about. ``TargetExplorer`` wraps one and, while
the perception reports what frames show of rooms and of the target's things (``Sightings``),
takes these steps before any frontier, first that applies:

1. **inspect**: a thing of the target in view (the surface of "What is on the X?", the table of a
   count, the object otherwise) that the robot has not yet stood before: go to a pose
   ``inspect_m`` from it (further for count groups, and for things above the tilted view) and
   face it; once.
2. **look around**: on entering the named room (after one move towards its middle), turn twice
   by 120 degrees (a step each); then, until the views have covered ``search_coverage`` of the
   room's seen floor (the map's explored cells among the cells frames showed as its floor),
   go to further viewpoints facing the floor not yet covered (``search_moves`` at most); the
   room is then searched. While
   the named room is unseen, the robot also looks around in a hallway (``CONNECTORS``), at
   points ``scan_apart_m`` apart (``scan_connectors``, off by default).
3. **go to the room**: the named room's floor seen (through a doorway, past a hallway) and the
   robot not in it: head for the reachable cell of that floor nearest its middle.
4. **search ends**: for "Is there an X in the R?", the named room searched without the X in
   view: ``done`` with reason "searched" (the robot answers from what it saw).
5. **glance** (``glance``, off: it measured the same): while the room to search is unseen, stand
   ``glance_m`` before the nearest door whose far side no frame has shown (``Sightings.doors``),
   facing it.

No move is returned that would take the view the robot already holds (``_new_view``, one
idle check for every move above and the frontier explorer's): such a move is dropped and the
next rule decides; a way to the named room that ends where the robot stands rests the room
for ``room_rest`` steps, and a frontier choice that stays turns the robot by 120 degrees.

Where the question names no room, the rooms of ``Target.likely_rooms`` (a prior from the
language model) are searched one by one as a named room is (``goal_room``): the most likely one
a frame has shown first; their frontiers weigh more, but no room is ruled out.

Otherwise the wrapped frontier explorer decides, its frontiers weighted by their room
(``room_prior``): x1e-6 in a room the question rules out, x100 in the named one. Whenever the
perception gives no sightings, the semantic values of its verbalized confidence steer the
frontier explorer alone. A VLM over images supplies the same ``Sightings`` from one call per
step (``perception.sightings``: the room in view, the doorways' rooms and boxes around the
target's things, back-projected with the depth), as the pixel perception does from its classes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from efficienteqa.explore.base import Decision, Frontier
from efficienteqa.explore.room_floors import RoomFloors
from efficienteqa.explore.settings import TargetConfig
from efficienteqa.explore.sfe import FrontierExplorer, cut_path, idle, settle
from efficienteqa.geometry import Pose2D, wrap_angle
from efficienteqa.mapping.coverage import hull_mask, room_coverage
from efficienteqa.mapping.grid import GridSpec
from efficienteqa.mapping.state import MapState
from efficienteqa.perception.base import Sighting, Sightings
from efficienteqa.question import Target

CAMERA_HEIGHT_M = 1.5
CONNECTORS = frozenset({"hallway"})  # rooms that lead to others: never ruled out
TOP_OF_VIEW_DEG = 22.0  # 30 deg down, half the 104 deg vertical field of view up
OVERHEAD_WORDS = ("ceiling", "chandelier", "pendant")  # words of things hung from the ceiling


@dataclass
class _Door:
    xy: np.ndarray
    room: str | None  # the room seen through it, where the perception says
    glanced: bool = False
    tries: int = 0


@dataclass
class _Thing:
    category: str
    xy: np.ndarray
    top_m: float
    room: str | None
    inspected: bool = False
    tries: int = 0


class TargetExplorer:
    """A frontier explorer steered by the question's target (module docstring)."""

    name = "target"

    def __init__(self, frontier: FrontierExplorer, config: TargetConfig | None = None) -> None:
        self.frontier = frontier
        self.config = config or TargetConfig()
        if self.config.room_prior:
            frontier.prior = self._room_prior
        self.reset(0)

    def reset(self, seed: int) -> None:
        self.frontier.reset(seed)
        self.target = Target()
        self.floors = RoomFloors()  # the floor each room showed
        self._things: list[_Thing] = []
        self._doors: list[_Door] = []
        self._looks: list[float] = []  # yaws still to look at, in the named room
        self._searched: set[str] = set()
        self._room_steps = 0
        self._room_rest_until = 0
        self._object_seen = False
        self._centred: set[str] = set()  # rooms entered with a move towards their middle
        self._looked_around: set[str] = set()  # rooms looked around in
        self._search_moves: dict[str, int] = {}  # room -> further viewpoints taken in it
        self._search_covered: dict[str, float] = {}  # room -> its coverage at the last one
        self._scans: list[np.ndarray] = []  # where the robot looked around in a hallway

    def set_target(self, target: Target) -> None:
        self.target = target

    # ----- what the frames showed ------------------------------------------------------------
    def see(self, spec: GridSpec, seen: Sightings) -> None:
        """Fuse one frame's sightings: the floor of each room in view, the target's things."""
        self.floors.add(spec, seen.floor)
        for s in seen.things:
            self._add_thing(s)
        for d in seen.doors:
            xy = np.asarray(d.xy, float)
            known = next((k for k in self._doors
                          if np.linalg.norm(k.xy - xy) <= self.config.door_merge_m), None)
            if known is None:
                self._doors.append(_Door(xy, d.room))
            elif known.room is None:
                known.room = d.room

    def _add_thing(self, s: Sighting) -> None:
        if (self.target.is_a(self.target.object, s.category)
                and (self.target.room is None or s.room == self.target.room)):
            self._object_seen = True  # in the named room, as the frame says
        xy = np.asarray(s.xy, float)
        for t in self._things:
            if t.category == s.category and np.linalg.norm(t.xy - xy) <= self.config.merge_m:
                t.room = t.room or s.room
                t.top_m = max(t.top_m, s.top_m)
                return
        self._things.append(_Thing(s.category, xy, s.top_m, s.room))

    def room_at(self, xy: tuple[float, float], within_m: float = 0.0) -> str | None:
        """The room whose seen floor holds the point, or the most of it within ``within_m``."""
        return self.floors.room_at(xy, within_m)

    def goal_room(self) -> str | None:
        """The room to search now: the named one; where none is named (``likely_rooms``), the
        most likely room not yet searched among those a frame showed, else the most likely
        one not searched (its frontiers weigh more until it is seen); None when none is left."""
        if self.target.room is not None or not self.config.likely_rooms:
            return self.target.room
        left = [r for r in self.target.likely_rooms if r not in self._searched]
        seen = [r for r in left if self.floors.size(r) >= self.config.min_room_cells]
        order = seen or left
        return order[0] if order else None

    def _room_prior(self, frontiers: list[Frontier]) -> np.ndarray:
        """Each frontier's weight factor by its room (``TargetConfig.room_prior``): a room the
        question names rules the others out; a likely room does not."""
        room, cfg = self.goal_room(), self.config
        out = np.ones(len(frontiers))
        if room is None:
            return out
        named = self.target.room is not None
        # rooms next to the named one lead there while it is unseen (TargetConfig.near_rooms)
        leads = (set(self.target.near_rooms) if cfg.near_rooms
                 and self.floors.size(room) < cfg.min_room_cells else set())
        for k, f in enumerate(frontiers):
            here = self.room_at(f.xy, cfg.frontier_room_m)
            ahead = here
            if cfg.ahead_m > 0:  # the room on the unexplored side, None where no frame showed one
                ahead = self.room_at((f.xy[0] + cfg.ahead_m * f.normal[0],
                                      f.xy[1] + cfg.ahead_m * f.normal[1]), cfg.frontier_room_m)
            if room in (here, ahead):
                out[k] = cfg.in_target
            elif (named and here is not None and ahead is not None
                  and here not in CONNECTORS and here not in self.target.rooms
                  and here not in leads):
                out[k] = cfg.elsewhere
        return out

    @property
    def searched(self) -> frozenset[str]:
        return frozenset(self._searched)

    # ----- deciding -----------------------------------------------------------------------------
    def decide(self, state: MapState, pose: Pose2D, values: np.ndarray | None,
               step: int) -> Decision:
        decision = self._steer(state, pose, values, step)
        if self.config.fresh_frontier and decision.frontier is None and not decision.done:
            self.frontier.forget()  # a move of its own: the next frontier is chosen afresh
        return decision

    def _steer(self, state: MapState, pose: Pose2D, values: np.ndarray | None,
               step: int) -> Decision:
        cfg, room = self.config, self.goal_room()
        here = self.room_at((pose.x, pose.y), cfg.here_m)
        if cfg.inspect:
            decision = self._inspect(state, pose)
            if decision is not None:
                return decision
        if room is not None and here == room and room not in self._searched:
            decision = self._search(state, pose, room)
            if decision is not None:
                return decision
            self._searched.add(room)
        if (cfg.scan_connectors and room is not None and here in CONNECTORS
                and self.floors.size(room) < cfg.min_room_cells
                and all(np.linalg.norm(pose.xy - p) > cfg.scan_apart_m for p in self._scans)):
            self._scans.append(pose.xy.copy())  # the named room unseen: look down the hallway
            self._looks = [pose.yaw + math.radians(120), pose.yaw + math.radians(240)]
        if (self._looks and here != room and room is not None
                and self.floors.size(room) >= cfg.min_room_cells):
            self._looks = []  # the named room came into view: no need to look further
        if self._looks and here != room:
            decision = self._look(pose)
            if decision is not None:
                return decision
        if (cfg.end_search and self.target.room is not None and room in self._searched
                and self.target.kind == "existence" and not self._object_seen):
            return Decision(pose, pose.xy[None, :].copy(), reason="searched", done=True)
        if (cfg.go_to_room and room is not None and here != room and room not in self._searched
                and step >= self._room_rest_until):
            decision = self._to_room(state, pose, room, step)
            if decision is not None:
                return decision
        if cfg.glance and room is not None and self.floors.size(room) < cfg.min_room_cells:
            decision = self._glance(state, pose)
            if decision is not None:
                return decision
        decision = self.frontier.decide(state, pose, values, step)
        if decision.done or self._new_view(decision, pose) is not None:
            return decision
        # The frontiers offer only the view the robot holds (every retry idle): turn instead.
        yaw = float(wrap_angle(pose.yaw + math.radians(120)))
        return Decision(Pose2D(pose.x, pose.y, yaw), pose.xy[None, :].copy(),
                        frontiers=decision.frontiers, weights=decision.weights, reason="turn")

    def _search(self, state: MapState, pose: Pose2D, room: str) -> Decision | None:
        """The next move of searching ``room``, where the robot stands; None once searched: one
        move towards its middle, a look-around, then (``search_coverage``) views from further
        points, each facing the room's floor not yet covered, until that share is covered."""
        cfg = self.config
        if room not in self._centred:  # one move towards the middle of the room
            self._centred.add(room)
            middle = self.floors.middle(state.spec, room)
            # a thing on the ceiling (at its middle, as a rule) is above the view from near it
            back_m = cfg.overhead_view_m if cfg.look_up and self._overhead() else 0.0
            if abs(np.linalg.norm(middle - pose.xy) - back_m) > 1.0 or back_m > 0:
                goal = self._stand_near(state, pose, middle, back_m, room)
                decision = None if goal is None else self._new_view(
                    self._move(state, pose, goal, middle, "into the " + room), pose)
                if decision is not None:
                    return decision
        if cfg.look_around and room not in self._looked_around:
            self._looked_around.add(room)
            self._looks = [pose.yaw + math.radians(120), pose.yaw + math.radians(240)]
        decision = self._look(pose)
        if decision is not None or cfg.search_coverage <= 0:
            return decision
        moves = self._search_moves.get(room, 0)
        covered = self.coverage(state, room)
        before = self._search_covered.get(room, -1.0)
        if (moves >= cfg.search_moves or covered >= cfg.search_coverage
                or covered - before < cfg.search_gain):  # the last viewpoint added nothing
            return None
        self._search_moves[room] = moves + 1
        self._search_covered[room] = covered
        uncovered = hull_mask(self.floors.cells[room]) & ~state.explored & ~state.occupied
        gap = state.spec.cell_to_world(np.argwhere(uncovered)).mean(axis=0)
        goal = self._stand_near(state, pose, gap, cfg.search_view_m, room)
        decision = None if goal is None else self._new_view(
            self._move(state, pose, goal, gap, "search the " + room), pose)
        if decision is None:  # no closer point: turn to the floor not yet covered
            yaw = math.atan2(gap[1] - pose.y, gap[0] - pose.x)
            decision = self._new_view(Decision(Pose2D(pose.x, pose.y, yaw),
                                               pose.xy[None, :].copy(),
                                               reason="search the " + room), pose)
        return decision

    def _overhead(self) -> bool:
        """Whether the question's object hangs from the ceiling: by its words ("ceiling lamp"),
        or a sighting of it whose top is above the camera."""
        obj = self.target.object
        if obj is None:
            return False
        if any(w in obj.lower().split() for w in OVERHEAD_WORDS):
            return True
        return any(self.target.is_a(obj, t.category) and t.top_m > CAMERA_HEIGHT_M
                   for t in self._things)

    def coverage(self, state: MapState, room: str) -> float:
        """How much of ``room`` its views covered (``mapping.coverage.room_coverage``: the
        explored share of the hull of its floor seen so far)."""
        cells = self.floors.cells.get(room)
        return 0.0 if cells is None else room_coverage(cells, state.explored, state.occupied)

    def _new_view(self, decision: Decision | None, pose: Pose2D) -> Decision | None:
        """``decision`` unless it would take the view the robot holds (within the frontier
        explorer's ``reached_m`` and ``idle_turn_deg``): the one idle check of every move."""
        fr = self.frontier.config
        if decision is None or idle(decision.pose, pose, fr.reached_m, fr.idle_turn_deg):
            return None
        return decision

    def _look(self, pose: Pose2D) -> Decision | None:
        """The next turn of a look-around that shows a new view (the others are dropped)."""
        while self._looks:
            yaw = float(wrap_angle(self._looks.pop(0)))
            decision = self._new_view(Decision(Pose2D(pose.x, pose.y, yaw),
                                               pose.xy[None, :].copy(), reason="look around"),
                                      pose)
            if decision is not None:
                return decision
        return None

    def _inspect(self, state: MapState, pose: Pose2D) -> Decision | None:
        wanted = self._inspected_things()
        for thing in wanted:
            if thing.inspected:
                continue
            distance = self._inspect_distance(thing)
            gap = float(np.linalg.norm(pose.xy - thing.xy))
            facing = abs(float(wrap_angle(math.atan2(thing.xy[1] - pose.y, thing.xy[0] - pose.x)
                                          - pose.yaw)))
            if (abs(gap - distance) <= self.config.reached_m + 0.3 and facing < math.radians(20)
                    ) or thing.tries >= self.config.inspect_tries:
                thing.inspected = True
                continue
            goal = self._stand_near(state, pose, thing.xy, distance, thing.room)
            if goal is None:
                thing.inspected = True
                continue
            thing.tries += 1
            decision = self._new_view(
                self._move(state, pose, goal, thing.xy, "inspect " + thing.category), pose)
            if decision is None:
                thing.inspected = True  # this view again: nothing more to see from here
                continue
            return decision
        return None

    def _glance(self, state: MapState, pose: Pose2D) -> Decision | None:
        """A look through the nearest door whose far side is unknown (``TargetConfig.glance``):
        a pose ``glance_m`` before it on this side, facing it; None when every door known is
        glanced."""
        cfg = self.config
        fr = self.frontier.config
        grid = state.island_grid
        dist = grid.distance_field((pose.x, pose.y), self._radius(state, pose), fr.snap_m)
        open_doors = []
        for door in self._doors:
            if door.glanced:
                continue
            gap = float(np.linalg.norm(pose.xy - door.xy))
            facing = abs(float(wrap_angle(math.atan2(door.xy[1] - pose.y, door.xy[0] - pose.x)
                                          - pose.yaw)))
            if ((gap <= cfg.glance_m + cfg.reached_m + 0.3 and facing < math.radians(30))
                    or door.tries >= cfg.glance_tries or door.room is not None
                    or len(self.floors.near(door.xy, cfg.door_side_m)) >= 2):
                door.glanced = True  # seen through, tried enough, or both sides known
                continue
            i, j = state.spec.world_to_cell(door.xy)
            far = float(dist[i, j]) if state.spec.contains((i, j)) else np.inf
            open_doors.append((far if np.isfinite(far) else 1e3 + gap, door))
        for _, door in sorted(open_doors, key=lambda t: t[0]):
            door.tries += 1
            goal = self._stand_near(state, pose, door.xy, cfg.glance_m, None)
            decision = None if goal is None else self._new_view(
                self._move(state, pose, goal, door.xy, "glance through a door"), pose)
            if decision is not None:
                return decision
            door.glanced = True  # no new view towards it from here
        return None

    def _inspected_things(self) -> list[_Thing]:
        """The things worth walking up to, in the named room when the frame said which room:
        the support for identification and count questions, else the object."""
        t = self.target
        key = t.support if t.kind in ("identification", "count") and t.support else t.object
        if key is None:
            return []
        return [x for x in self._things if t.is_a(key, x.category)
                and (t.room is None or x.room in (None, t.room) or t.object == "door")]

    def _inspect_distance(self, thing: _Thing) -> float:
        table = self.config.inspect_m
        distance = table.get(self.target.kind, table["default"])
        above = thing.top_m - CAMERA_HEIGHT_M
        if above > 0:  # a ceiling lamp: far enough back for the top of the view to reach it
            distance = max(distance, above / math.tan(math.radians(TOP_OF_VIEW_DEG - 4)))
        return distance

    def _to_room(self, state: MapState, pose: Pose2D, room: str, step: int) -> Decision | None:
        cells = self.floors.cells.get(room)
        if cells is None or cells.sum() < self.config.min_room_cells:
            return None
        self._room_steps += 1
        if self._room_steps > self.config.room_tries:  # the way in is not found: rest
            self._room_steps = 0
            self._room_rest_until = step + self.config.room_rest
            return None
        middle = self.floors.middle(state.spec, room)
        goal = self._stand_near(state, pose, middle, 0.0, room)
        decision = None if goal is None else self._new_view(
            self._move(state, pose, goal, middle, "to the " + room), pose)
        if decision is None:  # no way in from here: rest, so the frontiers take it elsewhere
            self._room_steps = 0
            self._room_rest_until = step + self.config.room_rest
        return decision

    def _stand_near(self, state: MapState, pose: Pose2D, xy: np.ndarray, distance_m: float,
                    room: str | None) -> np.ndarray | None:
        """A reachable cell about ``distance_m`` from ``xy`` (in ``room`` when the map knows it
        and such cells exist), the nearest to the robot by path; None if nothing is reachable."""
        fr = self.frontier.config
        grid = state.island_grid
        start = (pose.x, pose.y)
        radius = self._radius(state, pose)
        dist = grid.distance_field(start, radius, fr.snap_m)
        ok = grid.navigable(radius) & np.isfinite(dist)
        if not ok.any():
            return None
        cells = np.argwhere(ok)
        centres = state.spec.cell_to_world(cells)
        off = np.abs(np.linalg.norm(centres - xy, axis=1) - distance_m)
        if room is not None and room in self.floors.cells:
            inside = self.floors.cells[room][cells[:, 0], cells[:, 1]]
            if inside.any():
                off = np.where(inside, off, off + 2.0)
        cost = off + 0.1 * dist[cells[:, 0], cells[:, 1]]
        return centres[int(np.argmin(cost))]

    def _radius(self, state: MapState, pose: Pose2D) -> float:
        """The planning radius: the robot's, or 0 where its own cell is too tight for it."""
        fr = self.frontier.config
        fits = state.island_grid.snap((pose.x, pose.y), fr.robot_radius_m, fr.snap_m)
        return fr.robot_radius_m if fits is not None else 0.0

    def _move(self, state: MapState, pose: Pose2D, goal: np.ndarray, look_at: np.ndarray,
              reason: str) -> Decision | None:
        fr = self.frontier.config
        grid = state.island_grid
        start = (pose.x, pose.y)
        radius = self._radius(state, pose)
        path = grid.shortest_path(start, (float(goal[0]), float(goal[1])), radius, fr.snap_m)
        if path is None:
            return None
        if np.linalg.norm(path[0] - pose.xy) > 1e-9:
            path = np.vstack([pose.xy, path])
        path = settle(grid, cut_path(path, fr.max_step_m), radius, fr.stop_clearance_m,
                      fr.settle_m, fr.max_step_m, fr.snap_m)
        end = path[-1]
        arrived = np.linalg.norm(end - goal) <= self.config.reached_m
        if arrived or np.linalg.norm(end - look_at) < 0.3:
            yaw = math.atan2(look_at[1] - end[1], look_at[0] - end[0])
        else:
            d = end - path[-2] if len(path) > 1 else look_at - end
            yaw = math.atan2(d[1], d[0])
        return Decision(Pose2D(float(end[0]), float(end[1]), float(yaw)), path,
                        target_xy=(float(goal[0]), float(goal[1])), reason=reason)
