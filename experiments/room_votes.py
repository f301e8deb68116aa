"""Room types from what rooms hold, voted in the map (perception/pixels/rooms.py): the prior,
the agent's walks, and the floor's room type per frame against after voting.

    python -m experiments.room_votes prior                       # weights/room_prior.json
    python -m experiments.room_votes walk --houses 3000-3004 --out out/room_votes/train
    python -m experiments.room_votes score out/room_votes/train   # per frame vs voted

``prior`` counts objects per (category, room type) over the perception training houses
3000-3899 (the generated houses' labels; nothing is rendered). ``walk`` runs the real agent
(default configuration, pixel perception with the committed weights, MiniLM relevancy, the
model-free explore scorer, a stub answer that says "unknown") on each house's questions and
stores, per step, the network's classes, the depth, the pose and the true room type of the
floor at every 4th pixel each way. ``score`` replays the stored frames in walk order through
the segmentation with and without the votes (the network does not run again) and counts the
true floor points whose room type the labels name right (``evaluate._score_floor``'s count),
and the point under the robot.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.perception.pixels import rooms as rooms_module

TRAIN = range(3000, 3900)


def make_prior(out: Path) -> None:
    from efficienteqa.envs.synthetic.env import catalog_for
    from efficienteqa.envs.synthetic.generate import generate_house
    from efficienteqa.perception.pixels.frames import room_type_of, room_types

    catalog = catalog_for("sh3d")
    pairs: list[tuple[str, str]] = []
    t = time.perf_counter()
    for seed in TRAIN:
        house = generate_house(seed, catalog, "sh3d")
        kinds = {r.id: room_type_of(r.type) for r in house.layout.rooms}
        pairs += [(o.category, kinds[o.room_id]) for o in house.objects]
    rooms = room_types()
    record = {"command": "python -m experiments.room_votes prior",
              "houses": [TRAIN.start, TRAIN.stop - 1], "assets": "sh3d",
              "what": "objects per category and room type in the generated houses' labels "
                      "(doors left out); RoomPrior smooths them",
              "rooms": list(rooms), "counts": rooms_module.count_prior(pairs, rooms)}
    if out == rooms_module.PRIOR and out.exists():  # keep the floor confusions
        old = json.loads(out.read_text())
        if "floor_confusion" in old:
            record["floor_confusion"] = old["floor_confusion"]
    write_prior(record) if out == rooms_module.PRIOR else out.write_text(json.dumps(record))
    print(f"{len(pairs)} objects, {len(record['counts'])} categories, "
          f"{time.perf_counter() - t:.0f} s -> {out}")


def make_confusion(folders: list[Path], command: str) -> None:
    """Floor points per (true room type, room type the frame's own floor names), over stored
    walks, into the prior's JSON (``floor_confusion``)."""
    counts: dict[tuple[str, str], int] = {}
    figures = score(folders, False, counts)
    record = json.loads(rooms_module.PRIOR.read_text())
    rooms = record["rooms"]
    houses = sorted({int(p.stem.split("_")[0]) for f in folders for p in episodes(f)})
    record["floor_confusion"] = {
        "command": command, "houses": houses,
        "what": "true floor points (every 4th pixel each way) of the agent's walks: rows the "
                "true room type, columns the type the frame's predicted floor names",
        "counts": [[counts.get((t, q), 0) for q in rooms] for t in rooms]}
    write_prior(record)
    print(json.dumps(figures))


def write_prior(record: dict[str, Any]) -> None:
    """The prior's JSON with one line per table row."""
    lines = ["{"]
    items = list(record.items())
    for n, (key, value) in enumerate(items):
        end = "," if n < len(items) - 1 else ""
        if key == "counts":
            rows = [f"  {json.dumps(c)}: {json.dumps(v)}" for c, v in value.items()]
            lines.append(' "counts": {\n' + ",\n".join(rows) + f"\n }}{end}")
        elif isinstance(value, dict) and "counts" in value:
            head = json.dumps({k: v for k, v in value.items() if k != "counts"})[:-1]
            rows = ",\n   ".join(json.dumps(r) for r in value["counts"])
            lines.append(f' "{key}": {head}, "counts": [\n   {rows}]}}{end}')
        else:
            lines.append(f" {json.dumps(key)}: {json.dumps(value)}{end}")
    rooms_module.PRIOR.write_text("\n".join(lines) + "\n}\n")


# -- walks --------------------------------------------------------------------------------------
def parse_houses(text: str) -> list[int]:
    """"3000-3004" or "2000-2001,100-104" -> the houses."""
    houses: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.strip().partition("-")
        houses += range(int(lo), int(hi or lo) + 1)
    return houses


def true_floor(obs: Any, truth: Any) -> tuple[np.ndarray, list[str]]:
    """World xy and true room type of the true floor pixels, every 4th pixel each way (as
    ``evaluate._score_floor`` reads them); floor of no room is left out."""
    from efficienteqa.geometry import backproject
    from efficienteqa.perception.floor import FLOOR_TOLERANCE_M
    from efficienteqa.perception.pixels.frames import room_type_of

    k = 4
    points = backproject(obs.depth_m, obs.intrinsics, obs.cam_to_world)[::k, ::k]
    floor = ((obs.instance[::k, ::k] == 0) & (obs.depth_m[::k, ::k] > 0)
             & (np.abs(points[..., 2]) < FLOOR_TOLERANCE_M))
    xy, rooms = [], []
    for x, y in points[floor][:, :2]:
        room = truth.room_at(float(x), float(y))
        if room is not None:
            xy.append((x, y))
            rooms.append(room_type_of(room))
    return np.array(xy, np.float32).reshape(-1, 2), rooms


def walk(houses: list[int], per_house: int, out: Path, votes: bool, first: int = 0) -> None:
    """The agent's walks, each step's network output and truth stored (see the docstring)."""
    from efficienteqa.scenes import open_scene, synthetic_questions

    out.mkdir(parents=True, exist_ok=True)
    for house in houses:
        scene = open_scene(f"synthetic:{house}", oracle=False)
        env = scene.env
        try:
            qs = synthetic_questions(env, oracle=False)[first:first + per_house]  # type: ignore[arg-type]
            for n, q in enumerate(qs, start=first):
                t = time.perf_counter()
                steps, frames = walk_episode(env, q.question, votes)
                arrays = {f"{k}_{i}": v for i, f in enumerate(frames) for k, v in f.items()}
                np.savez_compressed(out / f"{house}_{n}.npz", n=len(frames),
                                    categories=np.array(network_categories()), **arrays)
                print(f"house {house} q{n} {steps} steps {len(frames)} frames "
                      f"{time.perf_counter() - t:.0f} s: {q.question}", flush=True)
        finally:
            env.close()


def walk_episode(env: Any, question: str, votes: bool) -> tuple[int, list[dict[str, Any]]]:
    """One episode of the agent (see the docstring); per valid step, what ``score`` reads."""
    from efficienteqa.agent import AgentConfig
    from efficienteqa.models.stub import StubChatModel
    from efficienteqa.perception.pixels.frames import room_type_of
    from efficienteqa.stack import Stack, build_agent
    from efficienteqa.trace import StepRecord

    truth = env.scene_labels()
    model = StubChatModel(lambda messages: "unknown", name="stub")
    built = build_agent(env, Stack(grouping="rules", perception="pixels"), AgentConfig(),
                        "synthetic", model=model)
    perception = built.agent.perception
    perception.room_votes = votes  # type: ignore[attr-defined]
    classify = perception.classify  # type: ignore[attr-defined]
    frames: list[dict[str, Any]] = []
    last: list[Any] = []

    def capture(rgb: np.ndarray, depth: np.ndarray) -> Any:
        # the step's first call reads the whole frame; close reads call again on crops
        classes = classify(rgb, depth)
        last.append(classes)
        return classes

    perception.classify = capture  # type: ignore[attr-defined]

    def hook(record: StepRecord, obs: Any, _: Any) -> None:
        calls = last[:]
        last.clear()
        if not record.valid or not calls:
            return
        c = calls[0]
        xy, rooms = true_floor(obs, truth)
        here = truth.room_at(obs.pose.x, obs.pose.y)
        frames.append({"category": c.category, "colour": c.colour, "state": c.state,
                       "confidence": c.confidence, "depth": obs.depth_m,
                       "intrinsics": obs.intrinsics, "cam_to_world": obs.cam_to_world,
                       "pose": np.array([obs.pose.x, obs.pose.y, obs.pose.yaw]),
                       "floor_xy": xy, "floor_room": np.array(rooms),
                       "here": room_type_of(here) if here else ""})

    result = built.agent.run(env, question, on_step=hook,
                              budget=built.agent.config.budget(env))
    return result.steps, frames


def network_categories() -> list[str]:
    import json as _json

    from efficienteqa.perception.pixels.backend import WEIGHTS
    from efficienteqa.perception.pixels.net import metadata_path

    return list(_json.loads(metadata_path(WEIGHTS).read_text())["vocabulary"]["categories"])


# -- scores ----------------------------------------------------------------------------------
def episodes(folder: Path) -> list[Path]:
    return sorted(folder.glob("*.npz"), key=lambda p: tuple(int(v) for v in p.stem.split("_")))


def rooms_at(labels: Any, xy: np.ndarray) -> list[str | None]:
    """``labels.room_at`` at each point, vectorised (the frame's floor cells or the map)."""
    from efficienteqa.perception.pixels.segment import ROOM_REACH_M

    if not len(xy):
        return []
    if labels._votes is not None:
        k = labels._votes.indices_at(xy)
        return [labels._votes.rooms[i] if i >= 0 else None for i in k.tolist()]
    if labels._tree is None:
        return [None] * len(xy)
    distance, k = labels._tree.query(xy, distance_upper_bound=ROOM_REACH_M)
    return [labels._rooms[i] if np.isfinite(d) else None for d, i in zip(distance, k.tolist())]


def score(folders: list[Path], votes: bool, confusion: dict[tuple[str, str], int] | None = None,
          **constants: float) -> dict[str, Any]:
    """Per frame (``votes`` False) or voted: the share of true floor points whose room type the
    labels name right, and of steps whose robot position they name right."""
    from efficienteqa.perception.pixels import segment
    from efficienteqa.perception.pixels.rooms import RoomPrior, RoomVotes
    from efficienteqa.perception.pixels.segment import PixelClasses, floor_types, read_frame

    for name, value in constants.items():
        for module in (rooms_module, segment):
            if hasattr(module, name):
                setattr(module, name, value)
    prior = RoomPrior.load(rooms_module.PRIOR) if votes else None
    floor = [0, 0]
    here = [0, 0, 0]  # right, answered, steps
    by_room: dict[str, list[int]] = {}
    per_episode: list[list[int]] = []  # floor right, floor points, here right, steps
    for folder in folders:
        for path in episodes(folder):
            before = [*floor, here[0], here[2]]
            z = np.load(path)
            names = [str(c) for c in z["categories"]]
            room_votes = RoomVotes(floor_types(names), prior) if votes else None
            for i in range(int(z["n"])):
                classes = PixelClasses(z[f"category_{i}"], z[f"colour_{i}"], z[f"state_{i}"],
                                       names, ("x",) * 64, ("x",) * 8, z[f"confidence_{i}"])
                _, labels = read_frame(classes, z[f"depth_{i}"], z[f"intrinsics_{i}"],
                                       z[f"cam_to_world_{i}"], room_votes)
                names_at = rooms_at(labels, z[f"floor_xy_{i}"])
                for want, got_name in zip(z[f"floor_room_{i}"].tolist(), names_at):
                    got = got_name == want
                    floor[0] += got
                    floor[1] += 1
                    by_room.setdefault(want, [0, 0])[0] += got
                    by_room[want][1] += 1
                    if confusion is not None and got_name is not None:
                        confusion[(want, got_name)] = confusion.get((want, got_name), 0) + 1
                want_here = str(z[f"here_{i}"])
                if want_here:
                    x, y, _ = z[f"pose_{i}"]
                    got_here = labels.room_at(float(x), float(y))
                    here[0] += got_here == want_here
                    here[1] += got_here is not None
                    here[2] += 1
            per_episode.append([a - b for a, b in zip([*floor, here[0], here[2]], before)])
    return {"votes": votes, "floor": round(floor[0] / max(floor[1], 1), 4),
            "floor_points": floor[1], "here": round(here[0] / max(here[2], 1), 4),
            "here_named": round(here[1] / max(here[2], 1), 4), "steps": here[2],
            "floor_by_room": {r: round(a / b, 3) for r, (a, b) in sorted(by_room.items())},
            "constants": constants, "episodes": per_episode}


# -- tuning ------------------------------------------------------------------------------------
THRESHOLDS = (0.5, 0.6, 0.7, 0.8, 0.9)  # object confidences tried


def seen_cache(folder: Path) -> list[list[dict[str, Any]]]:
    """Per episode, per frame: the ``Seen`` at each of THRESHOLDS, the truth and the pose
    (pickled next to the walks: the network's classes are read once)."""
    import pickle

    from efficienteqa.geometry import backproject
    from efficienteqa.perception.pixels import segment
    from efficienteqa.perception.pixels.segment import PixelClasses

    cache = folder / "_seen.pkl"
    if cache.exists():
        return pickle.loads(cache.read_bytes())
    out = []
    for path in episodes(folder):
        z = np.load(path)
        names = [str(c) for c in z["categories"]]
        frames = []
        for i in range(int(z["n"])):
            classes = PixelClasses(z[f"category_{i}"], z[f"colour_{i}"], z[f"state_{i}"], names,
                                   ("x",) * 64, ("x",) * 8, z[f"confidence_{i}"])
            depth, k, pose = z[f"depth_{i}"], z[f"intrinsics_{i}"], z[f"cam_to_world_{i}"]
            small = classes.category
            fy, fx = depth.shape[0] // small.shape[0], depth.shape[1] // small.shape[1]
            is_floor = np.array([n.startswith(segment.FLOOR_PREFIX) for n in names])
            floor = segment._floor_points(small, is_floor, depth, k, pose, fy, fx)
            depth_small = depth[fy // 2::fy, fx // 2::fx]
            regions = [(c, m) for c, m, sure in segment.regions_of(
                small, depth_small, names.index("door"), classes.confidence)
                if sure >= classes.min_confidence.get(names[c], segment.MIN_CONFIDENCE)]
            points = backproject(depth_small, segment.scaled_intrinsics(k, fy, fx), pose)
            seen = {}
            for t in THRESHOLDS:
                segment.OBJECT_CONFIDENCE = t
                seen[t] = segment._seen(classes, names, depth_small, points, floor, regions)
            frames.append({"seen": seen, "key": tuple(np.round(pose[:3] * 1000).astype(int)
                                                      .ravel().tolist()),
                           "floor_xy": z[f"floor_xy_{i}"], "floor_room": z[f"floor_room_{i}"],
                           "pose": z[f"pose_{i}"], "here": str(z[f"here_{i}"]), "names": names})
        out.append(frames)
    cache.write_bytes(pickle.dumps(out))
    return out


def tune(folders: list[Path], grid: dict[str, list[float]]) -> None:
    """Voted scores for every combination of ``grid``'s constants (rooms.py names, and
    OBJECT_CONFIDENCE among THRESHOLDS), on cached walks."""
    import itertools

    from efficienteqa.perception.pixels.rooms import RoomPrior, RoomVotes
    from efficienteqa.perception.pixels.segment import floor_types

    walks = [e for f in folders for e in seen_cache(f)]
    keys = list(grid)
    for values in itertools.product(*(grid[k] for k in keys)):
        sets = dict(zip(keys, values))
        threshold = sets.pop("OBJECT_CONFIDENCE", rooms_module.OBJECT_CONFIDENCE)
        for name, value in sets.items():
            setattr(rooms_module, name, value)
        prior = RoomPrior.load(rooms_module.PRIOR)
        floor, here = [0, 0], [0, 0]
        by_room: dict[str, list[int]] = {}
        here_by: dict[str, list[int]] = {}
        for frames in walks:
            votes = RoomVotes(floor_types(frames[0]["names"]), prior)
            for f in frames:
                room_map = votes.add(f["key"], f["seen"][threshold])
                got = room_map.indices_at(f["floor_xy"]) if len(f["floor_xy"]) else np.zeros(0, int)
                names = np.array([*votes.rooms, ""])[got]
                right = names == f["floor_room"]
                floor[0] += int(right.sum())
                floor[1] += len(right)
                for room, ok in zip(f["floor_room"].tolist(), right.tolist()):
                    by_room.setdefault(room, [0, 0])[0] += ok
                    by_room[room][1] += 1
                if f["here"]:
                    ok = room_map.room_at(*f["pose"][:2]) == f["here"]
                    here[0] += ok
                    here[1] += 1
                    here_by.setdefault(f["here"], [0, 0])[0] += ok
                    here_by[f["here"]][1] += 1
        print(json.dumps({"floor": round(floor[0] / max(floor[1], 1), 4),
                          "here": round(here[0] / max(here[1], 1), 4), "steps": here[1],
                          "set": {**sets, "OBJECT_CONFIDENCE": threshold},
                          "by_room": {r: round(a / b, 3) for r, (a, b) in sorted(by_room.items())},
                          "here_by_room": {r: f"{a}/{b}" for r, (a, b) in sorted(here_by.items())}}),
              flush=True)


def paired(before: list[list[int]], after: list[list[int]], draws: int = 2000,
           seed: int = 0) -> dict[str, Any]:
    """Voted minus per frame, with a 95% interval from resampling episodes (seeded)."""
    a, b = np.array(before, float), np.array(after, float)
    rng = np.random.default_rng(seed)
    out: dict[str, Any] = {"episodes": len(a)}
    for name, (right, n) in (("floor", (0, 1)), ("here", (2, 3))):
        def diff(k: np.ndarray, right: int = right, n: int = n) -> float:
            return float(b[k, right].sum() / b[k, n].sum() - a[k, right].sum() / a[k, n].sum())

        every = np.arange(len(a))
        boot = sorted(diff(rng.integers(0, len(a), len(a))) for _ in range(draws))
        out[name] = [round(100 * diff(every), 1), round(100 * boot[int(0.025 * draws)], 1),
                     round(100 * boot[int(0.975 * draws) - 1], 1)]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    p = sub.add_parser("prior")
    p.add_argument("--out", type=Path, default=rooms_module.PRIOR)
    w = sub.add_parser("walk")
    w.add_argument("--houses", required=True, help="e.g. 3000-3004 (training) or 2000-2001")
    w.add_argument("--per-house", type=int, default=2, help="questions (episodes) per house")
    w.add_argument("--first", type=int, default=0, help="the house's first question to walk")
    w.add_argument("--votes", choices=("on", "off"), default="on")
    w.add_argument("--out", type=Path, required=True)
    c = sub.add_parser("confusion")
    c.add_argument("folders", type=Path, nargs="+", help="walks of validation houses")
    s = sub.add_parser("score")
    s.add_argument("folders", type=Path, nargs="+")
    s.add_argument("--set", action="append", default=[], help="CONSTANT=VALUE of rooms.py")
    g = sub.add_parser("tune")
    g.add_argument("folders", type=Path, nargs="+")
    g.add_argument("--grid", action="append", default=[], help="CONSTANT=V1,V2,...")
    args = ap.parse_args()
    if args.what == "tune":
        tune(args.folders, {k: [float(x) for x in v.split(",")] for k, _, v in
                            (item.partition("=") for item in args.grid)})
    elif args.what == "prior":
        make_prior(args.out)
    elif args.what == "confusion":
        make_confusion(args.folders, "python -m experiments.room_votes confusion "
                       + " ".join(str(f) for f in args.folders))
    elif args.what == "walk":
        walk(parse_houses(args.houses), args.per_house, args.out, args.votes == "on", args.first)
    else:
        sets = {k: float(v) for k, _, v in (item.partition("=") for item in args.set)}
        runs = [score(args.folders, votes, **sets) for votes in (False, True)]
        for run in runs:
            print(json.dumps({k: v for k, v in run.items() if k != "episodes"}), flush=True)
        print(json.dumps(paired(runs[0]["episodes"], runs[1]["episodes"])))


if __name__ == "__main__":
    main()
