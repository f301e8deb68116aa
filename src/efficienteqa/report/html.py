"""``report.html``: one self-contained page per episode (images inlined, no scripts, no network).

Sections: the outcome and the back-ends that produced it; the top-down map with trajectory,
frontiers and semantic values; the relevancy curve with the threshold that acted at each step (the
paper's Fig. 4); the retrieved top-K frames as captured (what the answer model was given);
every frame with its Sim (with its lettered directions where the step had them); every model
exchange with its phase and the images it was sent, as sent. The answer is shown as
``vc.parse.clean_answer`` reads it (no markdown, no "The answer is").
"""

from __future__ import annotations

import html
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from efficienteqa.redact import redact_urls
from efficienteqa.vc.parse import clean_answer

CURVE_W, CURVE_H, PAD = 760, 260, 44

CSS = """
body{font-family:system-ui,sans-serif;margin:24px auto;max-width:1100px;color:#222}
h1{font-size:1.3em} h2{font-size:1.1em;margin-top:1.6em;border-bottom:1px solid #ddd}
table.kv td{padding:2px 12px 2px 0;vertical-align:top} table.kv td:first-child{color:#666}
.answer{font-size:1.4em;font-weight:600}
.grid{display:flex;flex-wrap:wrap;gap:10px}
figure{margin:0;width:250px;font-size:.82em} figure img{width:250px;border:1px solid #ccc}
figure.top{width:330px} figure.top img{width:330px}
figure.hit img{border:3px solid #d33}
figcaption{color:#444} .desc{color:#666;font-size:.92em}
details{margin:4px 0} summary{cursor:pointer}
pre{white-space:pre-wrap;background:#f6f6f6;padding:6px;font-size:.85em}
.note{color:#666;font-size:.9em}
summary img.sent{height:60px;vertical-align:middle;margin-left:6px;border:1px solid #ccc}
"""


def _img(src: str, alt: str, cls: str = "") -> str:
    return f'<img src="{src}" alt="{html.escape(alt)}"{f" class={cls!r}" if cls else ""}>'


def relevancy_svg(per_step: Sequence[Mapping[str, Any]], z_th: float, min_step: int,
                  stop_step: int | None, retrieved: Sequence[int] = (),
                  sim_abs: float | None = None) -> str:
    """Sim per step (dots, retrieved frames ringed), the threshold that acted at each step
    (dashed: mu + z sigma of the other frames, z the step's ``z_applied``: ``z_th``, or the
    gate's lower one on a frame it passed), the Sim that stops whatever the baseline
    (``sim_abs``, dotted, for a rule with ``absolute``), the first step a stop is allowed (grey
    line) and the stop (red)."""
    pts = [(s["step"], s["sim"]) for s in per_step if s.get("sim") is not None]
    thr = [(s["step"], s["threshold"]) for s in per_step if s.get("threshold") is not None]
    applied = sorted({s["z_applied"] for s in per_step if s.get("z_applied") is not None})
    z_said = "/".join(f"{z:g}" for z in applied) if applied else f"{z_th:g}"
    if not pts:
        return '<p class="note">No valid frame: no relevancy curve.</p>'
    steps = [s["step"] for s in per_step]
    x0, x1 = min(steps), max(max(steps), min_step)
    values = [v for _, v in pts] + [v for _, v in thr] + ([sim_abs] if sim_abs is not None else [])
    y0, y1 = min(values), max(values)
    if y1 - y0 < 1e-9:
        y0, y1 = y0 - 0.5, y1 + 0.5
    margin = 0.08 * (y1 - y0)
    y0, y1 = y0 - margin, y1 + margin

    def x(step: float) -> float:
        return PAD + (CURVE_W - 2 * PAD) * ((step - x0) / max(x1 - x0, 1))

    def y(v: float) -> float:
        return CURVE_H - PAD + (2 * PAD - CURVE_H) * ((v - y0) / (y1 - y0))

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{CURVE_W}" height="{CURVE_H}" '
           f'viewBox="0 0 {CURVE_W} {CURVE_H}" role="img" aria-label="relevancy curve" '
           'font-family="sans-serif" font-size="11">',
           f'<rect x="{PAD}" y="{PAD / 2}" width="{CURVE_W - 2 * PAD}" '
           f'height="{CURVE_H - 1.5 * PAD}" fill="#fafafa" stroke="#ccc"/>']
    for k in range(5):  # y ticks
        v = y0 + (y1 - y0) * k / 4
        out.append(f'<text x="{PAD - 4}" y="{y(v) + 4:.1f}" text-anchor="end">{v:.2f}</text>')
    tick = max(1, round((x1 - x0) / 10))
    for s in range(x0, x1 + 1, tick):
        out.append(f'<text x="{x(s):.1f}" y="{CURVE_H - PAD + 16}" text-anchor="middle">{s}</text>')
    out.append(f'<text x="{CURVE_W / 2}" y="{CURVE_H - 6}" text-anchor="middle">step</text>')
    out.append(f'<text x="12" y="{CURVE_H / 2}" transform="rotate(-90 12 {CURVE_H / 2})" '
               'text-anchor="middle">Sim(I_t, Q)</text>')
    out.append(f'<line x1="{x(min_step):.1f}" x2="{x(min_step):.1f}" y1="{PAD / 2}" '
               f'y2="{CURVE_H - PAD}" stroke="#999" stroke-dasharray="2 3"/>')
    if len(thr) > 1:
        path = " ".join(f"{x(s):.1f},{y(v):.1f}" for s, v in thr)
        out.append(f'<polyline points="{path}" fill="none" stroke="#d33" stroke-width="1.5" '
                   f'stroke-dasharray="6 4"><title>mu + {z_said} sigma</title></polyline>')
    if sim_abs is not None:
        out.append(f'<line x1="{PAD}" x2="{CURVE_W - PAD}" y1="{y(sim_abs):.1f}" '
                   f'y2="{y(sim_abs):.1f}" stroke="#d33" stroke-dasharray="1 3">'
                   f'<title>Sim {sim_abs:g} stops</title></line>')
    out.append('<polyline points="' + " ".join(f"{x(s):.1f},{y(v):.1f}" for s, v in pts)
               + '" fill="none" stroke="#369" stroke-width="1.5"/>')
    for s, v in pts:
        ring = ' stroke="#d33" stroke-width="2"' if s in retrieved else ""
        out.append(f'<circle cx="{x(s):.1f}" cy="{y(v):.1f}" r="3.5" fill="#369"{ring}>'
                   f'<title>step {s}: Sim {v:.3f}</title></circle>')
    if stop_step is not None:
        out.append(f'<line x1="{x(stop_step):.1f}" x2="{x(stop_step):.1f}" y1="{PAD / 2}" '
                   f'y2="{CURVE_H - PAD}" stroke="#d33" stroke-width="2"/>')
    legend = [("#369", "Sim per frame (ringed: retrieved top-K)", ""),
              ("#d33", f"threshold that acted: mu + {z_said} sigma", ' stroke-dasharray="6 4"'),
              ("#999", f"no stop before step {min_step}", ' stroke-dasharray="2 3"')]
    for k, (colour, label, dash) in enumerate(legend):
        lx = PAD + 8 + 250 * k
        out.append(f'<line x1="{lx}" x2="{lx + 22}" y1="{PAD / 2 - 8}" y2="{PAD / 2 - 8}" '
                   f'stroke="{colour}" stroke-width="2"{dash}/>'
                   f'<text x="{lx + 26}" y="{PAD / 2 - 4}">{html.escape(label)}</text>')
    out.append("</svg>")
    return "\n".join(out)


def _kv(rows: Sequence[tuple[str, Any]]) -> str:
    return '<table class="kv">' + "".join(
        f"<tr><td>{html.escape(k)}</td><td>{html.escape(str(v))}</td></tr>" for k, v in rows
    ) + "</table>"


def _fmt(v: float | None, digits: int = 3) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def _target_value(value: object) -> str:
    """One field of the record's target as words: a list joined by commas, an alias pair
    (the question's words, the category) as "couch = sofa"."""
    if isinstance(value, list):
        return ", ".join(" = ".join(map(str, v)) if isinstance(v, list) else str(v)
                         for v in value)
    return str(value)


def render_report(record: Mapping[str, Any], map_url: str, frames: Mapping[int, str],
                  descriptions: Mapping[int, str] | None = None) -> str:
    """The page for ``record`` (an ``episode.json`` dict). ``map_url`` and ``frames`` (step ->
    frame as captured) are ``data:`` URLs (``models.images.encode_image``), so the page needs no
    files. ``frames`` from ``report.frames.FrameCollector`` (a ``StepFrames``) also holds the
    lettered frames (``marked``) and the thumbnails of the images model calls were sent, by
    reference (``sent``); a plain mapping shows neither."""
    descriptions = descriptions or {}
    marked: Mapping[int, str] = getattr(frames, "marked", {})
    sent: Mapping[str, Any] = getattr(frames, "sent", {})
    per_step = record["per_step"]
    cfg = record["config"]
    stop_cfg = cfg.get("stop", {})
    retrieved = [r["step"] for r in record["retrieved"]]
    stop_step = record["steps"] if record["stop_reason"] == "relevancy" else None
    ref = record.get("reference") or {}
    backends = record["backends"]
    text_perception = backends.get("perception") in ("semantic-sensor", "pixels")
    model = record["model"]

    target = record.get("target") or {}
    outcome = [("answer confidence", f"{record['confidence']:.2f}"),
               ("steps", f"{record['steps']} of a budget of {record['budget']}"
                + (f" (oracle: {record['oracle_steps']})" if record.get("oracle_steps") else "")),
               ("stop reason", record["stop_reason"])]
    if ref.get("answer"):
        outcome.append(("reference answer", ref["answer"]))
    if target.get("kind") not in (None, "other"):
        outcome.append(("the question's target", ", ".join(
            f"{k} {_target_value(v)}" for k, v in target.items() if v)))
    outcome += [("scene", record["scene"]),
                ("wall time", f"{record['timing']['wall_s']:.1f} s "
                 f"({record['timing']['per_step_s']:.2f} s per step, answer "
                 f"{record['timing']['answer_s']:.1f} s)"),
                ("model calls", f"{model['calls']} ({model['prompt_tokens']} prompt + "
                 f"{model['completion_tokens']} completion tokens, {model['latency_s']:.1f} s)")]
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>EfficientEQA episode"
             f"</title><style>{CSS}</style></head><body>",
             f"<h1>{html.escape(record['question'])}</h1>",
             f'<p class="answer" id="answer">'
             f'{html.escape(clean_answer(record["answer"] or "") or "(no answer)")}</p>',
             _kv(outcome), "<h2>Back-ends</h2>", _kv(sorted(backends.items()))]
    if text_perception:
        parts.append('<p class="note">Semantic-sensor perception: the language model read the '
                     "text descriptions under the frames (built from the simulator's object "
                     "labels), not the pixels.</p>")
    parts += ["<h2>Map</h2>",
              '<p class="note">Free floor light grey, explored green, obstacles black, unknown '
              "dark grey; semantic values as a yellow-red heat map; frontiers blue with their "
              "outward normals; trajectory orange, the robot red.</p>",
              _img(map_url, "top-down map", "map"),
              "<h2>Relevancy</h2>",
              relevancy_svg(per_step, stop_cfg.get("z_th", 3.0), stop_cfg.get("min_step", 10),
                            stop_step, retrieved,
                            stop_cfg.get("sim_abs") if "absolute" in str(stop_cfg.get("rule", ""))
                            else None),
              f"<h2>Retrieved top-{len(retrieved)} frames</h2>",
              '<p class="note">As captured, without lettered circles: ' + (
                  "the answer model read the descriptions under them." if text_perception else
                  "the images the answer model was sent.") + "</p>",
              '<div class="grid">']
    for r in record["retrieved"]:
        parts.append(_figure(r["step"], frames, descriptions,
                             f"step {r['step']}, Sim {r['sim']:.3f}", "top"))
    parts += ["</div>", "<h2>Every frame</h2>", '<div class="grid">']
    shown = {**frames, **marked}  # a step's lettered frame where it had prompts
    for s in per_step:
        caption = (f"step {s['step']}: Sim {_fmt(s['sim'])}, z {_fmt(s['z'], 2)}"
                   if s["valid"] else f"step {s['step']}: invalid frame")
        if s["lsv"]:
            caption += " · LSV " + " ".join(f"{k}={v:.2f}" for k, v in s["lsv"].items())
        if s["gsv"] is not None:
            caption += f" · GSV {s['gsv']:.2f}"
        if s.get("decision"):
            caption += f" · {s['decision']}"
        if s.get("gate"):
            caption += f" · gate: {s['gate']['why']}"
        if s["step"] in marked:
            caption += " · lettered directions drawn"
        parts.append(_figure(s["step"], shown, descriptions, caption,
                             "hit" if s["step"] in retrieved else ""))
    parts += ["</div>", f"<h2>Model exchanges ({model['calls']})</h2>"]
    for e in model["exchanges"]:
        head = (f"#{e['index']} · {e['phase'] or '-'} · {e['model']} · {e['prompt_tokens']}+"
                f"{e['completion_tokens']} tokens · {e['latency_s']:.2f} s"
                + (" · cached" if e["cached"] else "") + (f" · {e['images']} image(s)"
                                                           if e["images"] else ""))
        parts.append(f"<details><summary>{html.escape(head)}{_sent_images(e, sent)}</summary>"
                     f"<pre>{html.escape(e['prompt'])}</pre><b>reply</b>"
                     f"<pre>{html.escape(e['reply'])}</pre></details>")
    parts += ["<h2>Configuration</h2>",
              f"<pre>{html.escape(json.dumps(cfg, indent=1))}</pre>",
              f'<p class="note">code {html.escape(record["code_version"])}</p></body></html>']
    return "\n".join(parts)


def _sent_images(exchange: Mapping[str, Any], sent: Mapping[str, Any]) -> str:
    """The images of one call, in the order sent: each a thumbnail of the frame it was (as
    captured or with the lettered circles), or a note where the report kept no such frame."""
    out = []
    for ref in exchange.get("image_refs") or ():
        image = sent.get(ref)
        if image is None:
            out.append(f' <span class="note">[image {html.escape(ref)}: not a kept frame]</span>')
        else:
            out.append(f' <img class="sent" src="{image.url}" alt="sent: {html.escape(image.label)}"'
                       f' title="{html.escape(image.label)}">')
    return "".join(out)


def _figure(step: int, frames: Mapping[int, str], descriptions: Mapping[int, str],
            caption: str, cls: str) -> str:
    img = _img(frames[step], f"frame {step}") if step in frames else ""
    desc = (f'<div class="desc">{html.escape(descriptions[step])}</div>'
            if step in descriptions else "")
    return (f'<figure class="{cls}">{img}<figcaption>{html.escape(caption)}</figcaption>'
            f"{desc}</figure>")


def write_report(path: Path, record: Mapping[str, Any], map_url: str,
                 frames: Mapping[int, str], descriptions: Mapping[int, str] | None = None
                 ) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(redact_urls(render_report(record, map_url, frames, descriptions)),
                    encoding="utf-8")
    return path
