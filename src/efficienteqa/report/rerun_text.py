"""The text of an episode in rerun: the answer document and the one line per step of the step
log. Plain strings from the episode's records, kept apart from ``rerun_log`` as they need no
rerun.
"""

from __future__ import annotations

from efficienteqa.trace import EpisodeResult, StepRecord
from efficienteqa.vc.parse import clean_answer


def answer_markdown(result: EpisodeResult) -> str:
    """The outcome as a markdown document: question, answer with its confidence, why and
    where exploration stopped, and the retrieved frames by step."""
    answer = clean_answer(result.answer) if result.answer else "(none)"
    last = result.records[-1] if result.records else None
    stop = f"{result.stop_reason} at step {result.steps} of {result.budget}"
    if (result.stop_reason == "relevancy" and last is not None and last.check is not None
            and last.check.tested_step not in (None, last.step)):
        stop += f" (the frame of step {last.check.tested_step})"
    lines = [f"**Question:** {result.question}", "",
             f"**Answer:** {answer} (confidence {result.confidence:.2f})", "",
             f"**Stop:** {stop}", "", "| rank | step | Sim |", "|---|---|---|"]
    lines += [f"| {rank} | {step} | {sim:.3f} |" for rank, (step, sim) in enumerate(result.retrieved, 1)]
    return "\n".join(lines)


def step_line(record: StepRecord) -> str:
    """One line of what happened at a step, as the step log shows it."""
    parts = [f"step {record.step}"]
    c = record.check
    if not record.valid:
        parts.append("frame not used (too little depth)")
    elif c is None:
        parts.append("no Sim (the relevancy reply was unreadable)")
    else:
        parts.append(f"Sim {c.sim:.3f}")
        if c.z is not None:
            parts.append(f"z {c.z:+.2f}" + (f" vs {c.z_applied:g}" if c.z_applied is not None else ""))
        if c.tested_step not in (None, record.step):
            parts.append(f"(tested: step {c.tested_step})")
        if c.stop:
            parts.append("STOP")
    if record.gate is not None:
        parts.append(f"gate {'passed' if record.gate.get('ok') else 'refused'}: {record.gate.get('why', '')}")
    if record.decision:
        parts.append(f"-> {record.decision} ({record.n_frontiers} frontiers)")
    return "  ".join(parts)

