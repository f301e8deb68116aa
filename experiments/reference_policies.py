"""Reference policies for the steering benchmark (DESIGN 9): yardsticks, not agents.

They walk a synthetic house with the project's step rule and read its ground truth (rooms,
doors, the navigation grid, which room holds the question's evidence); the renderer only says
what a frame shows (the 250 px "in view" test of ``envs/synthetic/questions.py``, the door test
below, the glimpse test). Every future explorer change is read against them.

The step rule. The start view is step 1 (as for the oracle's step count). A step moves at most
``STEP_M`` metres along a collision-free path on the navigation grid, then takes one 120-degree
view; turning in place to face a new direction is a step; a look-around (the two other
directions of a room, at +-120 deg of the current yaw) is two steps. A move ends facing the
direction of travel unless its goal sets a yaw.

Policies (``POLICIES``):

- ``target-room``: knows which room holds the evidence (not where it lies, nor the doors).
  Doors are discovered only by looking: a door counts once a frame shows its opening (a point of
  it at 0.5 or 1.2 m height that the depth buffer does not hide) or its panel
  (``DOOR_PANEL_PIXELS``); a discovered door reveals the two rooms it joins. Until a discovered
  open door leads into the target room, it goes through the nearest (path metres to the pose
  ``ENTRY_M`` past the door) discovered door into a room it has not entered, with one view on
  entering (facing the room's centre; along a corridor, its farther end). Where no such door is
  left it looks around where it stands, then at the centre of the nearest entered room it has
  not looked around in. Once a door into the target room is seen it goes through it; inside,
  it looks around, then visits further viewpoints there (near the room's centre, its quarters;
  not within ``VIEWPOINT_APART_M`` of where it looked around), looking around at each.
- ``target-room-aimed``: the same, knowing where the target room lies as well: of the
  discovered doors it takes the one with the shortest path plus straight line on to the target
  room, and only when that brings it closer to the target room than it stands (else it looks
  around first); it enters a corridor facing the target room's side.
- ``named-room`` ("knows the named room", the explorers' yardstick): knows only the rooms the
  question names (``named_rooms``: the house's room names read in the question's words, not the
  evidence's room), then walks as ``target-room`` with those as its target rooms; where nothing
  is left to do in them (the evidence lies elsewhere) it goes on room by room. Where the
  question names no room (a location question) it searches room by room from the start.
- ``room-by-room``: knows nothing of the target. It looks around in the room it stands in, then
  goes into the nearest discovered room it has not searched, looks around there, and so on; when
  every discovered room is searched it visits the rooms' viewpoints, looking around.

All "go closer on a glimpse" (the ``-no-closer`` variants do not): when a frame shows an
evidence object with at least ``GLIMPSE_PIXELS`` but not the whole evidence in view, the robot
walks to a pose that shows it, facing it: floor points on rings around the evidence in its room,
in order of the fewest steps from the robot, then nearest to 1.5 m beyond the evidence's spread,
then the object's front side first; the first that the renderer confirms (a half-resolution
frame, then the full one), else the first unconfirmed.

Measure: the step of the first frame with the evidence in view (``None`` when the budget ends
first; the benchmark counts it as budget + 1).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M
from efficienteqa.envs.synthetic.layout import Door, Room
from efficienteqa.envs.synthetic.oracle import STEP_M
from efficienteqa.envs.synthetic.questions import Question, evidence_visible
from efficienteqa.geometry import Pose2D, camera_to_world, wrap_angle
from efficienteqa.mapping.navgrid import path_length, truncate_path
from efficienteqa.observation import Observation

LOOK_TURNS = (2 * math.pi / 3, -2 * math.pi / 3)  # a look-around: two more views
GLIMPSE_PIXELS = 20  # an evidence object this large in a frame is a glimpse
DOOR_PANEL_PIXELS = 50  # a door panel this large in a frame shows its door
DOOR_SAMPLES = ((-0.3, 0.5), (0.0, 0.5), (0.3, 0.5), (-0.3, 1.2), (0.0, 1.2), (0.3, 1.2))
DEPTH_TOLERANCE_M = 0.15  # a door point counts as seen unless the depth buffer is nearer by this
ENTRY_M = 1.0  # entering a room: the pose this far past the door's centre, facing in
ARRIVE_SLACK_M = 0.5  # entering a room or a viewpoint: close enough (no step for the rest)
CORRIDOR_ASPECT = 2.0  # a room this elongated is entered facing along it
APPROACH_M = 1.5  # glimpse poses: preferably this far beyond the evidence's spread ...
APPROACH_RING_M = (0.6, 4.0)  # ... on rings this far (m, plus the spread), 0.3 m apart
APPROACH_RENDERS = 60  # candidate poses tested with the renderer per glimpse
MAX_APPROACHES = 3  # glimpse walks per episode
VIEWPOINT_SNAP_M = 1.2
VIEWPOINT_APART_M = 1.0  # viewpoints this far from each other and from where it looked around


@dataclass(frozen=True)
class PolicySpec:
    target_room: bool  # knows which room holds the evidence
    closer: bool  # goes closer on a glimpse
    aim: bool = False  # (target_room) knows where that room lies too, and heads for it
    named: bool = False  # (target_room) its target rooms are the ones the question names


POLICIES: dict[str, PolicySpec] = {
    "target-room": PolicySpec(target_room=True, closer=True),
    "room-by-room": PolicySpec(target_room=False, closer=True),
    "target-room-no-closer": PolicySpec(target_room=True, closer=False),
    "room-by-room-no-closer": PolicySpec(target_room=False, closer=False),
    "target-room-aimed": PolicySpec(target_room=True, closer=True, aim=True),
    "named-room": PolicySpec(target_room=True, closer=True, named=True),
}


def named_rooms(text: str, rooms: Sequence[Room]) -> set[int]:
    """The ids of the rooms whose name the question says, as whole words; a longer name wins
    where names overlap ("guest bedroom" is not also "bedroom")."""
    words = re.sub(r"[^a-z0-9]+", " ", text.lower()).split()
    taken = [False] * len(words)
    out: set[int] = set()
    for room in sorted(rooms, key=lambda r: -len(r.name.split())):
        name = room.name.lower().split()
        for i in range(len(words) - len(name) + 1):
            if words[i:i + len(name)] == name and not any(taken[i:i + len(name)]):
                taken[i:i + len(name)] = [True] * len(name)
                out.add(room.id)
    return out


@dataclass
class ReferenceEpisode:
    """One reference walk. ``steps``: frames taken (the start view included); ``first_seen``:
    the step whose frame first shows the evidence in view, None if never; ``stop``: "seen",
    "budget", or "exhausted" (nothing left to visit)."""

    first_seen: int | None = None
    first_near: int | None = None
    first_glimpse: int | None = None
    steps: int = 0
    moves: int = 0  # steps that changed the position (not turns in place)
    turns: int = 0  # steps that only turned
    refused: int = 0  # moves the environment refused (the step is spent where it stood)
    approaches: int = 0  # glimpse walks started
    metres: float = 0.0
    rooms_entered: int = 0
    doors_seen: int = 0
    stop: str = ""
    trace: list[tuple[float, float, float, str]] = field(default_factory=list)


@dataclass
class _Goal:
    xy: tuple[float, float]
    yaw: float | None  # None: arrive facing the direction of travel
    tag: str  # "look" (a turn of a look-around), "enter", "enter-search", "search", "approach"
    room: int | None = None
    slack_m: float = 0.0  # arrived within this much of xy (inside ``room``)


class ReferencePolicy:
    """One episode of a reference policy on ``question`` in ``env`` (ground truth read)."""

    def __init__(self, env: SyntheticEnv, question: Question, spec: PolicySpec, budget: int,
                 near: Callable[[tuple[float, float]], float] | None = None,
                 near_m: float = 2.0) -> None:
        self.env, self.q, self.spec, self.budget = env, question, spec, budget
        self.house = env.house
        self.grid = env.grid
        self.layout = env.house.layout
        self.near, self.near_m = near, near_m
        # The evidence's rooms (where a glimpse's approach poses lie) and the rooms it steers
        # to: the same, or for ``named`` the rooms the question names.
        self.evidence_rooms = {self.house.object(e).room_id for e in question.evidence}
        self.targets = (named_rooms(question.question, self.layout.rooms) if spec.named
                        else set(self.evidence_rooms))
        self.panels = {int(k): v for k, v in self.house.meta.get("door_objects", {}).items()}
        self.known_doors: set[int] = set()
        self.entered: set[int] = set()
        self.searched: set[int] = set()
        self.visited_viewpoints: set[tuple[float, float]] = set()
        self.looked: list[tuple[float, float]] = []  # where the robot looked around
        self.queue: list[_Goal] = []
        self.ep = ReferenceEpisode()
        self.pose = env.house.start
        self._field: tuple[tuple[int, int], np.ndarray] | None = None

    # -- the episode ----------------------------------------------------------------------
    def run(self) -> ReferenceEpisode:
        obs, _ = self.env.reset()
        self.ep.steps = 1
        self._observe(obs, "start")
        while self.ep.first_seen is None and self.ep.steps < self.budget:
            nxt = self._next()
            if nxt is None:
                self.ep.stop = "exhausted"
                break
            pose, tag = nxt
            moved = math.hypot(pose.x - self.pose.x, pose.y - self.pose.y)
            obs, _, _, _, info = self.env.step(pose)
            self.ep.steps += 1
            if info.get("blocked"):
                self.ep.refused += 1
                self.queue = self.queue[1:]  # that goal cannot be reached this way
            elif moved > 1e-6:
                self.ep.moves += 1
                self.ep.metres += moved
            else:
                self.ep.turns += 1
            self._observe(obs, tag)
        if not self.ep.stop:
            self.ep.stop = "seen" if self.ep.first_seen is not None else "budget"
        self.ep.rooms_entered = len(self.entered)
        self.ep.doors_seen = len(self.known_doors)
        return self.ep

    def _observe(self, obs: Observation, tag: str) -> None:
        self.pose = obs.pose
        step = self.ep.steps
        self.ep.trace.append((round(obs.pose.x, 2), round(obs.pose.y, 2), round(obs.pose.yaw, 3),
                              tag))
        room = self._room_at(obs.pose.x, obs.pose.y)
        if room is not None:
            self.entered.add(room)
        if (self.ep.first_near is None and self.near is not None
                and self.near((obs.pose.x, obs.pose.y)) <= self.near_m):
            self.ep.first_near = step
        if evidence_visible(obs.instance, self.q.evidence):
            self.ep.first_seen = step
            return
        new_doors = self._doors_in_view(obs) - self.known_doors
        self.known_doors |= new_doors
        glimpse = any(evidence_visible(obs.instance, [e], min_pixels=GLIMPSE_PIXELS)
                      for e in self.q.evidence)
        if glimpse and self.ep.first_glimpse is None:
            self.ep.first_glimpse = step
        heading = self.queue[0].tag if self.queue else ""
        if (glimpse and self.spec.closer and heading != "approach"
                and self.ep.approaches < MAX_APPROACHES):
            goal = self._approach_pose()
            if goal is not None:
                self.ep.approaches += 1
                self.queue = [goal]
                return
        if (self.spec.target_room and heading not in ("approach", "enter-search", "search", "look")
                and room not in self.targets
                and any(self._leads_to_target(self.layout.doors[d]) for d in new_doors)):
            self.queue = []  # a door into the target room: decide again

    # -- deciding -------------------------------------------------------------------------
    def _next(self) -> tuple[Pose2D, str] | None:
        """The next pose to ask for, or None when nothing is left to do."""
        for _ in range(200):
            if not self.queue:
                self._decide()
                if not self.queue:
                    return None
            goal = self.queue[0]
            if self._reached(goal):
                self.queue.pop(0)
                self._arrived(goal)
                continue
            pose = self._step_toward(goal)
            if pose is None:  # unreachable
                self.queue.pop(0)
                continue
            return pose, goal.tag
        return None

    def _arrived(self, goal: _Goal) -> None:
        if goal.tag in ("enter-search", "search"):
            self._look_around()
            if goal.room is not None:
                self.searched.add(goal.room)

    def _decide(self) -> None:
        here = self._room_at(self.pose.x, self.pose.y)
        if self.spec.target_room and self.targets:
            self._decide_target(here)
            if not self.queue and self.spec.named:  # nothing left in the named rooms: from
                self.targets = set()  # now on, room by room
                self._decide_rooms(here)
        else:
            self._decide_rooms(here)

    def _decide_target(self, here: int | None) -> None:
        if here is not None and here in self.targets:
            if here not in self.searched:
                self.searched.add(here)
                self._look_around()
                return
            goal = self._nearest([self._viewpoint_goal(vp, r) for r in sorted(self.targets)
                                  for vp in self._viewpoints(r)])
            if goal is not None:
                self.queue = [goal]
            return
        into_target = [self._entry(d, r, "enter-search") for d in sorted(self.known_doors)
                       for r in self._door_rooms(d) if r in self.targets]
        goal = self._nearest(into_target)
        if goal is not None:
            self.queue = [goal]
            return
        onward = [self._entry(d, r, "enter") for d in sorted(self.known_doors)
                  for r in self._door_rooms(d) if r not in self.entered]
        goal = self._nearest(onward, towards_target=self.spec.aim)
        closer = goal is not None and (not self.spec.aim or self._to_target(goal.xy)
                                       < self._to_target((self.pose.x, self.pose.y)))
        if goal is not None and (closer or here in self.searched or here is None):
            self.queue = [goal]
            return
        if here is not None and here not in self.searched:
            self.searched.add(here)
            self._look_around()
            return
        goal = self._nearest([self._viewpoint_goal(vp, r) for r in sorted(self.entered)
                              if r not in self.searched for vp in self._viewpoints(r)],
                             towards_target=self.spec.aim)
        if goal is not None:
            self.queue = [goal]

    def _to_target(self, xy: Sequence[float]) -> float:
        """Straight-line metres from a point to the nearest target room (0 inside)."""
        out = math.inf
        for r in self.targets:
            room = self.layout.rooms[r]
            dx = max(room.x0 - xy[0], 0.0, xy[0] - room.x1)
            dy = max(room.y0 - xy[1], 0.0, xy[1] - room.y1)
            out = min(out, math.hypot(dx, dy))
        return out

    def _decide_rooms(self, here: int | None) -> None:
        if here is not None and here not in self.searched:
            self.searched.add(here)
            self._look_around()
            return
        goal = self._nearest([self._entry(d, r, "enter-search") for d in sorted(self.known_doors)
                              for r in self._door_rooms(d) if r not in self.searched])
        if goal is None:  # every discovered room searched: their viewpoints, nearest first
            goal = self._nearest([self._viewpoint_goal(vp, r)
                                  for r in range(len(self.layout.rooms))
                                  if r in self.entered or r in self._discovered_rooms()
                                  for vp in self._viewpoints(r)])
        if goal is not None:
            self.queue = [goal]

    def _look_around(self) -> None:
        yaw = self.pose.yaw
        self.looked.append((self.pose.x, self.pose.y))
        self.queue[:0] = [_Goal((self.pose.x, self.pose.y), float(wrap_angle(yaw + turn)), "look")
                          for turn in LOOK_TURNS]

    # -- rooms, doors, viewpoints -----------------------------------------------------------
    def _room_at(self, x: float, y: float) -> int | None:
        room = self.layout.room_at(x, y)
        return room.id if room is not None else None

    def _door_rooms(self, door_id: int) -> list[int]:
        door = self.layout.doors[door_id]
        return [r for r in (door.room_a, door.room_b) if r >= 0] if door.open else []

    def _discovered_rooms(self) -> set[int]:
        return {r for d in self.known_doors for r in self._door_rooms(d)}

    def _leads_to_target(self, door: Door) -> bool:
        return door.open and (door.room_a in self.targets or door.room_b in self.targets)

    def _entry(self, door_id: int, room_id: int, tag: str) -> _Goal | None:
        """The pose ENTRY_M past the door's centre inside ``room_id``, facing into it."""
        door, room = self.layout.doors[door_id], self.layout.rooms[room_id]
        normal = np.array([0.0, 1.0]) if door.axis == "x" else np.array([1.0, 0.0])
        centre = np.array([door.x, door.y])
        if not room.contains(*(centre + 0.3 * normal)):
            normal = -normal
        cell = self.grid.snap(centre + ENTRY_M * normal, ROBOT_RADIUS_M, 0.8)
        if cell is None:
            return None
        xy = self.grid.spec.cell_to_world(cell)
        if not room.contains(*xy) or self._room_at(self.pose.x, self.pose.y) == room_id:
            return None
        # Through this door: the shortest path to the entry pose passes its doorway (the far
        # side of a door is not an entry into the room it is reached from another way).
        field_m = self._distance_field()
        doorway = self.grid.snap(centre, ROBOT_RADIUS_M, 0.5)
        if doorway is None:
            return None
        past = float(np.hypot(*(xy - self.grid.spec.cell_to_world(doorway))))
        if field_m[cell] < field_m[doorway] + past - 0.3:
            return None
        return _Goal((float(xy[0]), float(xy[1])), self._entry_yaw(room, xy, normal), tag,
                     room_id, ARRIVE_SLACK_M)

    def _entry_yaw(self, room: Room, xy: np.ndarray, normal: np.ndarray) -> float:
        """Facing into a room on entering it: towards its centre; along a corridor, towards
        its farther end (for the target-room policy, the end on the target rooms' side where
        they lie to one side)."""
        w, d = room.x1 - room.x0, room.y1 - room.y0
        centre = np.array(room.centre)
        if max(w, d) >= CORRIDOR_ASPECT * min(w, d):
            k = 0 if w >= d else 1
            along = np.eye(2)[k]
            half = max(w, d) / 2 - 0.5
            ends = [centre + along * half, centre - along * half]
            ends.sort(key=lambda e: -float(np.hypot(*(e - xy))))  # the farther end first
            if self.spec.target_room and self.spec.aim and room.id not in self.targets:
                # towards the target rooms where they lie on one side along the corridor
                spans = [((r.x0, r.x1), (r.y0, r.y1))[k]
                         for r in (self.layout.rooms[t] for t in sorted(self.targets))]
                if all(hi <= xy[k] for _, hi in spans):
                    ends.sort(key=lambda e: e[k])
                elif all(lo >= xy[k] for lo, _ in spans):
                    ends.sort(key=lambda e: -e[k])
            aim = ends[0] - xy
        else:
            aim = centre - xy if float(np.hypot(*(centre - xy))) > 0.8 else normal
        return math.atan2(aim[1], aim[0])

    def _viewpoints(self, room_id: int) -> list[tuple[float, float]]:
        """Navigable points of a room not yet visited nor looked around at: near its centre,
        then its quarters."""
        room: Room = self.layout.rooms[room_id]
        w, d = room.x1 - room.x0, room.y1 - room.y0
        wanted = [room.centre] + [(room.x0 + fx * w, room.y0 + fy * d)
                                  for fx in (0.25, 0.75) for fy in (0.25, 0.75)]
        out: list[tuple[float, float]] = []
        for xy in wanted:
            cell = self.grid.snap(xy, ROBOT_RADIUS_M, VIEWPOINT_SNAP_M)
            if cell is None:
                continue
            p = self.grid.spec.cell_to_world(cell)
            p = (round(float(p[0]), 3), round(float(p[1]), 3))
            if (room.contains(*p) and p not in self.visited_viewpoints
                    and all(math.dist(p, o) > VIEWPOINT_APART_M for o in out + self.looked)):
                out.append(p)
        return out

    def _viewpoint_goal(self, xy: tuple[float, float], room_id: int) -> _Goal:
        return _Goal(xy, None, "search", room_id, ARRIVE_SLACK_M)

    def _nearest(self, goals: Sequence[_Goal | None], towards_target: bool = False
                 ) -> _Goal | None:
        """The goal with the shortest path from the robot (None when none is reachable); with
        ``towards_target``, the shortest path plus the straight line on to the target room."""
        field_m = self._distance_field()
        best, best_d = None, math.inf
        for g in goals:
            if g is None:
                continue
            cell = self.grid.snap(g.xy, ROBOT_RADIUS_M, 0.5)
            d = field_m[cell] if cell is not None else math.inf
            if towards_target:
                d += self._to_target(g.xy)
            if d < best_d:
                best, best_d = g, d
        if best is not None and best.tag == "search":
            self.visited_viewpoints.add(best.xy)
        return best

    def _distance_field(self) -> np.ndarray:
        here = (self.pose.x, self.pose.y)
        cell = self.grid.snap(here, ROBOT_RADIUS_M, 0.5)
        if self._field is None or self._field[0] != cell:
            self._field = (cell, self.grid.distance_field(here, ROBOT_RADIUS_M))
        return self._field[1]

    def _doors_in_view(self, obs: Observation) -> set[int]:
        """Doors whose opening (a sample point not hidden in the depth buffer) or panel is in
        the frame."""
        h, w = obs.depth_m.shape
        world_to_cam = np.linalg.inv(obs.cam_to_world)
        k = obs.intrinsics
        counts = np.bincount(obs.instance[obs.instance > 0].ravel())
        out = set()
        for door in self.layout.doors:
            if door.id in self.known_doors:
                continue
            panel = self.panels.get(door.id)
            if panel is not None and panel < len(counts) and counts[panel] >= DOOR_PANEL_PIXELS:
                out.add(door.id)
                continue
            along = (1.0, 0.0) if door.axis == "x" else (0.0, 1.0)
            pts = np.array([[door.x + s * along[0], door.y + s * along[1], z, 1.0]
                            for s, z in DOOR_SAMPLES])
            cam = (world_to_cam @ pts.T).T[:, :3]
            ahead = cam[:, 2] > 0.2
            if not ahead.any():
                continue
            cam = cam[ahead]
            u = k[0, 0] * cam[:, 0] / cam[:, 2] + k[0, 2]
            v = k[1, 1] * cam[:, 1] / cam[:, 2] + k[1, 2]
            inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
            if not inside.any():
                continue
            depth = obs.depth_m[v[inside].astype(int), u[inside].astype(int)]
            if np.any((depth <= 0) | (depth >= cam[inside, 2] - DEPTH_TOLERANCE_M)):
                out.add(door.id)
        return out

    # -- going closer on a glimpse ----------------------------------------------------------
    def _approach_pose(self) -> _Goal | None:
        """A pose that shows the whole evidence, facing it: floor points on rings around it
        (``APPROACH_RING_M``) in its room, in order of the fewest steps from the robot, then
        the nearest to the preferred distance (``APPROACH_M`` beyond the evidence's spread),
        then the front side; the first that the renderer confirms (half resolution, then full),
        else the first of them unconfirmed."""
        objects = [self.house.object(e) for e in self.q.evidence]
        centre = np.mean([[o.x, o.y] for o in objects], axis=0)
        extent = max(math.hypot(o.x - centre[0], o.y - centre[1]) for o in objects)
        preferred = APPROACH_M + extent
        anchor = objects[0]
        if anchor.support_id is not None:
            anchor = self.house.object(anchor.support_id)
        front = math.atan2(-math.cos(anchor.yaw), math.sin(anchor.yaw))
        field_m = self._distance_field()
        candidates = []
        for r in np.arange(APPROACH_RING_M[0], APPROACH_RING_M[1] + 1e-9, 0.25) + extent:
            n = max(8, int(2 * math.pi * r / 0.3))
            for a in range(n):
                angle = front + 2 * math.pi * a / n
                x, y = centre[0] + r * math.cos(angle), centre[1] + r * math.sin(angle)
                if (not self.env.is_navigable(x, y)
                        or self._room_at(x, y) not in self.evidence_rooms):
                    continue
                i, j = self.grid.spec.world_to_cell((x, y))
                d = field_m[int(i), int(j)]
                if not np.isfinite(d):
                    continue
                off = abs(float(wrap_angle(angle - front)))
                yaw = math.atan2(centre[1] - y, centre[0] - x)
                candidates.append((math.ceil(d / STEP_M - 1e-9), round(abs(r - preferred) / 0.25),
                                   off, Pose2D(float(x), float(y), yaw)))
        if not candidates:
            return None
        candidates.sort(key=lambda c: c[:3])
        camera = self.env.camera
        half = camera.scaled(camera.width // 2, camera.height // 2)
        for *_, pose in candidates[:APPROACH_RENDERS]:
            frame = self.env.renderer.render(camera_to_world(pose, half), camera=half)
            if not evidence_visible(frame.instance, self.q.evidence):
                continue
            full = self.env.renderer.render(camera_to_world(pose, camera))
            if evidence_visible(full.instance, self.q.evidence):
                return _Goal((pose.x, pose.y), pose.yaw, "approach")
        pose = candidates[0][3]
        return _Goal((pose.x, pose.y), pose.yaw, "approach")

    # -- moving -----------------------------------------------------------------------------
    def _reached(self, goal: _Goal) -> bool:
        close = (math.hypot(goal.xy[0] - self.pose.x, goal.xy[1] - self.pose.y)
                 < max(0.05, goal.slack_m) and self._inside(goal, (self.pose.x, self.pose.y)))
        return close and (goal.yaw is None
                          or abs(float(wrap_angle(goal.yaw - self.pose.yaw))) < 1e-3)

    def _step_toward(self, goal: _Goal) -> Pose2D | None:
        """The pose after one step towards ``goal``: at most STEP_M along the shortest path."""
        here = (self.pose.x, self.pose.y)
        if math.hypot(goal.xy[0] - here[0], goal.xy[1] - here[1]) < 0.05:
            return Pose2D(here[0], here[1], goal.yaw if goal.yaw is not None else self.pose.yaw)
        path = self.grid.shortest_path(here, goal.xy, ROBOT_RADIUS_M)
        if path is None:
            return None
        if path_length(path) <= STEP_M + 1e-6:
            xy, last = np.asarray(goal.xy, float), path[-2]
            heading = math.atan2(xy[1] - last[1], xy[0] - last[0])
            return Pose2D(float(xy[0]), float(xy[1]), goal.yaw if goal.yaw is not None else heading)
        xy = truncate_path(path, STEP_M)
        seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
        k = min(int(np.searchsorted(np.cumsum(seg), STEP_M)), len(seg) - 1)
        direction = path[k + 1] - path[k]
        heading = math.atan2(direction[1], direction[0])
        if (goal.yaw is not None and path_length(path) <= STEP_M + goal.slack_m
                and self._inside(goal, xy)):  # close enough: arrive here, facing as the goal
            heading = goal.yaw
        return Pose2D(float(xy[0]), float(xy[1]), heading)

    def _inside(self, goal: _Goal, xy: Sequence[float]) -> bool:
        """Whether xy is inside the goal's room, 0.3 m from its walls (True without a room)."""
        return goal.room is None or self.layout.rooms[goal.room].contains(xy[0], xy[1], 0.3)


def run_policy(env: SyntheticEnv, question: Question, name: str, budget: int,
               near: Callable[[tuple[float, float]], float] | None = None,
               near_m: float = 2.0) -> ReferenceEpisode:
    """One episode of the reference policy ``name`` (a key of ``POLICIES``)."""
    return ReferencePolicy(env, question, POLICIES[name], budget, near, near_m).run()
