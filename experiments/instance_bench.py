"""Instance bench (DESIGN 9, objects as instances): chairs counted per frame, per instance map
and through the count gate on the agent's walks to count questions, without a language model.

Walks: ``walk`` writes, for each house with a count question ("How many chairs are around the
table in the dining room?"), the poses of the default explorer (target steering, the model-free
direction scorer, the semantic sensor steering, the early stop off) walking towards it to the
step budget (the format of ``experiments/walk_poses.py``); or the agent's own walks that
``experiments/count_bench.py --out`` records (a .jsonl file: the first count question per
house).

``score``: each walk's frames, in order, read by a perception (``pixels``: the committed
network with room votes, as the agent runs it; ``semantic``: the labels; cached beside the
walks file), which fills an instance map (``mapping.instances``) as the agent's does. Against
the semantic sensor's truth:

- *per frame*: chairs the frame's description lists (the describer's 150 px) against the true
  chairs it shows at the same threshold, |said - true| averaged over frames;
- *per map*, at the walk's end: sure chair instances against the true chairs seen (at least
  GLIMPSE_PIXELS in some frame), |map - true| per walk; unmatched (sure instances with no true
  chair within MATCH_M, each true chair matched once) and chairs missed;
- *the count asked*: the map's count (``mapping.instances.asked_count``) at the walk's end
  against the question's answer, beside the most chairs one frame lists in the room;
- *through the gate*: the frames replayed through the rules gate reading the map, or (views)
  the sightings merged by place: the count at its first whole-group verdict, or at the walk's
  end when none comes (the walk goes on as recorded; only the stop differs).

Back-ends: synthetic houses (sh3d), the perception named, no language model.

    python -m experiments.count_bench --seeds 0-39 --perception pixels --out out/cb-train.jsonl
    python -m experiments.instance_bench score out/cb-train.jsonl --perception pixels
    python -m experiments.instance_bench score out/cb-train.jsonl --sweep --set SURE=0.8

Tune on training houses (0-99), check on validation houses (2000-2009; the perception's
3900-3909), never on the held-out houses 100-129.
"""

from __future__ import annotations

import argparse
import json
import math
import pickle
import statistics
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.agent import AgentConfig
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping import instances as instance_map
from efficienteqa.mapping.instances import Region
from efficienteqa.perception.base import Sightings
from efficienteqa.perception.regions import GLIMPSE_PIXELS
from efficienteqa.perception.semantic import SemanticPerception
from efficienteqa.perception.visible import REFERENCE_AREA_PX, FrameDescription, visible_objects
from efficienteqa.question import parse_question
from efficienteqa.records import code_version
from efficienteqa.scenes import synthetic_questions
from efficienteqa.stack import EXPLORE_SCORERS
from efficienteqa.stop import gate as gate_module
from efficienteqa.stop.gate import RulesGate
from efficienteqa.stop.rules import env_step_budget
from experiments.common import explore_episode, seed_set

MATCH_M = 0.6  # an instance is a true chair's when it is the nearest within this


def walk(house: int) -> tuple[str, int, list[list[float]]] | None:
    """The count question, its answer and the poses of a walk towards it in ``house``."""
    with SyntheticEnv.from_seed(house) as env:
        questions = [q for q in synthetic_questions(env, oracle=False) if q.category == "count"]
        if not questions:
            return None
        q = questions[0]
        scorer = EXPLORE_SCORERS.build("direction-logit",
                                       perception=SemanticPerception(env.scene_labels()))
        config = AgentConfig.of(max_steps=env_step_budget(env), seed=0)
        ep = explore_episode(env, config, q.question, scorer=scorer, to_budget=True)
    return q.question, int(q.answer), [[round(p.x, 3), round(p.y, 3), round(p.yaw, 4)]
                                       for p in ep.poses]


@dataclass
class Walk:
    """One walk read by a perception: each frame's regions for the instance map, and what the
    truth and the frame's description say of chairs."""

    house: int
    question: str
    answer: int
    regions: list[list[Region]]
    frame_errors: list[int]  # chairs the description lists minus true chairs, per frame
    seen: dict[int, tuple[float, float]]  # true chairs seen: id -> place
    table: tuple[float, float] | None  # the asked table's place
    view: int  # the most chairs one frame's description lists in the asked room
    described: list[FrameDescription]  # each frame's description (the gate reads it)
    sightings: list[Sightings]  # each frame's sightings of the question's target


def read_walk(house: int, question: str, answer: int, poses: list[list[float]],
              perception: Any) -> Walk:
    target = parse_question(question)
    room = target.room
    with SyntheticEnv.from_seed(house) as env:
        labels = env.scene_labels()
        chair_ids = {o.id for o in env.house.objects if o.category == "chair"}
        asked = [int(t) for t, chairs in env.house.meta.get("chairs_at_table", {}).items()
                 if len(chairs) == answer]
        table = env.house.object(asked[0]) if asked else None
        perception.reset()
        regions, errors, seen, view = [], [], set(), 0
        described: list[FrameDescription] = []
        sighted: list[Sightings] = []
        for pose in poses:
            obs = env.observe(Pose2D(*pose))
            h, w = obs.depth_m.shape
            glimpse = max(1, round(GLIMPSE_PIXELS * h * w / REFERENCE_AREA_PX))
            true = {o.instance_id for o in visible_objects(obs, labels)
                    if o.instance_id in chair_ids}
            seen |= {o.instance_id for o in visible_objects(obs, labels, glimpse)
                     if o.instance_id in chair_ids}
            shown, their = perception.read(obs)
            said = [o for o in visible_objects(shown, their) if o.label.category == "chair"]
            errors.append(len(said) - len(true))
            d = perception.describe(obs)
            here = {None, f"in the {room}"} if d.room == room else {f"in the {room}"}
            view = max(view, sum(1 for o in d.objects if o.label.category == "chair"
                                 and o.where in here))
            regions.append(perception.regions(obs))
            described.append(d)
            sighted.append(perception.sightings(obs, target))
        places = {o.id: (o.x, o.y) for o in env.house.objects if o.id in seen}
    return Walk(house, question, answer, regions, errors, places,
                (table.x, table.y) if table is not None else None, view, described, sighted)


class _Replay:
    """A walk's frames as the gate reads them, one at a time (``frame``), with the instance map
    filled as the agent fills it."""

    def __init__(self, walk: Walk) -> None:
        self.walk, self.frame = walk, 0
        self.instances = instance_map.InstanceMap()

    def describe(self, obs: Any) -> FrameDescription:
        return self.walk.described[self.frame]

    def sightings(self, obs: Any, target: Any) -> Sightings:
        return self.walk.sightings[self.frame]

    def instances_seen(self, obs: Any, target: Any) -> instance_map.FrameInstances:
        return self.instances.add(self.walk.regions[self.frame])


def gate_walk(walk: Walk, instances: bool) -> tuple[int | None, int | None]:
    """The walk replayed through the rules gate, reading the instance map or (``instances``
    False) the frames' sightings merged by place: the frame of its first whole-group verdict
    (None: none within the walk) and the count the answer would be told then (or at the walk's
    end): the map's, or the most chairs one frame lists up to then."""
    replay = _Replay(walk)
    gate = RulesGate(replay, instances=instances)
    target = parse_question(walk.question)
    stop, view = None, 0
    for k in range(len(walk.regions)):
        replay.frame = k
        d = walk.described[k]
        here = {None, f"in the {target.room}"} if d.room == target.room else {
            f"in the {target.room}"}
        view = max(view, sum(1 for o in d.objects if o.label.category == "chair"
                             and o.where in here))
        verdict = gate.check(walk.question, target, None, "")
        if verdict.final:
            stop = k
            break
    if not instances:
        return stop, view or None
    counted = instance_map.asked_count(replay.instances, target)
    return stop, counted.n if counted else None


def score_walk(walk: Walk) -> dict[str, Any]:
    """The walk's regions replayed into a fresh instance map, scored (module docstring)."""
    instances = instance_map.InstanceMap()
    for frame in walk.regions:
        instances.add(frame)
    room = parse_question(walk.question).room
    chairs = [i for i in instances.instances() if i.category == "chair"]
    matched = _match([i.xy for i in chairs], list(walk.seen.values()))

    def in_room(i: Any) -> bool:
        return room is None or i.room in (None, room)

    counted = instance_map.count(instances, lambda c: c == "chair", lambda c: c == "table",
                                 in_room)
    group = None
    if walk.table is not None:
        tables = [i for i in instances.instances() if i.category == "table"]
        near = min(tables, key=lambda i: math.dist(i.xy, walk.table), default=None)  # type: ignore[arg-type]
        if near is not None and math.dist(near.xy, walk.table) <= MATCH_M:
            group = len(instances.group(lambda c: c == "chair", [near.id]))
    gated = gate_walk(walk, instances=True)
    before = gate_walk(walk, instances=False)
    return {"house": walk.house, "answer": walk.answer, "frames": walk.frame_errors,
            "map": len(chairs), "true_seen": len(walk.seen), "duplicates": len(chairs) - matched,
            "missed": len(walk.seen) - matched, "counted": counted.n if counted else None,
            "group": group, "view": walk.view, "gate_stop": gated[0], "gate_count": gated[1],
            "views_stop": before[0], "views_count": before[1]}


def _match(found: list[tuple[float, float]], true: list[tuple[float, float]]) -> int:
    """Pairs of a found and a true place within MATCH_M, nearest first, each used once."""
    pairs = sorted((math.dist(f, t), i, j) for i, f in enumerate(found)
                   for j, t in enumerate(true) if math.dist(f, t) <= MATCH_M)
    a, b, n = set(), set(), 0
    for _, i, j in pairs:
        if i not in a and j not in b:
            a.add(i)
            b.add(j)
            n += 1
    return n


def summary(rows: list[dict[str, Any]]) -> str:
    frames = [d for r in rows for d in r["frames"]]
    nonzero = [d for r in rows for d, t in zip(r["frames"], r["frames"]) if d != 0]
    per_map = [abs(r["map"] - r["true_seen"]) for r in rows]
    right = sum(r["counted"] == r["answer"] for r in rows)
    group = sum(r["group"] == r["answer"] for r in rows)
    view = sum(r["view"] == r["answer"] for r in rows)

    def gated(prefix: str) -> str:
        stops = [r for r in rows if r[f"{prefix}_stop"] is not None]
        return (f"{sum(r[f'{prefix}_count'] == r['answer'] for r in rows)}/{len(rows)} right "
                f"({sum(r[f'{prefix}_count'] == r['answer'] for r in stops)}/{len(stops)} "
                f"stopped by a whole group)")
    return (f"{len(rows)} walks, {len(frames)} frames: chairs miscounted per frame "
            f"{statistics.mean(abs(d) for d in frames):.3f} (over {sum(1 for d in frames if d > 0)}"
            f" / under {sum(1 for d in frames if d < 0)} frames; {len(nonzero)} frames wrong); "
            f"per map {statistics.mean(per_map):.2f} (map {sum(r['map'] for r in rows)} sure "
            f"chair instances, {sum(r['true_seen'] for r in rows)} true chairs seen, "
            f"{sum(r['duplicates'] for r in rows)} unmatched, {sum(r['missed'] for r in rows)} "
            f"missed); count asked right {right}/{len(rows)} (the most one view lists: "
            f"{view}/{len(rows)}); group around the asked table right {group}/{len(rows)}; "
            f"through the gate, instances: {gated('gate')}; views: {gated('views')}")


def read_walks(path: Path) -> dict[str, dict[str, Any]]:
    """Walks by house: a file of ``walk`` (JSON), or the agent's own walks that
    ``experiments.count_bench --out`` wrote (JSON lines, one per question: the first per
    house)."""
    if path.suffix != ".jsonl":
        return dict(json.loads(path.read_text())["houses"])
    walks: dict[str, dict[str, Any]] = {}
    for line in path.read_text().splitlines():
        row = json.loads(line)
        house = row["id"].split("-")[-2]
        walks.setdefault(house, {"question": row["question"], "answer": row["truth"],
                                 "poses": row["poses"]})
    return walks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    w = sub.add_parser("walk")
    w.add_argument("--seeds", default="3900-3909")
    w.add_argument("--out", type=Path, required=True)
    s = sub.add_parser("score")
    s.add_argument("walks", type=Path)
    s.add_argument("--perception", default="pixels", choices=("pixels", "semantic"))
    s.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="a constant of mapping.instances or stop.gate for this run (tuning)")
    s.add_argument("--sweep", action="store_true",
                   help="score the defaults, then each --set alone")
    s.add_argument("--fresh", action="store_true", help="read the frames again (not the cache)")
    s.add_argument("--verbose", action="store_true", help="a line per walk")
    args = parser.parse_args()
    if args.command == "walk":
        houses: dict[str, Any] = {}
        for house in seed_set(args.seeds):
            got = walk(house)
            if got is None:
                continue
            houses[str(house)] = dict(zip(("question", "answer", "poses"), got))
            print(f"house {house}: {len(got[2])} poses ({got[0]} {got[1]})", flush=True)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"command": f"python -m experiments.instance_bench walk "
                                                   f"--seeds {args.seeds} --out {args.out}",
                                        "code_version": code_version(), "houses": houses},
                                       indent=1) + "\n")
        return
    walks = read_walks(args.walks)
    cache = args.walks.with_name(f"{args.walks.stem}-{args.perception}.pkl")
    if cache.is_file() and not args.fresh:
        read = pickle.loads(cache.read_bytes())
    else:
        pixels: Any = None
        if args.perception == "pixels":
            from efficienteqa.perception.pixels.backend import PixelPerception

            pixels = PixelPerception.load(room_votes=True)
        read = []
        for name, walked in walks.items():
            if pixels is not None:
                perception: Any = pixels
            else:
                with SyntheticEnv.from_seed(int(name)) as house_env:
                    perception = SemanticPerception(house_env.scene_labels())
            walk_read = read_walk(int(name), walked["question"], int(walked["answer"]),
                                  walked["poses"], perception)
            for frame in walk_read.regions:  # smaller on disk
                frame[:] = [replace(r, points=r.points.astype(np.float32)) for r in frame]
            read.append(walk_read)
            print(f"house {name}: read", flush=True)
        cache.write_bytes(pickle.dumps(read))
    settings = [[]] + [[s] for s in args.set] if args.sweep else [args.set]
    for chosen in settings:
        saved = {}
        for setting in chosen:
            name, _, value = setting.partition("=")
            module = next((m for m in (instance_map, gate_module) if hasattr(m, name)), None)
            if module is None:
                raise SystemExit(f"mapping.instances and stop.gate have no {name}")
            saved[name] = (module, getattr(module, name))
            parsed = json.loads(value)
            setattr(module, name, tuple(parsed) if isinstance(parsed, list) else parsed)
        rows = [score_walk(w) for w in read]
        if args.verbose:
            for row in rows:
                print(f"house {row['house']}: truth {row['answer']}, counted {row['counted']}, "
                      f"group {row['group']}, one view {row['view']}; map {row['map']} chairs, "
                      f"{row['true_seen']} seen; gate: instances {row['gate_count']} at "
                      f"{row['gate_stop']}, views {row['views_count']} at {row['views_stop']}")
        print(f"{args.perception}, {', '.join(chosen) or 'defaults'}: {summary(rows)}",
              flush=True)
        for name, (module, value) in saved.items():
            setattr(module, name, value)

if __name__ == "__main__":
    main()
