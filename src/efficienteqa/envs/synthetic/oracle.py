"""Oracle step counts: the fewest steps after which a question's evidence is in view.

Candidate poses on a ring around the evidence face it; they are tried in order of geodesic
distance from the start, rendering the instance buffer at low resolution and confirming the
winner at full resolution. The result is the physical lower bound for the "steps" metric.
"""

from __future__ import annotations

import math

import numpy as np

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.generate import ROBOT_RADIUS_M
from efficienteqa.envs.synthetic.navigation import oracle_moves, rasterise
from efficienteqa.envs.synthetic.questions import Question, evidence_visible
from efficienteqa.geometry import Pose2D, camera_to_world
from efficienteqa.mapping.navgrid import OccupancyGrid

STEP_M = 3.0
RING_M = (0.8, 5.0)
CANDIDATE_SPACING_M = 0.35
MAX_RENDERS = 80


def candidate_poses(env: SyntheticEnv, evidence: list[int], sight: OccupancyGrid | None = None
                    ) -> list[tuple[float, Pose2D]]:
    """(geodesic metres from the start, pose facing the evidence) for reachable ring cells."""
    centre = np.mean([[env.house.object(e).x, env.house.object(e).y] for e in evidence], axis=0)
    field_m = env.grid.distance_field((env.house.start.x, env.house.start.y), ROBOT_RADIUS_M)
    xs, ys = env.grid.spec.centres()
    stride = max(1, round(CANDIDATE_SPACING_M / env.grid.spec.resolution_m))
    sub = (slice(None, None, stride), slice(None, None, stride))
    dist_to_evidence = np.hypot(xs[sub] - centre[0], ys[sub] - centre[1])
    ok = np.isfinite(field_m[sub]) & (dist_to_evidence >= RING_M[0]) & (dist_to_evidence <= RING_M[1])
    sight = sight if sight is not None else _sight_grid(env)
    out = []
    for x, y, d in zip(xs[sub][ok], ys[sub][ok], field_m[sub][ok]):
        offset = centre - (x, y)
        near = centre - offset / np.linalg.norm(offset) * 0.5  # just off the evidence itself
        if sight.line_of_sight((x, y), near):
            out.append((float(d), Pose2D(float(x), float(y), math.atan2(offset[1], offset[0]))))
    out.sort(key=lambda c: c[0])
    return out


def _sight_grid(env: SyntheticEnv) -> OccupancyGrid:
    """Walls and doors only: what blocks the view across a room (furniture is mostly low)."""
    lay = env.house.layout
    return rasterise(
        env.grid.spec,
        [(r.x0, r.y0, r.x1, r.y1) for r in lay.rooms],
        [(w.x0, w.y0, w.x1, w.y1, w.thickness_m) for w in lay.walls if w.z0 < 0.5],
        [o.footprint() for o in env.house.objects if o.category == "door"],
    )


def oracle_steps(env: SyntheticEnv, question: Question, sight: OccupancyGrid | None = None
                 ) -> tuple[int | None, Pose2D | None]:
    """(observations until the evidence is in view, the pose that shows it) or (None, None)."""
    if not question.evidence:
        return None, None
    full = env.camera
    low = full.scaled(full.width // 4, full.height // 4)
    start_view = env.renderer.render(camera_to_world(env.house.start, full))
    if evidence_visible(start_view.instance, question.evidence):
        return 1, env.house.start
    for rendered, (dist_m, pose) in enumerate(candidate_poses(env, question.evidence, sight)):
        if rendered >= MAX_RENDERS:
            break
        frame = env.renderer.render(camera_to_world(pose, low), camera=low)
        if not evidence_visible(frame.instance, question.evidence):
            continue
        confirm = env.renderer.render(camera_to_world(pose, full))
        if evidence_visible(confirm.instance, question.evidence):
            start_xy = (env.house.start.x, env.house.start.y)
            moves = oracle_moves(env.grid, start_xy, [(pose.x, pose.y)], ROBOT_RADIUS_M, STEP_M)
            return 1 + max(1, moves if moves is not None else math.ceil(dist_m / STEP_M)), pose
    return None, None


def annotate(env: SyntheticEnv, questions: list[Question]) -> list[Question]:
    """Fill in oracle steps and poses; drop questions whose evidence can never be seen."""
    sight = _sight_grid(env)  # one walls-and-doors grid for all questions of the house
    kept = []
    for q in questions:
        steps, pose = oracle_steps(env, q, sight)
        if q.evidence and steps is None:
            continue
        q.oracle_steps = steps
        q.oracle_pose = (round(pose.x, 3), round(pose.y, 3), round(pose.yaw, 4)) if pose else None
        kept.append(q)
    return kept
