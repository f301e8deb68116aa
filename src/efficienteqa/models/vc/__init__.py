"""Verbalized confidence (paper, "Exploration - VC"; SPEC 3.3, 3.5, 3.6, 7).

One reply holds M answers with confidences ``{r_i, c_i}``; they are parsed (``parse``),
normalised (``c_i' = c_i / sum c``), grouped into semantic classes ``R_k = E(r_i)`` with
``C_k = sum c_i'`` (``grouping``), and the class of highest ``C_k`` is the answer (``calls``).
Parsers never raise: whatever can be read is kept, documented defaults fill the gaps, and every
repair is a short string in ``problems`` so that an episode can count them.
"""

from efficienteqa.models.vc.calls import (
    answer_with_confidence,
    blind_answer,
    explore_prompt,
    explore_scores,
    letter_probs_from_logprobs,
    yes_prob_from_logprobs,
)
from efficienteqa.models.vc.grouping import (
    ExactGrouper,
    Grouper,
    LLMGrouper,
    RuleGrouper,
    argmax,
    contradictory,
    group_answers,
    normalise,
)
from efficienteqa.models.vc.parse import (
    BARE_YES_NO_CONFIDENCE,
    DEFAULT_LETTERS,
    DEFAULT_P_YES,
    AnswerClass,
    AnswerResult,
    Candidate,
    M,
    ParseResult,
    parse_candidates,
    parse_letters,
    parse_worth_exploring,
)
from efficienteqa.models.vc.prompts import load_prompt

__all__ = [
    "BARE_YES_NO_CONFIDENCE", "DEFAULT_LETTERS", "DEFAULT_P_YES", "M", "AnswerClass",
    "AnswerResult", "Candidate", "ExactGrouper", "Grouper", "LLMGrouper", "ParseResult",
    "RuleGrouper", "answer_with_confidence", "argmax", "blind_answer", "contradictory",
    "explore_prompt", "explore_scores", "group_answers", "letter_probs_from_logprobs",
    "load_prompt", "normalise", "parse_candidates", "parse_letters", "parse_worth_exploring",
    "yes_prob_from_logprobs",
]
