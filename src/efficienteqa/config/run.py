"""A run's whole configuration: one tree of sections, each a dataclass that owns its fields.

==========  ===========================  ================================================
section     dataclass                    what it holds
==========  ===========================  ================================================
backends    ``backends.Stack``           the VLM, perception, sightings, relevancy, server
scene       ``SceneConfig``              the simulator and its assets
explore     ``explore.config``           DESIGN 3.2-3.3 and the steering (``sfe``, ``target``)
stop        ``stop.rules.StopConfig``    DESIGN 3.4 and the answerability gate (DESIGN 9)
answer      ``answer.config``            DESIGN 3.5
eval        ``EvalConfig``               the method, dataset, judge and workers of ``eval``
==========  ===========================  ================================================

Every field is declared once with ``knobs.knob`` (default, help, beyond the paper or not), and
everything else is made from the fields (``knobs.leaves``): the CLI's flags (``--stop.z-th``,
with the flat ``--z-th`` kept as an alias), the TOML sections of ``--config`` and the presets,
the record (``run.json``'s ``stack`` is ``backends``, its ``config`` the agent's three sections)
and the run's table label (``eval.run_labels.settings`` flattens the sections, whose field names are
unique).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from efficienteqa.answer.config import AnswerConfig
from efficienteqa.config.backends import Stack
from efficienteqa.config.knobs import knob
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS
from efficienteqa.explore.config import ExploreConfig
from efficienteqa.stop.rules import StopConfig, gated_stop

if TYPE_CHECKING:
    from efficienteqa.agent import AgentConfig

# The dataset of `ask --episode` and `eval` when neither the command line nor a preset names one.
DEFAULT_DATASET = "synthetic"


# The synthetic houses' noise profiles (envs/synthetic/noise.py; named here so the configuration
# stays free of numpy, and a test holds the two lists equal).
NOISE_PROFILES = ("none", "robot", "robot-depth", "robot-odometry", "robot-moves", "robot-camera")


@dataclass(frozen=True)
class SceneConfig:
    """Where the scenes come from."""

    env: str = knob("synthetic", help="synthetic (generated houses) | habitat (Habitat-Sim + "
                    "HM3D; needs scene.hm3d_root).")
    assets: str = knob(DEFAULT_ASSETS, help="The synthetic houses' furniture: sh3d (the "
                       "furniture package's CC0 catalogue) | sh3d-all (with its CC-BY "
                       "catalogues: 375 meshes in 92 categories, credited in ATTRIBUTION.md) | "
                       "builtin (boxes).")
    hm3d_root: Path | None = knob(None, help="Folder holding the HM3D scene folders, e.g. "
                                  "00800-TEEsavR23oF/ (see docs/habitat.md).")
    noise: str = knob("none", beyond=True, help="A robot's imperfections in the synthetic "
                      "houses: none | robot (depth noise and holes, odometry drift, moves that "
                      "fall short or fail, a camera off its calibration) | robot-depth | "
                      "robot-odometry | robot-moves | robot-camera (one at a time).")

    def __post_init__(self) -> None:
        if self.noise not in NOISE_PROFILES:
            raise ValueError(f"noise must be one of {', '.join(NOISE_PROFILES)}, not "
                             f"{self.noise!r}")


@dataclass(frozen=True)
class EvalConfig:
    """What ``eval`` runs and how it grades; ``ask --episode`` reads ``dataset`` and
    ``hm_eqa_path`` too."""

    method: str = knob("efficienteqa", help="efficienteqa | explore-eqa | explore-eqa-blackbox "
                       "| blind | frontier-only | random | module:function.")
    dataset: str = knob(DEFAULT_DATASET, help="synthetic (the fixed split) | "
                        "synthetic-test (the held-out test split) | synthetic-paraphrase (its "
                        "first 48 re-phrased) | synthetic:SEEDS (e.g. synthetic:0-9) | hm-eqa | "
                        "FILE.jsonl (your own questions, each with its "
                        "scene, e.g. recorded:walk.mcap).")
    hm_eqa_path: Path | None = knob(None, help="Folder with HM-EQA's questions.csv and "
                                    "scene_init_poses.csv (default: downloaded).")
    limit: int | None = knob(None, help="Only the first N questions of the dataset.")
    closed_set: bool = knob(False, help="HM-EQA's four-choice mode (all 500 questions): "
                            "graded by the chosen letter; the default judge is then none.")
    judge: str | None = knob(None, help="The LLM-Match judge (a VLM spec), or rule / none for "
                             "no model (synthetic questions are always graded by the rule judge "
                             "too). Default: rule for synthetic datasets, the local model for "
                             "the others (questions without a reference answer are not graded).")
    judge_mode: str | None = knob(None, help="grade (1-5 by the project's rubric) | yes-prob (1 "
                                  "+ 4 P(yes) for 'same answer?') | openeqa (OpenEQA's LLM-Match "
                                  "protocol; the paper preset's) | auto (default: yes-prob for "
                                  "local models, else grade).")
    workers: int = knob(1, help="Episodes in parallel; more than 1 runs on Ray.")
    address: str | None = knob(None, help="A Ray cluster address (default: a local Ray).")
    reports: bool = knob(False, help="Also write each episode's report.html.")

    def __post_init__(self) -> None:
        if self.limit is not None and self.limit < 1:
            raise ValueError(f"limit must be at least 1, not {self.limit}")
        if self.workers < 1:
            raise ValueError(f"workers must be at least 1, not {self.workers}")


# The eval fields `ask` reads: where `--episode` comes from.
ASK_EVAL_FIELDS = ("dataset", "hm_eqa_path")


@dataclass(frozen=True)
class RunConfig:
    """The tree. ``agent`` is what an episode runs with; ``backends`` what it runs on."""

    backends: Stack = field(default_factory=Stack)
    scene: SceneConfig = field(default_factory=SceneConfig)
    explore: ExploreConfig = field(default_factory=ExploreConfig)
    stop: StopConfig = field(default_factory=gated_stop)  # AgentConfig's
    answer: AnswerConfig = field(default_factory=AnswerConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)

    @property
    def agent(self) -> AgentConfig:
        from efficienteqa.agent import AgentConfig  # the agent's code: imported when run

        return AgentConfig(explore=self.explore, stop=self.stop, answer=self.answer)


# How --help groups the sections.
SECTION_TITLES = {"backends": "Back-ends", "scene": "Scene", "explore": "Explore (DESIGN 3.2-3.3)",
                  "stop": "Stop (DESIGN 3.4) and its gate", "answer": "Answer (DESIGN 3.5)",
                  "eval": "Evaluation"}
