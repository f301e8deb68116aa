"""When a setting acts: the one list of a run's settings that would change nothing.

``inert(run, agent)`` names each such setting with the reason, for the agent configuration the
episodes run with (``agent``: the method's, ``eval.methods.effective_config``). Everything that
must know reads it: ``presets.resolve`` refuses such a setting given on the command line, in
one line; ``presets.to_toml`` (``efficienteqa config``) marks it with a comment that says why
where a preset or a ``--config`` file sets it. A setting the run ignores is thus never shown as
live.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from efficienteqa.stop.rules import rule_parts, z_th_acts

if TYPE_CHECKING:
    from efficienteqa.agent import AgentConfig
    from efficienteqa.config.run import RunConfig

FRONTIER_EXPLORERS = ("sfe", "frontier-only")


def reads_target(steering: str | None, gate: str | None) -> bool:
    """Whether anything reads the question's target: the steering, or a gate (so the reading,
    the matching and the sightings act); the tables' labels ask it too."""
    return steering != "none" or gate != "none"


def inert(run: RunConfig, agent: AgentConfig) -> dict[str, str]:
    """{dotted setting: why it does not act} for ``run`` whose episodes run ``agent``."""
    out: dict[str, str] = {}
    stop, explore = agent.stop, agent.explore
    if not z_th_acts(stop.gate):
        out["stop.z_th"] = (f"the {stop.gate} gate judges every frame, and a frame it passes "
                            f"stops at stop.z_gated ({stop.z_gated:g}), one it turns down never")
    else:
        out["stop.z_gated"] = f"the {stop.gate} gate leaves the stop to Z_th (stop.z_th)"
        out["stop.gate_final"] = f"the {stop.gate} gate does not judge every frame"
    parts = rule_parts(stop.rule)
    if "floor" not in parts:
        out["stop.sigma_floor"] = f"the stop rule {stop.rule!r} has no 'floor' part"
    if "absolute" not in parts:
        out["stop.sim_abs"] = f"the stop rule {stop.rule!r} has no 'absolute' part"
    if not stop.enabled:
        for name in ("z_th", "z_gated", "min_step", "rule", "sigma_floor", "sim_abs",
                     "gate_final"):
            out[f"stop.{name}"] = "the early stop is off (stop.enabled false)"
    steers = explore.steering != "none"
    if not reads_target(explore.steering, stop.gate):
        why = "nothing reads the question's target: no steering (explore.steering none) and no gate"
        for path in ("explore.reading", "explore.matching", "backends.sightings"):
            out[path] = why
    if agent.answer.answer == "direct":
        out["backends.grouping"] = "the direct answer gives one answer: nothing to group"
    if explore.explorer not in FRONTIER_EXPLORERS:
        out["explore.sfe"] = f"this run explores with {explore.explorer!r}, not a frontier explorer"
    if not steers:
        out["explore.target"] = "this run does not steer by the question's target"
    del run  # the run's own sections (scene, eval) hold no setting that depends on another yet
    return out
