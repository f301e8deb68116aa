"""Named sets of command-line settings. A preset fills only the options the user did not give.

``paper``: the set-up of the paper's experiments (its Sec. IV): HM-EQA's first 100 questions
in Habitat-Sim, GPT-4o (gpt-4o-2024-05-13, temperature 1) reading the RGB frames, BLIP-2 ITM
(Salesforce/blip2-itm-vit-g) for relevancy, Z_th = 3 and K = 5. The paper does not name its
LLM-Match judge; the preset uses the same GPT-4o, grading 1-5.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from efficienteqa.errors import EfficientEQAError

PAPER_VLM = "openai:gpt-4o-2024-05-13"

PRESETS: dict[str, dict[str, Any]] = {
    "paper": {
        "dataset": "hm-eqa", "limit": 100, "env": "habitat",
        "vlm": PAPER_VLM, "temperature": 1.0, "perception": "rgb", "relevancy": "blip2-itm",
        "grouping": "llm", "z_th": 3.0, "top_k": 5,
        "judge": PAPER_VLM, "judge_mode": "grade",
    },
}


def apply_preset(name: str | None, given: Mapping[str, Any], defaulted: set[str]) -> dict[str, Any]:
    """``given`` with the preset's value for each option in ``defaulted`` (the ones the user
    left at their defaults); options the preset does not name are kept."""
    if name is None:
        return dict(given)
    if name not in PRESETS:
        raise EfficientEQAError(f"unknown preset {name!r}", fix=f"use one of {', '.join(PRESETS)}")
    values = PRESETS[name]
    return {k: values[k] if k in values and k in defaulted else v for k, v in given.items()}
