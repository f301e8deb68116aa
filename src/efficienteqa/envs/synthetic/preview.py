"""Pictures of a house: a labelled top-down map and a contact sheet of views."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Callable

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from efficienteqa.envs.synthetic.env import SyntheticEnv
from efficienteqa.envs.synthetic.questions import Question
from efficienteqa.geometry import Pose2D

PX_PER_M = 48
MARGIN_M = 0.3


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1
        return ImageFont.load_default()


def topdown_map(env: SyntheticEnv, questions: list[Question] | None = None) -> Image.Image:
    """The house from above (ceiling cut away) with room names, the start pose and the poses
    from which each question's evidence is first seen (numbered like the questions)."""
    lay = env.house.layout
    lo = np.array([-MARGIN_M, -MARGIN_M])
    hi = np.array([lay.width_m + MARGIN_M, lay.depth_m + MARGIN_M])
    image = Image.fromarray(env.renderer.render_topdown(lo, hi, PX_PER_M, cut_z=2.2))
    draw = ImageDraw.Draw(image)
    height = image.height

    def px(x: float, y: float) -> tuple[float, float]:
        return ((x - lo[0]) * PX_PER_M, height - (y - lo[1]) * PX_PER_M)

    font = _font(15)
    for room in lay.rooms:
        cx, cy = px(*room.centre)
        draw.text((cx, cy), room.name, fill=(20, 20, 20), font=font, anchor="mm",
                  stroke_width=3, stroke_fill=(255, 255, 255))
    _arrow(draw, px, env.house.start, (220, 30, 30), "start")
    for n, q in enumerate(questions or []):
        if q.oracle_pose:
            _arrow(draw, px, Pose2D(*q.oracle_pose), (30, 90, 220), f"Q{n}")
    return image


def _arrow(draw: ImageDraw.ImageDraw, px: Callable[[float, float], tuple[float, float]],
           pose: Pose2D, colour: tuple[int, int, int], label: str) -> None:
    x, y = px(pose.x, pose.y)
    tip = px(pose.x + 0.6 * math.cos(pose.yaw), pose.y + 0.6 * math.sin(pose.yaw))
    draw.ellipse((x - 7, y - 7, x + 7, y + 7), fill=colour, outline=(255, 255, 255), width=2)
    draw.line((x, y, *tip), fill=colour, width=4)
    draw.text((x + 9, y + 9), label, fill=colour, font=_font(13), stroke_width=2,
              stroke_fill=(255, 255, 255))


def contact_sheet(env: SyntheticEnv, questions: list[Question], columns: int = 3,
                  thumb: tuple[int, int] = (320, 240)) -> Image.Image:
    """The start view and, for each question, the view from its oracle pose, captioned."""
    views: list[tuple[Pose2D, str]] = [(env.house.start, "start view")]
    for n, q in enumerate(questions):
        if q.oracle_pose:
            views.append((Pose2D(*q.oracle_pose),
                          f"Q{n} [{q.category}, {q.oracle_steps} steps] {q.question} -> {q.answer}"))
    caption_h = 46
    rows = math.ceil(len(views) / columns)
    sheet = Image.new("RGB", (columns * thumb[0], rows * (thumb[1] + caption_h)), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    font = _font(12)
    for k, (pose, caption) in enumerate(views):
        col, row = k % columns, k // columns
        x, y = col * thumb[0], row * (thumb[1] + caption_h)
        rgb = Image.fromarray(env.observe(pose).rgb).resize(thumb, Image.Resampling.BILINEAR)
        sheet.paste(rgb, (x, y))
        text = "\n".join(textwrap.wrap(caption, width=52)[:3])
        draw.multiline_text((x + 4, y + thumb[1] + 2), text, fill=(0, 0, 0), font=font)
    return sheet
