"""Direction benchmark (DESIGN 8): which lettered direction leads to the evidence?

Frames come from exploration episodes in synthetic houses, run with the explore module as the
agent runs it (SFE, the default prompt points; flat semantic values, so the episodes do not
depend on any scorer). Every step where the module offered lettered directions is kept with
what the text model would read (the ``semantic`` perception's view text and each letter's
direction text, exactly as ``explore_request`` gives them), each point's xy, its straight-line
range from the robot and its path distance to the nearest evidence view reachable from the start
(the sound oracle, ``explore/oracle.py``). The best letters are the closest ones; a frame where
no point has a finite distance, or where every point is tied, is dropped. An episode ends when
the evidence is first in view (directions matter until then) or at the step budget.

    python -m experiments.direction_bench frames --seeds training --out out/direction/train.jsonl
    python -m experiments.direction_bench frames --seeds 2000-2039 --out out/direction/held.jsonl
    python -m experiments.direction_bench score out/direction/held.jsonl --scorers random,nearest,...

Scorers are evaluated on the cached frames without re-rendering. Top-1 counts fractional credit
for ties of the scorer (k letters tied at the scorer's best, j of them oracle-best: j / k), so
no random tie-break is needed; Spearman is per frame between the scores and the negative
distances (a frame with constant scores counts 0), averaged over frames. Tune on the training
houses (0-20) only; report the held-out houses (2000 and up).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from efficienteqa.agent import AgentConfig
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.questions import Question, evidence_visible
from efficienteqa.explore.module import SemanticScore
from efficienteqa.explore.text_scorers import DirectionFrame
from efficienteqa.observation import Observation, PromptPoint
from efficienteqa.perception.semantic import SemanticPerception
from efficienteqa.scenes import synthetic_questions
from experiments.common import evidence_distance, explore_episode, seed_set

TIE_M = 0.05  # distances within this of the least are tied for best


@dataclass
class Frame:
    """One prompted step, as cached in the JSONL file."""

    question: str
    question_id: str
    house: int
    step: int
    view: str
    directions: dict[str, str]  # letter -> direction text, as the model reads it
    xy: dict[str, list[float]]  # letter -> floor point (m)
    ranges_m: dict[str, float]  # letter -> straight line from the robot (m)
    distances_m: dict[str, float | None]  # letter -> path to the evidence (None: unreachable)

    def direction_frame(self) -> DirectionFrame:
        return DirectionFrame(self.question, self.view, dict(self.directions),
                              dict(self.ranges_m))

    @property
    def best(self) -> list[str]:
        return best_letters(self.distances_m) or []


def best_letters(distances: dict[str, float | None], tie_m: float = TIE_M) -> list[str] | None:
    """The oracle-best letters (path distance within ``tie_m`` of the least), or None when the
    frame cannot label anything: no finite distance, or every letter tied."""
    finite = {k: float(d) for k, d in distances.items() if d is not None and math.isfinite(d)}
    if not finite:
        return None
    least = min(finite.values())
    best = [k for k, d in finite.items() if d <= least + tie_m]
    return None if len(best) == len(distances) else sorted(best)


def top1_credit(scores: dict[str, float], best: Sequence[str]) -> float:
    """Fractional top-1 credit: the share of the scorer's tied-best letters that are oracle-best."""
    hi = max(scores.values())
    top = [k for k, v in scores.items() if v >= hi - 1e-12]
    return sum(k in best for k in top) / len(top)


def spearman(scores: dict[str, float], distances: dict[str, float | None]) -> float:
    """Spearman's rho between the scores and the negative distances (unreachable: +inf away),
    with average ranks for ties; 0 when either side is constant."""
    letters = sorted(scores)
    a = _ranks([scores[k] for k in letters])
    b = _ranks([-(distances[k] if distances[k] is not None else math.inf) for k in letters])
    a, b = a - a.mean(), b - b.mean()
    den = math.sqrt(float((a * a).sum() * (b * b).sum()))
    return float((a * b).sum() / den) if den > 0 else 0.0


def _ranks(values: Sequence[float]) -> np.ndarray:
    v = np.asarray(values, float)
    order = np.argsort(v, kind="stable")
    ranks = np.empty(len(v))
    ranks[order] = np.arange(len(v), dtype=float)
    for x in np.unique(v):  # average ranks of ties
        ranks[v == x] = ranks[v == x].mean()
    return ranks


class FrameRecorder:
    """A ``SemanticScorer`` that records each prompted frame and answers flat values."""

    def __init__(self, perception: SemanticPerception, distance_m: Callable[[Sequence[float]], float],
                 q: Question, house: int) -> None:
        self.perception, self.distance_m, self.q, self.house = perception, distance_m, q, house
        self.frames: list[Frame] = []
        self.dropped_at: list[int] = []  # the steps of prompted frames that label nothing
        self._new: list[Frame | None] = []  # recorded this step (None: dropped), not stamped

    def stamp(self, step: int) -> None:
        """Give the frames recorded since the last call their step (the agent's step hook)."""
        for f in self._new:
            if f is None:
                self.dropped_at.append(step)
            else:
                f.step = step
                self.frames.append(f)
        self._new = []

    def score(self, obs: Observation, prompts: list[PromptPoint], question: str) -> SemanticScore:
        request = self.perception.explore_request(obs, prompts)
        distances = {p.letter: _finite_or_none(self.distance_m(p.xy)) for p in prompts}
        frame = Frame(question, self.q.id, self.house, 0, request.view,
                      dict(request.directions),  # type: ignore[arg-type]
                      {p.letter: [round(p.xy[0], 3), round(p.xy[1], 3)] for p in prompts},
                      {p.letter: round(float(np.hypot(p.xy[0] - obs.pose.x, p.xy[1] - obs.pose.y)), 3)
                       for p in prompts},
                      distances)
        self._new.append(None if best_letters(distances) is None else frame)
        share = 1.0 / len(prompts)
        return SemanticScore({p.letter: share for p in prompts}, 0.5)


def _finite_or_none(d: float) -> float | None:
    return round(float(d), 3) if math.isfinite(d) else None


def episode_frames(env: SyntheticEnv, q: Question, seed: int, explorer_seed: int
                   ) -> tuple[list[Frame], int]:
    """The labelled frames of one episode, and how many prompted frames were dropped. The
    episode is the agent's loop (SFE with the default options, no target steering) with the
    recorder as its scorer, up to the step the evidence is first in view (that step's frame
    is not kept: directions matter until then)."""
    distance_m = evidence_distance(env, q)
    if not distance_m.reachable:
        return [], 0
    recorder = FrameRecorder(SemanticPerception(env.scene_labels()), distance_m, q, seed)
    ep = explore_episode(env, AgentConfig.of(explorer="sfe", seed=explorer_seed, steering="none"),
                         q.question, scorer=recorder,
                         seen=lambda instance: evidence_visible(instance, q.evidence),
                         on_step=lambda record, obs, out: recorder.stamp(record.step))
    end = ep.first_seen or ep.steps + 1
    return ([f for f in recorder.frames if f.step < end],
            sum(step < end for step in recorder.dropped_at))


def cmd_frames(args: argparse.Namespace) -> None:
    seeds = seed_set(args.seeds)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    done = {(f["house"], f["question_id"]) for f in map(json.loads, out.open())} \
        if out.exists() and args.resume else set()
    total = dropped = 0
    with out.open("a" if args.resume else "w") as fh:
        for seed in seeds:
            if total >= args.frames:
                break
            with SyntheticEnv.from_seed(seed, args.assets) as env:
                asked = [q for q in synthetic_questions(env) if q.evidence and q.oracle_steps]
                turn = seed % len(asked) if asked else 0
                for q in (asked[turn:] + asked[:turn])[:args.per_house]:
                    if (seed, q.id) in done:
                        continue
                    frames, lost = episode_frames(env, q, seed, seed * 1000)
                    frames = spread(frames, args.per_episode)
                    for f in frames:
                        fh.write(json.dumps(asdict(f)) + "\n")
                    fh.flush()
                    total += len(frames)
                    dropped += lost
                    print(f"house {seed} {q.id}: {len(frames)} frames ({lost} dropped)  "
                          f"{q.question}", flush=True)
    print(f"{total} frames written to {out} ({dropped} prompted frames dropped: no finite "
          f"distance or all tied); seeds {args.seeds}")


def spread(frames: list[Frame], n: int) -> list[Frame]:
    """At most ``n`` frames, evenly spaced over the episode (consecutive frames look alike)."""
    if len(frames) <= n:
        return frames
    return [frames[int(i)] for i in np.linspace(0, len(frames) - 1, n).round()]


def load_frames(path: str | Path) -> list[Frame]:
    return [Frame(**json.loads(line)) for line in Path(path).open() if line.strip()]


# name -> factory() -> object with ``letter_scores(DirectionFrame) -> (scores, info)``
def _scorers() -> dict[str, Callable[[], object]]:
    from efficienteqa.explore import text_scorers as ts
    from experiments import direction_scorers as ds

    def model() -> object:
        from efficienteqa.models.backends import ChatBackend, build_chat_model

        return build_chat_model(ChatBackend(cache=True))

    def vlm(kind: str) -> Callable[[], object]:
        return lambda: ds.ELICITATIONS[kind](model())

    out: dict[str, Callable[[], object]] = {
        "random": lambda: ds.RandomDirections(seed=0),
        "nearest": ds.NearestDirections,
        "keyword": ds.KeywordDirections,
        "minilm": lambda: ds.EmbeddingDirections.from_package(),
        "minilm-parts": lambda: ds.EmbeddingDirections.from_package(parts=True),
        "minilm-parts-near": lambda: ds.EmbeddingDirections.from_package(parts=True,
                                                                         near_weight=1.0),
        "direction-logit": lambda: ts.LogitDirections(ts.LOGIT_WEIGHTS, name="direction-logit"),
    }
    from experiments.direction_scorers import ELICITATIONS

    for kind in ELICITATIONS:
        out[kind] = vlm(kind)
    return out


@dataclass
class Result:
    name: str
    frames: int
    top1: float
    spearman: float
    ms: float
    problems: int


def evaluate(scorer: object, frames: Sequence[Frame], name: str) -> Result:
    credits, rhos, times, problems = [], [], [], 0
    for f in frames:
        start = time.perf_counter()
        scores, info = scorer.letter_scores(f.direction_frame())  # type: ignore[attr-defined]
        times.append(time.perf_counter() - start)
        problems += bool(info.get("problems"))
        credits.append(top1_credit(scores, f.best))
        rhos.append(spearman(scores, f.distances_m))
    return Result(name, len(frames), float(np.mean(credits)), float(np.mean(rhos)),
                  1e3 * float(np.mean(times)), problems)


def oracle_result(frames: Sequence[Frame]) -> Result:
    credits = [top1_credit({k: -(d if d is not None else math.inf) for k, d in f.distances_m.items()},
                           f.best) for f in frames]
    rhos = [spearman({k: -(d if d is not None else 1e9) for k, d in f.distances_m.items()},
                     f.distances_m) for f in frames]
    return Result("oracle", len(frames), float(np.mean(credits)), float(np.mean(rhos)), 0.0, 0)


def cmd_score(args: argparse.Namespace) -> None:
    frames = load_frames(args.frames)
    if args.limit and args.limit < len(frames):  # evenly spaced over the file: every house
        frames = [frames[int(i)] for i in np.linspace(0, len(frames) - 1, args.limit).round()]
    if args.take:
        frames = frames[:args.take]
    houses = sorted({f.house for f in frames})
    print(f"{len(frames)} frames from {len(houses)} houses ({houses[0]}-{houses[-1]}: "
          f"{','.join(map(str, houses))}), {len({f.question_id for f in frames})} questions; "
          f"chance top-1 {np.mean([len(f.best) / len(f.directions) for f in frames]):.3f}")
    factories = _scorers()
    names = args.scorers.split(",")
    results = [oracle_result(frames)]
    for name in names:
        if name == "oracle":
            continue
        if name not in factories:
            raise SystemExit(f"unknown scorer {name!r}: one of {', '.join(factories)}")
        results.append(evaluate(factories[name](), frames, name))
        r = results[-1]
        print(f"  {r.name:22s} top-1 {r.top1:.3f}  spearman {r.spearman:+.3f}  "
              f"{r.ms:8.1f} ms/frame  unreadable {r.problems}", flush=True)
    print()
    print_table([asdict(r) for r in results])
    if args.json:
        Path(args.json).write_text(json.dumps([asdict(r) for r in results], indent=1))


def print_table(results: Sequence[dict], run: str = "") -> None:
    """The markdown table of scorer results (dicts of ``evaluate``'s fields)."""
    lead = "| run " if run else ""
    print(f"{lead}| scorer | frames | top-1 | Spearman | ms/frame (mean) | unreadable |")
    print("|---" * (6 + bool(run)) + "|")
    for r in results:
        cell = f"| {run} " if run else ""
        print(f"{cell}| {r['name']} | {r['frames']} | {r['top1']:.3f} | {r['spearman']:+.3f} | "
              f"{r['ms']:.1f} | {r['problems']} |")


def cmd_table(args: argparse.Namespace) -> None:
    """The README's table from the ``--json`` files of earlier ``score`` runs."""
    for k, name in enumerate(args.files):
        rows = json.loads(Path(name).read_text())
        if k:
            print()
        print(f"{name}:")
        print_table(rows)


def fit_logit(features: Sequence[np.ndarray], best: Sequence[np.ndarray], l2: float = 0.05
              ) -> np.ndarray:
    """Weights of the conditional logit (``LogitDirections``) by maximum likelihood of the
    oracle-best letters (their summed probability), with an L2 penalty ``l2``."""
    from scipy.optimize import minimize

    def loss(w: np.ndarray) -> float:
        total = 0.0
        for x, b in zip(features, best):
            z = x @ w
            p = np.exp(z - z.max())
            total -= math.log(float((p * b).sum() / p.sum()) + 1e-12)
        return total / len(features) + l2 * float(w @ w)

    return np.asarray(minimize(loss, np.zeros(features[0].shape[1]), method="L-BFGS-B").x)


def cmd_fit(args: argparse.Namespace) -> None:
    """Fit the logit's weights on training frames; top-1 by leave-houses-out cross-validation
    (5 folds by house seed) and on the frames fitted."""
    from efficienteqa.explore.text_scorers import FEATURES, LogitDirections, direction_features

    frames = load_frames(args.frames)
    if any(f.house >= 2000 for f in frames):
        raise SystemExit("fit on training houses only")
    embedder = None
    if args.embed:
        from efficienteqa.relevancy.text import MiniLMScorer

        embedder = MiniLMScorer.from_package(num_threads=1)
    xs = [direction_features(f.direction_frame(), embedder) for f in frames]
    if not args.embed:
        xs = [x[:, :-2] for x in xs]
    bs = [np.array([x in f.best for x in f.directions], float) for f in frames]
    houses = np.array([f.house for f in frames])
    credit = []
    for k in range(5):
        train = [i for i in range(len(frames)) if houses[i] % 5 != k]
        w = fit_logit([xs[i] for i in train], [bs[i] for i in train], args.l2)
        for i in range(len(frames)):
            if houses[i] % 5 == k:
                z = xs[i] @ w
                credit.append(top1_credit(dict(zip(frames[i].directions, z)), frames[i].best))
    w = fit_logit(xs, bs, args.l2)
    weights = list(w) + ([] if args.embed else [0.0, 0.0])
    fitted = evaluate(LogitDirections(weights, embedder), frames, "fitted")
    print(f"{len(frames)} frames, houses {sorted(set(houses.tolist()))}; l2 {args.l2}; "
          f"embedder {'MiniLM' if args.embed else 'none'}")
    print(f"top-1 leave-houses-out (5 folds) {np.mean(credit):.3f}; on the fitted frames "
          f"{fitted.top1:.3f}, Spearman {fitted.spearman:+.3f}")
    print("weights = (" + ", ".join(f"{v:.4f}" for v in weights) + ")  # " + ", ".join(FEATURES))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     epilog=__doc__.split("\n\n", 1)[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="job", required=True)
    frames = sub.add_parser("frames", help="run episodes and cache labelled frames as JSONL")
    frames.add_argument("--seeds", default="training",
                        help="'training' (0-20), 'held-out' (2000-2999) or seeds like 2000-2039")
    frames.add_argument("--assets", default="sh3d", choices=["sh3d", "builtin"])
    frames.add_argument("--per-house", type=int, default=2, help="questions per house")
    frames.add_argument("--per-episode", type=int, default=8,
                        help="at most this many frames per episode, evenly spaced")
    frames.add_argument("--frames", type=int, default=10**9, help="stop after this many frames")
    frames.add_argument("--resume", action="store_true", help="append, skipping done questions")
    frames.add_argument("--out", default="out/direction/frames.jsonl")
    score = sub.add_parser("score", help="evaluate scorers on cached frames")
    score.add_argument("frames")
    score.add_argument("--scorers", default="random,nearest,keyword,minilm")
    score.add_argument("--limit", type=int, default=0, help="N frames evenly spaced over the file (the "
                       "model's elicitations are slow on 2 cores)")
    score.add_argument("--take", type=int, default=0,
                       help="then only the first N of those (a smaller run of the same frames)")
    score.add_argument("--json", default="", help="write the results here too")
    fit = sub.add_parser("fit", help="fit the logit scorer's weights on training frames")
    fit.add_argument("frames")
    fit.add_argument("--l2", type=float, default=0.05)
    fit.add_argument("--embed", action=argparse.BooleanOptionalAction, default=True,
                     help="with the two MiniLM cosine features")
    table = sub.add_parser("table", help="print the tables of earlier score runs (--json files)")
    table.add_argument("files", nargs="+")
    args = parser.parse_args()
    {"frames": cmd_frames, "score": cmd_score, "fit": cmd_fit, "table": cmd_table}[args.job](args)


if __name__ == "__main__":
    main()
