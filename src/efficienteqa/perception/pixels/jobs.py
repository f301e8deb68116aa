"""The pixel network's tool jobs, each declared once: what ``efficienteqa perception dataset |
train | evaluate | thresholds`` take, with their defaults and help.

A job is a frozen dataclass of ``knob`` fields (as a run's configuration is): the CLI makes one
option per field from it (``cli.options.job_options``), and the library function that does the
work takes the job itself (``train_as_asked(TrainJob(data=...))``), so a default lives here and
nowhere else. Light: no torch, no rendering.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from efficienteqa.config.knobs import knob
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS
from efficienteqa.perception.pixels.houses import RECOLOUR_SHARE

THREADS = 2  # the machine's cores; 1 does better when others load them
CHECKPOINT_EVERY = 250  # steps between checkpoints (a few minutes on 2 cores)
# Wider deep levels (DESIGN 9, learned perception: the earlier network underfit); the 1/1 and
# 1/2 levels, which cost the most time per frame, keep their widths. Inference stays <= 100 ms
# (benchmarks.pixels_bench).
WIDE_WIDTHS = (16, 32, 64, 96, 160)
COMMITTED_WEIGHTS = Path("src/efficienteqa/perception/pixels/weights/pixels.pt")  # from the root
_ASSETS = ("The houses' furniture: sh3d (the CC0 catalogue the network trains on) or sh3d-all "
           "(every catalogue of the package; ")


@dataclass(frozen=True)
class DatasetJob:
    """``perception dataset``: RGB-D frames with per-pixel labels, rendered at half size."""

    seeds: str = knob(help="House seeds, e.g. 3000-3199 (within 3000-3999, the houses reserved "
                           "for perception; 3900-3909 validate).")
    out: Path = knob(help="Output folder (shards and meta.json; runs merge).")
    frames_per_house: int = knob(20, help="Views per house.")
    seed: int = knob(0, help="Seed of the views (with each house seed).")
    workers: int = knob(2, help="Rendering processes.")
    recolour_share: float = knob(RECOLOUR_SHARE, help="Share of colourable objects recoloured in training "
                                           "houses (3000-3899).")
    assets: str = knob(DEFAULT_ASSETS, help=_ASSETS + "training houses then never show the "
                                                      "KatorLegaz catalogue).")


@dataclass(frozen=True)
class TrainJob:
    """``perception train``: the network fitted on a dataset's frames."""

    data: Path = knob(help="A folder written by 'perception dataset'.")
    out: Path = knob(COMMITTED_WEIGHTS, help="The weights file (.pt; its .json is written "
                                             "beside it).")
    steps: int = knob(4000, help="Optimiser steps (fixes the result with --seed).")
    seed: int = knob(0, help="Seed of initialisation and crops.")
    batch: int = knob(8, help="Crops per step.")
    minutes: float = knob(90.0, help="Stop early after this long (a guard; recorded).")
    threads: int = knob(THREADS, help="Torch CPU threads.")
    widths: str = knob(",".join(map(str, WIDE_WIDTHS)), help="Channels of the 1/1 ... 1/16 "
                                                             "levels.")
    device: str = knob("auto", help="auto (cuda where torch sees one) | cpu | cuda.")
    resume: bool = knob(False, help="Continue from the checkpoint beside --out (same options "
                                    "and data).")
    checkpoint_every: int = knob(CHECKPOINT_EVERY, help="Steps between checkpoints (0: none).")


@dataclass(frozen=True)
class MeasureJob:
    """``perception evaluate``: the network against the semantic sensor on held-out houses."""

    seeds: str = knob("100-129", help="Houses to measure on, e.g. 100-129 (the evaluation "
                                      "split); never the network's training houses.")
    frames_per_house: int = knob(8, help="Views per house.")
    seed: int = knob(0, help="Seed of the views (with each house seed).")
    weights: Path | None = knob(None, help="Weights to measure (default: the committed ones).")
    out: Path | None = knob(None, help="Write the figures here as JSON.")
    poses: Path | None = knob(None, help="Measure at the poses of recorded walks (a file of "
                                         "experiments/walk_poses.py), frames spread evenly over "
                                         "each house's walk.")
    assets: str = knob(DEFAULT_ASSETS, help=_ASSETS + "objects of the CC-BY catalogues are "
                                                      "measured apart).")
    close_reads: int | None = knob(None, help="Supports read again a frame, on a crop around "
                                              "each (default: the pixel perception's own; 0 is "
                                              "off).")


@dataclass(frozen=True)
class ThresholdJob:
    """``perception thresholds``: each category's region threshold, chosen on validation houses."""

    seeds: str = knob("3900-3909", help="Validation houses to choose on (within 3900-3909).")
    frames_per_house: int = knob(10, help="Views per house.")
    seed: int = knob(0, help="Seed of the views (with each house seed).")
    weights: Path | None = knob(None, help="Weights to choose for (default: the committed ones); "
                                           "their .json records the choice.")
    write: bool = knob(False, help="Record the thresholds in the weights' .json (else only "
                                   "print them).")
