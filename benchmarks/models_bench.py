"""Model back-end benchmark: latency and tokens per call type on the default stack.

Back-ends: the embedded language model (Qwen2.5-Coder-1.5B-Instruct Q4_K_M, llama.cpp server on
loopback, 2 threads) reading semantic-sensor descriptions of synthetic-house frames (CC0
furniture); grouping with the rule grouper and the LLM confirmer. No image model is involved.

    python -m benchmarks.models_bench [--model qwen2.5-coder-1.5b] [--calls 8]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time
from pathlib import Path

import numpy as np

from efficienteqa.answer.calls import answer_with_confidence
from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.labels import HouseLabels
from efficienteqa.explore.prompting import candidate_points
from efficienteqa.explore.vlm_scorer import explore_scores
from efficienteqa.geometry import Pose2D
from efficienteqa.mapping.maps2d import Mapper
from efficienteqa.mapping.tsdf import VolumeSpec
from efficienteqa.models import local
from efficienteqa.models.backends import ChatBackend, build_chat_model
from efficienteqa.perception.semantic import describe_directions, describe_frame
from efficienteqa.scenes import synthetic_questions
from efficienteqa.vc.grouping import LLMGrouper, RuleGrouper


def frames(env: SyntheticEnv, n: int):
    """(observation, description, direction texts) at n navigable poses with prompts."""
    lo, hi = env.bounds
    rng = np.random.default_rng(0)
    cells = np.argwhere(env.grid.navigable(0.3))
    labels = HouseLabels(env.house)
    out = []
    while len(out) < n:
        x, y = env.grid.spec.cell_to_world(cells[rng.integers(len(cells))])
        mapper = Mapper(VolumeSpec.around(lo[:2], hi[:2], 0.0), 0.0, (x, y))
        obs = env.observe(Pose2D(float(x), float(y), float(rng.uniform(-np.pi, np.pi))))
        state = mapper.update(obs)
        prompts = candidate_points(state, obs.cam_to_world, obs.intrinsics, (640, 480), 0)
        if len(prompts) >= 2:
            out.append((obs, describe_frame(obs, labels).text,
                        describe_directions(obs, prompts, labels)))
    return out


def stats(name: str, latencies: list[float], prompt_tokens: list[int],
          completion_tokens: list[int], extra: str = "") -> None:
    lat = np.array(latencies)
    print(f"{name:22s} n={len(lat):2d}  median {np.median(lat):5.2f} s  p90 "
          f"{np.percentile(lat, 90):5.2f} s  prompt {statistics.median(prompt_tokens):4.0f} tok  "
          f"completion {statistics.median(completion_tokens):3.0f} tok  {extra}")


def server_peak_mib(info: local.ServerInfo) -> float:
    for line in Path(f"/proc/{info.pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=local.DEFAULT_MODEL)
    parser.add_argument("--calls", type=int, default=8)
    parser.add_argument("--seed", type=int, default=21, help="synthetic house")
    args = parser.parse_args()

    local.stop(args.model)
    start = time.perf_counter()
    info = local.serve(args.model)
    print(f"server start to healthy: {time.perf_counter() - start:.1f} s ({args.model})")
    model = build_chat_model(ChatBackend("local", args.model, base_url=info.base_url, cache=False))
    env = SyntheticEnv.from_seed(args.seed)
    questions = [q.question for q in synthetic_questions(env)]
    views = frames(env, args.calls)

    lat, pt, ct, problems = [], [], [], 0
    for _, view, directions in views:
        before = model.usage.prompt_tokens, model.usage.completion_tokens
        t = time.perf_counter()
        score = explore_scores(model, questions[0], view, directions)  # one episode's question
        lat.append(time.perf_counter() - t)
        pt.append(model.usage.prompt_tokens - before[0])
        ct.append(model.usage.completion_tokens - before[1])
        problems += bool(score.info["problems"])
    stats("explore (LSV + GSV)", lat, pt, ct, f"replies needing repair: {problems}/{len(lat)}")

    lat, pt, ct = [], [], []
    texts = [v for _, v, _ in views]
    for k in range(min(args.calls, len(questions))):
        before = model.usage.prompt_tokens, model.usage.completion_tokens
        t = time.perf_counter()
        answer_with_confidence(model, questions[k], texts[k:k + 5] or texts[:5], RuleGrouper())
        lat.append(time.perf_counter() - t)
        pt.append(model.usage.prompt_tokens - before[0])
        ct.append(model.usage.completion_tokens - before[1])
    stats("answer (top-5 frames)", lat, pt, ct)

    grouper = LLMGrouper(model)
    pairs = [("sofa", "couch"), ("in the kitchen", "kitchen counter"), ("a mug", "a cup"),
             ("fridge", "refrigerator"), ("on the table", "on the desk"), ("lamp", "light")]
    lat, pt, ct = [], [], []
    for a, b in pairs:
        before = model.usage.calls, model.usage.prompt_tokens, model.usage.completion_tokens
        t = time.perf_counter()
        grouper.partition("What is it?", [a, b])
        if model.usage.calls > before[0]:
            lat.append(time.perf_counter() - t)
            pt.append(model.usage.prompt_tokens - before[1])
            ct.append(model.usage.completion_tokens - before[2])
    if lat:
        stats("grouping (one pair)", lat, pt, ct, f"{len(lat)} of {len(pairs)} pairs reached the model")

    cached = build_chat_model(ChatBackend("local", args.model, base_url=info.base_url))
    explore_scores(cached, questions[0], texts[0], views[0][2])
    t = time.perf_counter()
    explore_scores(cached, questions[0], texts[0], views[0][2])
    print(f"cache hit: {1e3 * (time.perf_counter() - t):.1f} ms")
    print(f"peak memory: server {server_peak_mib(info):.0f} MiB, this process "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")
    print("judging: LLM-Match is measured by the evaluation, not here")


if __name__ == "__main__":
    main()
