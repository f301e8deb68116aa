"""The paper's ablation tables in form: Table II (Z_th: LLM-Match and steps) and Table III (K:
LLM-Match), with their curves, for every group of runs that differ in that setting alone."""

from __future__ import annotations

from collections.abc import Sequence

from efficienteqa.eval.compare import ablations
from efficienteqa.eval.plots import xy_svg
from efficienteqa.eval.run_labels import settings_label
from efficienteqa.eval.run_tables import (
    RULE_HEADER,
    Figure,
    Table,
    any_ruled,
    episodes_cell,
    num,
    provenance,
    slug,
)
from efficienteqa.eval.summary import RunSummary


def ablation_blocks(summaries: Sequence[RunSummary], prefix: str) -> list[Table | Figure]:
    """The paper's Tables II (Z_th: LLM-Match and steps) and III (K: LLM-Match) with their curves,
    for every group of runs that differ in that setting alone."""
    blocks: list[Table | Figure] = []
    for key, symbol, with_steps, paper in (("z_th", "Z_th", True, "II"), ("top_k", "K", False, "III")):
        for i, group in enumerate(ablations(summaries, key), 1):
            first = group[0]
            name = settings_label(first.method, first.settings, skip=[key], preset=first.preset,
                                  baseline=first.baseline)
            suffix = f"-{i}" if i > 1 else ""
            ruled = any_ruled(group)
            header = [symbol, *([RULE_HEADER] if ruled else []), "LLM-Match (%) ↑",
                      *(["Avg steps ↓"] if with_steps else []), "Episodes"]
            rows = [[f"{s.settings[key]:g}" if isinstance(s.settings[key], float) else str(s.settings[key]),
                     *([num(s.rule_accuracy)] if ruled else []), num(s.llm_match),
                     *([num(s.mean_steps)] if with_steps else []), episodes_cell(s)]
                    for s in group]
            blocks.append(Table(f"Ablation over {symbol}: {name} (the paper's Table {paper})",
                                header, rows, provenance(group)))
            xs = [float(s.settings[key]) for s in group]
            plots = [("llm-match", "LLM-Match (%)", [s.llm_match for s in group])]
            if ruled:
                plots.insert(0, ("rule", "Rule-judge accuracy (%)", [s.rule_accuracy for s in group]))
            if with_steps:
                plots.append(("steps", "Avg steps", [s.mean_steps for s in group]))
            for tag, y_label, ys in plots:
                points = [(x, y, "") for x, y in zip(xs, ys)]
                blocks.append(Figure(f"{prefix}-{slug(key)}{suffix}-{tag}.svg",
                                     f"{y_label} vs {symbol}: {name}",
                                     xy_svg(points, x_label=symbol, y_label=y_label, connect=True)))
    return blocks
