"""The answer module's knobs (DESIGN 3.5), a section of the run's configuration tree
(``config.run.RunConfig.answer``; fields declared with ``knobs.knob``)."""

from __future__ import annotations

from dataclasses import dataclass

from efficienteqa.answer.calls import (
    ANSWER_PROBABILITIES,
    ANSWER_PROBABILITY,
    TOKEN_ANSWER,
    TOKEN_ANSWERS,
)
from efficienteqa.answer.confident import STEP_WEIGHTS
from efficienteqa.answer.rag import TOP_K, Confidence
from efficienteqa.config.knobs import knob

# Where the answer comes from: the top-K frames at the end (EfficientEQA's RAG), or the best
# per-step answer by weight x confidence (ExploreEQA).
ANSWER_AT = ("retrieval", "best-step")
ANSWERS = ("auto", "direct", "paper")


@dataclass(frozen=True)
class AnswerConfig:
    """How the question is answered from what was seen. Each default is written here once and
    recorded in run.json as it is."""

    top_k: int = knob(TOP_K, help="Frames retrieved for the answer (the paper's K).")
    distinct_views: bool = knob(True, beyond=True, off="repeated_views", help="Retrieve K "
                                "different views, or (off) the K most relevant frames even when "
                                "they repeat one view (DESIGN 3.5).")
    answer: str = knob("auto", beyond=True, help="How the retrieved frames are answered: auto "
                       "(direct when the model gives logprobs) | direct (one answer with a hint "
                       "for the question's form, confidence its token probability) | paper (M "
                       "verbalized guesses, grouped; DESIGN 3.5).")
    answer_at: str = knob("retrieval", help="retrieval (the top-K frames at the end: "
                          "EfficientEQA) | best-step (the best per-step answer: ExploreEQA); "
                          "set by the method.")
    confidence: Confidence = knob("verbalized", help="How the model's confidence is read, for "
                                  "semantic values and answers: verbalized (black-box) | token "
                                  "(token probabilities, white-box); set by the method.")
    step_weight: str = knob("relevancy", help="ExploreEQA's answer: what weighs each step's "
                            "answer: relevancy (the relevancy scorer's Sim, no extra call) | "
                            "confident (the VLM's own P(yes) to 'are you confident about "
                            "answering with this view?', one call a frame, as ExploreEQA's "
                            "code; the paper preset's).")
    answer_every_step: bool = knob(False, help="ExploreEQA's answer: ask at every valid frame, "
                                   "as ExploreEQA does online (off: only the frames that can "
                                   "still win; the same answer in fewer calls).")
    answer_probability: str = knob(ANSWER_PROBABILITY, help="How a token-probability answer's "
                                   "confidence is read: product (the whole answer's "
                                   "probability) | per-token (its tokens' geometric mean).")
    token_answer: str = knob(TOKEN_ANSWER, help="White-box ExploreEQA's per-frame prompt: short "
                             "(one line) | verbalized (DESIGN 3.5's prompt with one guess, read "
                             "by its token probability).")

    def __post_init__(self) -> None:
        if self.top_k < 1:
            raise ValueError(f"top_k must be at least 1, not {self.top_k}")
        for name, allowed in (("answer", ANSWERS), ("answer_at", ANSWER_AT),
                              ("confidence", ("verbalized", "token")),
                              ("step_weight", STEP_WEIGHTS),
                              ("answer_probability", ANSWER_PROBABILITIES),
                              ("token_answer", TOKEN_ANSWERS)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"{name} must be one of {allowed}, not {getattr(self, name)!r}")
