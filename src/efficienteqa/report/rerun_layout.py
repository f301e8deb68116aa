"""Where an episode's rerun log puts things: the entity paths, the colours of the curves, and
the viewer's layout (``blueprint``). Kept apart from ``rerun_log`` (which logs to these paths)
so that the viewer's shape is read in one place. Entity paths:

- ``world`` (right-handed, z up, metres: the canonical frame): ``world/camera`` the frame's
  pose (``cam_to_world``) and pinhole (OpenCV axes: RDF), with ``world/camera/rgb`` (JPEG) and
  ``world/camera/depth`` (metres, ``meter`` 1); ``world/robot`` the robot's pose (x, y, yaw),
  its heading an arrow; ``world/trajectory`` the poses so far on the floor; from the explore
  module's steps: ``world/frontiers`` (labels: member cells), ``world/prompts`` (labels:
  letter and local value), ``world/target`` and ``world/plan`` (the path to the next pose);
- ``map``: the top-down picture (``mapping.visualize.map_image``) per explore step, and the
  final map at the last step;
- ``relevancy/sim`` (Sim per valid frame), ``relevancy/threshold`` (the threshold that acted:
  ``mu + z_applied * sigma``, the dashed line of report.html), ``relevancy/tested`` (the Sim it
  was compared with: the frame tested, the best so far under ``lookback``),
  ``relevancy/sim_abs`` (a rule with ``absolute``), ``relevancy/retrieved`` (the top-K's Sims,
  at their steps); ``zscore/z`` and ``zscore/z_applied``;
- ``episode/question``, ``episode/steps`` (one line per step), ``episode/answer`` (answer,
  confidence, stop reason, retrieved steps) and ``episode/retrieved/<rank>`` (the top-K frames
  as captured, with their ``frame_step`` and ``sim``).
"""

from __future__ import annotations

from typing import Any

WORLD = "world"
CAMERA = "world/camera"
RGB = "world/camera/rgb"
DEPTH = "world/camera/depth"
ROBOT = "world/robot"
TRAJECTORY = "world/trajectory"
FRONTIERS = "world/frontiers"
PROMPTS = "world/prompts"
TARGET = "world/target"
PLAN = "world/plan"
MAP = "map"
SIM = "relevancy/sim"
THRESHOLD = "relevancy/threshold"
TESTED = "relevancy/tested"
SIM_ABS = "relevancy/sim_abs"
RETRIEVED_SIM = "relevancy/retrieved"
Z = "zscore/z"
Z_APPLIED = "zscore/z_applied"
QUESTION = "episode/question"
STEPS = "episode/steps"
ANSWER = "episode/answer"
RETRIEVED = "episode/retrieved"

SIM_BLUE, THRESHOLD_RED, GREY = (0x33, 0x66, 0x99), (0xDD, 0x33, 0x33), (0x99, 0x99, 0x99)


def blueprint(top_k: int) -> Any:
    """The viewer's layout: the world in 3D with the camera below it, the map, the relevancy
    and z curves and the text, and the top-K frames in a column."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(origin=WORLD, name="world"),
                rrb.Horizontal(rrb.Spatial2DView(origin=CAMERA, contents=f"{RGB}/**", name="camera"),
                               rrb.Spatial2DView(origin=CAMERA, contents=f"{DEPTH}/**", name="depth")),
                row_shares=[2, 1]),
            rrb.Vertical(
                rrb.Spatial2DView(origin=MAP, name="map"),
                rrb.TimeSeriesView(origin="relevancy", name="relevancy"),
                rrb.TimeSeriesView(origin="zscore", name="z"),
                rrb.Tabs(rrb.TextDocumentView(origin=ANSWER, name="answer"),
                         rrb.TextLogView(origin=STEPS, name="steps"),
                         rrb.TextDocumentView(origin=QUESTION, name="question")),
                row_shares=[3, 2, 1, 2]),
            rrb.Vertical(*(rrb.Spatial2DView(origin=f"{RETRIEVED}/{rank}", name=f"top {rank}")
                           for rank in range(1, max(top_k, 1) + 1))),
            column_shares=[3, 2, 1]))

