"""``RunSpec``: a run as every episode shares it, the configuration tree and what planning
(``eval.plan.plan_run``) decided from it."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from efficienteqa.agent import AgentConfig
from efficienteqa.config.backends import Stack
from efficienteqa.config.run import EvalConfig, RunConfig, SceneConfig
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS
from efficienteqa.eval.judge_prompts import DEFAULT_JUDGE, DEFAULT_JUDGE_MODE, judge_mode

if TYPE_CHECKING:
    from efficienteqa.datasets.base import EvalQuestion
    from efficienteqa.scenes import Scene


@dataclass(frozen=True)
class RunSpec:
    """A run as every episode shares it: the configuration tree it was made from (``run``,
    recorded in run.json as ``efficienteqa config`` prints it) and what planning decided from
    it (``eval.plan.plan_run``): ``judge``, a VLM spec for LLM-Match ("local:MODEL",
    "openai:MODEL") or None for no judging; ``judge_mode`` (see ``eval.judge``; "auto" is
    resolved here and recorded as the mode it names); ``preset`` and ``preset_config``, the
    named configuration the options started from (``--preset NAME`` or ``--config FILE``'s
    path; None: the defaults) and what it alone sets, since a table labels the run by what it
    changed against that (DESIGN 6). Everything else is read from the tree: the properties
    below are views of it, never copies. Questions that carry their accepted answers
    (synthetic datasets) are also graded by the ``rule`` judge, whatever ``judge`` is."""

    run: RunConfig = field(default_factory=RunConfig)
    judge: str | None = DEFAULT_JUDGE
    judge_mode: str = DEFAULT_JUDGE_MODE  # "grade" (1-5 asked for; capable judges) | "yes-prob"
    preset: str | None = None
    preset_agent: AgentConfig | None = None  # None: the run's own agent (no preset)

    def __post_init__(self) -> None:
        object.__setattr__(self, "judge_mode", judge_mode(self.judge_mode, self.judge))

    @classmethod
    def of(cls, method: str, dataset: str, *, stack: Stack | None = None,
           config: AgentConfig | None = None, closed_set: bool = False, reports: bool = False,
           assets: str = DEFAULT_ASSETS, env: str = "synthetic", hm3d_root: str | None = None,
           noise: str = "none", judge: str | None = DEFAULT_JUDGE,
           judge_mode: str = DEFAULT_JUDGE_MODE, preset: str | None = None,
           preset_agent: AgentConfig | None = None) -> RunSpec:
        """A spec from its parts, for a caller without a tree (tests, experiments): the tree
        is built from them, with every other setting at its default."""
        agent = config or AgentConfig()
        tree = RunConfig(backends=stack or Stack(),
                         scene=SceneConfig(env=env, assets=assets, noise=noise,
                                           hm3d_root=Path(hm3d_root) if hm3d_root else None),
                         explore=agent.explore, stop=agent.stop, answer=agent.answer,
                         eval=EvalConfig(method=method, dataset=dataset, closed_set=closed_set,
                                         reports=reports))
        return cls(tree, judge=judge, judge_mode=judge_mode, preset=preset,
                   preset_agent=preset_agent)

    @property
    def method(self) -> str:
        return self.run.eval.method

    @property
    def dataset(self) -> str:
        return self.run.eval.dataset

    @property
    def closed_set(self) -> bool:
        return self.run.eval.closed_set

    @property
    def reports(self) -> bool:
        return self.run.eval.reports

    @property
    def stack(self) -> Stack:
        return self.run.backends

    @property
    def config(self) -> AgentConfig:
        """The agent's three sections; the method's own settings go on top (``method_config``)."""
        return self.run.agent

    @property
    def preset_config(self) -> AgentConfig:
        return self.preset_agent or self.config

    @property
    def assets(self) -> str:
        return self.run.scene.assets

    @property
    def env(self) -> str:
        """The simulator of the dataset's scenes: "synthetic" or "habitat" (``hm3d_root``)."""
        return self.run.scene.env

    @property
    def noise(self) -> str:
        return self.run.scene.noise  # the synthetic houses' noise profile (envs/synthetic/noise)

    @property
    def hm3d_root(self) -> str | None:
        root = self.run.scene.hm3d_root
        return str(root) if root is not None else None

    def open_scene(self, q: EvalQuestion) -> Scene:
        """``q``'s scene as this run opens it for any method: its simulator, furniture, noise
        and HM-EQA start; no oracle steps (the question carries its own)."""
        from efficienteqa.envs.habitat.scenes import HabitatStart
        from efficienteqa.scenes import open_scene

        return open_scene(q.scene, self.assets, env=self.env, hm3d_root=self.hm3d_root,
                          start=HabitatStart.from_source(q.source), oracle=False,
                          noise=self.noise)
