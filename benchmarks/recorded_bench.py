"""A recorded walk answered end to end: how long each phase takes per frame.

A synthetic walk (a house's rooms visited in turn along shortest paths, a frame every 0.25 m
and a look around in each room) is written as an MCAP file as a robot would record it (rgb8,
16UC1 depth in millimetres, camera_info, /tf at 10 Hz stamps) with the simulator's instance ids
and labels, then asked about as `efficienteqa ask --scene recorded:walk.mcap` does (the
``ask`` job, report included, with a progress bar), on the default stack but the model server:
semantic-sensor perception, MiniLM relevancy, the rules gate, a stub chat model (answers
"white"), every frame read (the relevancy stop off unless ``--early-stop``). The phases are
timed by wrapping their methods in this process only:

- reading: the walk's reset/step (MCAP decoding, images to arrays);
- perception: the semantic sensor's descriptions; relevancy: MiniLM; gate: the rules gate;
- mapping: TSDF integration of every frame and the 2-D maps (refreshed once, at the end);
- answer: the answer call; other: the rest (the report's thumbnails and page, bookkeeping).

    python -m benchmarks.recorded_bench --frames 300 [--assets builtin] [--out out/recorded-bench]
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from efficienteqa.agent import AgentConfig
from efficienteqa.ask import ask
from efficienteqa.envs.recorded import open_recording
from efficienteqa.envs.recorded.write import WalkRecorder
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS
from efficienteqa.geometry import Pose2D
from efficienteqa.models.stub import StubChatModel
from efficienteqa.scenes import Scene
from efficienteqa.stack import Stack

QUESTION = "What colour is the bed?"
STEP_M = 0.25


def walk_poses(env: SyntheticEnv, frames: int) -> list[Pose2D]:
    """Room centres in turn along shortest paths, a pose every STEP_M facing the way, and eight
    views around at each centre, until ``frames`` poses."""
    grid, here = env.grid, env.start
    poses = [here]
    rooms = [r for r in env.house.layout.rooms]
    k = 0
    while len(poses) < frames:
        room = rooms[k % len(rooms)]
        k += 1
        path = grid.shortest_path((here.x, here.y), ((room.x0 + room.x1) / 2,
                                                     (room.y0 + room.y1) / 2), ROBOT_RADIUS_M)
        if path is None or len(path) < 2:
            continue
        yaw = here.yaw
        for a, b in zip(path[:-1], path[1:]):
            length = float(np.hypot(*(b - a)))
            yaw = math.atan2(b[1] - a[1], b[0] - a[0])
            for s in np.arange(STEP_M, length + 1e-9, STEP_M):
                p = a + (b - a) * (s / length)
                poses.append(Pose2D(float(p[0]), float(p[1]), yaw))
        end = path[-1]
        poses += [Pose2D(float(end[0]), float(end[1]), yaw + i * math.pi / 4) for i in range(1, 9)]
        here = poses[-1]
    return poses[:frames]


def record_walk(seed: int, assets: str, frames: int, path: Path) -> dict[str, float]:
    t0 = time.perf_counter()
    env = SyntheticEnv.from_seed(seed, assets)
    poses = walk_poses(env, frames)
    t1 = time.perf_counter()
    render = write = 0.0
    clock = iter(range(10**18, 10**18 + frames * 10**8, 10**8))  # 10 Hz stamps
    with WalkRecorder(path, labels=env.scene_labels(), depth_encoding="16UC1",
                      clock=lambda: next(clock)) as recorder:
        for pose in poses:
            t = time.perf_counter()
            obs = env.observe(pose)
            render += time.perf_counter() - t
            t = time.perf_counter()
            recorder.add(obs)
            write += time.perf_counter() - t
    env.close()
    return {"house_s": t1 - t0, "render_s": render, "write_s": write,
            "mcap_mb": path.stat().st_size / 1e6}


class Timer:
    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)

    def wrap(self, phase: str, fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def timed(*args: Any, **kwargs: Any) -> Any:
            t = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds[phase] += time.perf_counter() - t
                self.calls[phase] += 1
        return timed


@contextmanager
def timed_phases(timer: Timer) -> Iterator[None]:
    """Wraps the phases' methods on their classes for the duration (this process only)."""
    from efficienteqa.mapping.maps2d import Mapper
    from efficienteqa.perception.semantic import SemanticPerception
    from efficienteqa.relevancy.text import MiniLMScorer
    from efficienteqa.stop.gate import RulesGate

    patched = [(SemanticPerception, "describe", "perception"), (MiniLMScorer, "score_many", "relevancy"),
               (RulesGate, "check", "gate"), (Mapper, "integrate", "mapping: integrate"),
               (Mapper, "state", "mapping: 2-D maps")]
    saved = [(cls, name, cls.__dict__[name]) for cls, name, _ in patched]
    try:
        for cls, name, phase in patched:
            setattr(cls, name, timer.wrap(phase, cls.__dict__[name]))
        yield
    finally:
        for cls, name, fn in saved:
            setattr(cls, name, fn)


class TimedWalk:
    """The recorded walk with its reads timed (``reading``)."""

    recorded = True

    def __init__(self, walk: Any, timer: Timer) -> None:
        self._walk, self.camera, self.note = walk, walk.camera, walk.note
        self.reset = timer.wrap("reading", walk.reset)
        self.step = timer.wrap("reading", walk.step)
        self.observe, self.close, self.scene_labels = walk.observe, walk.close, walk.scene_labels

    @property
    def length(self) -> int:
        return int(self._walk.length)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--assets", default=DEFAULT_ASSETS)
    parser.add_argument("--early-stop", action="store_true",
                        help="Let the relevancy stop end the reading (default: read every frame).")
    parser.add_argument("--out", default="out/recorded-bench")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"walk-{args.seed}-{args.assets}-{args.frames}.mcap"
    made = record_walk(args.seed, args.assets, args.frames, path) if not path.exists() else {}
    if made:
        print(f"recorded {path}: {made['mcap_mb']:.0f} MB, rendering {made['render_s']:.1f} s, "
              f"writing {made['write_s']:.1f} s")
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    from efficienteqa.stack import build_relevancy

    t = time.perf_counter()
    build_relevancy("minilm")  # loading MiniLM, apart: a CLI run pays it once
    load_s = time.perf_counter() - t
    timer = Timer()
    t0 = time.perf_counter()
    walk = TimedWalk(timer.wrap("opening", open_recording)(str(path)), timer)
    print(walk.note)
    model = StubChatModel(lambda messages: "white", name="stub")
    with timed_phases(timer), Progress("{task.description}", BarColumn(), MofNCompleteColumn(),
                                       TimeElapsedColumn()) as progress:
        task = progress.add_task("reading frames", total=walk.length)
        done = ask(QUESTION, Scene(walk, f"recorded:{path.name} (mcap)"), out / "episode",
                   stack=Stack(), model=model, config=AgentConfig.of(enabled=args.early_stop),
                   on_step=lambda record, *_: progress.update(task, completed=record.step))
    wall = time.perf_counter() - t0
    result = done.result
    phases = dict(timer.seconds)
    phases["answer"] = result.answer_s
    phases["other"] = wall - sum(phases.values())
    row = {"frames": result.steps, "stop": result.stop_reason, "answer": result.answer,
           "wall_s": round(wall, 2), "minilm_load_s": round(load_s, 2),
           "phases_s": {k: round(v, 2) for k, v in phases.items()},
           "per_frame_ms": {k: round(1e3 * v / max(result.steps, 1), 1) for k, v in phases.items()},
           **({"recording": {k: round(v, 2) for k, v in made.items()}} if made else {})}
    print(json.dumps(row, indent=1))
    (out / "recorded_bench.json").write_text(json.dumps(row, indent=1) + "\n")


if __name__ == "__main__":
    main()
