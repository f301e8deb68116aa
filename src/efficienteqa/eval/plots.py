"""The report's one plot: an SVG scatter or line of (x, y, label) points with labelled levels,
drawn here so reports need no plotting library (``eval.tables`` inlines it in HTML and writes it
as a file beside the Markdown)."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence

PLOT_W, PLOT_H, PAD = 540, 340, 56


def _ticks(lo: float, hi: float, target: int = 5) -> tuple[list[float], int]:
    """Round tick values (steps of 1, 2 or 5 times a power of ten) inside [lo, hi], and the
    decimals that print them exactly."""
    raw = (hi - lo) / target
    magnitude = 10.0 ** math.floor(math.log10(raw))
    step = next(m * magnitude for m in (1, 2, 5, 10) if m * magnitude >= raw)
    first = math.ceil(lo / step) * step
    count = int((hi - first) / step + 1e-9) + 1
    return [first + k * step for k in range(count)], max(0, -math.floor(math.log10(step) + 1e-9))


def _span(values: Sequence[float]) -> tuple[float, float]:
    lo, hi = min(values), max(values)
    if hi - lo < 1e-9:
        return lo - 1.0, hi + 1.0
    margin = 0.1 * (hi - lo)
    return lo - margin, hi + margin


def xy_svg(points: Sequence[tuple[float, float, str]], *, x_label: str, y_label: str,
           connect: bool = False, levels: Sequence[tuple[float, str]] = ()) -> str:
    """A scatter (``connect``: a line through the points in order) of (x, y, label) points, with
    optional labelled dashed horizontal ``levels``; points or levels with NaN are left out."""
    pts = [(x, y, lab) for x, y, lab in points if not (math.isnan(x) or math.isnan(y))]
    lvls = [(y, lab) for y, lab in levels if not math.isnan(y)]
    head = (f'<svg xmlns="http://www.w3.org/2000/svg" width="{PLOT_W}" height="{PLOT_H}" '
            f'viewBox="0 0 {PLOT_W} {PLOT_H}" role="img" aria-label="{html.escape(y_label)} vs '
            f'{html.escape(x_label)}" font-family="sans-serif" font-size="11">')
    if not pts and not lvls:
        return (head + f'<text x="{PLOT_W / 2}" y="{PLOT_H / 2}" text-anchor="middle">'
                "no measured value to plot</text></svg>")
    x0, x1 = _span([p[0] for p in pts] or [0.0])
    y0, y1 = _span([p[1] for p in pts] + [y for y, _ in lvls])

    def sx(v: float) -> float:
        return PAD + (PLOT_W - 2 * PAD) * (v - x0) / (x1 - x0)

    def sy(v: float) -> float:
        return PLOT_H - PAD - (PLOT_H - 1.6 * PAD) * (v - y0) / (y1 - y0)

    out = [head, f'<rect x="{PAD}" y="{0.6 * PAD}" width="{PLOT_W - 2 * PAD}" '
                 f'height="{PLOT_H - 1.6 * PAD}" fill="#fafafa" stroke="#ccc"/>']
    y_ticks, y_digits = _ticks(y0, y1)
    for v in y_ticks:
        out.append(f'<text x="{PAD - 5}" y="{sy(v) + 4:.1f}" text-anchor="end">{v:.{y_digits}f}</text>'
                   f'<line x1="{PAD}" x2="{PLOT_W - PAD}" y1="{sy(v):.1f}" y2="{sy(v):.1f}" stroke="#eee"/>')
    if pts:
        x_ticks, x_digits = _ticks(x0, x1)
        for v in x_ticks:
            out.append(f'<text x="{sx(v):.1f}" y="{PLOT_H - PAD + 16}" '
                       f'text-anchor="middle">{v:.{x_digits}f}</text>')
    out.append(f'<text x="{PLOT_W / 2}" y="{PLOT_H - 12}" text-anchor="middle">{html.escape(x_label)}</text>')
    out.append(f'<text x="14" y="{PLOT_H / 2}" transform="rotate(-90 14 {PLOT_H / 2})" '
               f'text-anchor="middle">{html.escape(y_label)}</text>')
    for y, lab in lvls:
        out.append(f'<line x1="{PAD}" x2="{PLOT_W - PAD}" y1="{sy(y):.1f}" y2="{sy(y):.1f}" '
                   f'stroke="#999" stroke-dasharray="6 4"/><text x="{PLOT_W - PAD - 4}" '
                   f'y="{sy(y) - 4:.1f}" text-anchor="end" fill="#666">{html.escape(lab)} '
                   f'(no steps): {y:.1f}</text>')
    if connect and len(pts) > 1:
        path = " ".join(f"{sx(x):.1f},{sy(y):.1f}" for x, y, _ in pts)
        out.append(f'<polyline points="{path}" fill="none" stroke="#369" stroke-width="1.5"/>')
    for x, y, lab in pts:
        tip = html.escape(f"{lab + ': ' if lab else ''}({x:g}, {y:.2f})")
        out.append(f'<circle cx="{sx(x):.1f}" cy="{sy(y):.1f}" r="4" fill="#369">'
                   f'<title>{tip}</title></circle>')
        if lab:  # on the left of points in the right third, so the label stays inside
            right = sx(x) > 0.66 * PLOT_W
            anchor = "end" if right else "start"
            out.append(f'<text x="{sx(x) + (-7 if right else 7):.1f}" y="{sy(y) - 6:.1f}" '
                       f'text-anchor="{anchor}">{html.escape(lab)}</text>')
    out.append("</svg>")
    return "\n".join(out)
