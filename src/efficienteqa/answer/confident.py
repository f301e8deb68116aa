"""ExploreEQA's weight of a step's answer: the model's own P(yes) to "Are you confident about
answering the question with the current view?" (DESIGN 3.6).

ExploreEQA answers with the step whose answer scores highest; its code weighs each step's answer
by this P(yes), asked of the same model on the same view. ``AgentConfig.step_weight`` chooses
it ("confident", the paper preset's) or the relevancy scorer's Sim ("relevancy", the main
table's rows: no extra call). White-box reads P(yes) from the first reply token's yes/no
probabilities; black-box from a verbalized "yes 80". An unreadable reply weighs 0: that step
cannot win, and the problem is recorded.
"""

from __future__ import annotations

import math

import numpy as np

from efficienteqa.models.base import ChatModel, Message
from efficienteqa.vc.logprobs import yes_prob_or_none
from efficienteqa.vc.prompts import load_prompt
from efficienteqa.vc.yes_no import yes_no_confidence

PROMPTS = "efficienteqa.answer"  # answer/prompts/confident.txt, confident_token.txt
STEP_WEIGHTS = ("relevancy", "confident")
TOP_LOGPROBS = 10
MAX_TOKENS = 16


def confident_probability(model: ChatModel, question: str, item: str | np.ndarray, *,
                          token: bool) -> tuple[float, list[str]]:
    """P(yes) that the view ``item`` (a frame's text, or its RGB image) answers ``question``,
    and what of the reply could not be read (then P = 0)."""
    view = (f"What it sees now: {item}" if isinstance(item, str)
            else "The image is what it sees now.")
    images = () if isinstance(item, str) else (item,)
    name = "confident_token" if token else "confident"
    prompt = load_prompt(name, PROMPTS).format(question=question, view=view)
    if token:
        resp = model.chat([Message("user", prompt, images)], max_tokens=1, temperature=0.0,
                          logprobs=TOP_LOGPROBS)
        p = yes_prob_or_none(resp.logprobs)
        if p is None:
            return 0.0, [f"no yes/no among the reply's tokens {resp.text!r}: weight 0"]
        return p, []
    resp = model.chat([Message("user", prompt, images)], max_tokens=MAX_TOKENS, temperature=0.0)
    p, problems = yes_no_confidence(resp.text or "")
    if math.isnan(p):
        return 0.0, [f"unreadable reply {(resp.text or '')[:60]!r}: weight 0"]
    return p, problems
