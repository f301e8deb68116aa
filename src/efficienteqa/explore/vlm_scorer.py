"""Semantic values from a (vision-)language model with verbalized confidence (SPEC 3.3)."""

from __future__ import annotations

from efficienteqa.explore.module import SemanticScore
from efficienteqa.models.base import ChatModel
from efficienteqa.models.vc.calls import explore_scores, explore_token_scores
from efficienteqa.models.vc.parse import M
from efficienteqa.observation import Observation, PromptPoint
from efficienteqa.perception.base import Perception


class VLMScorer:
    """The ``SemanticScorer`` of the agent: one VC call per prompted frame gives the per-letter
    LSV distribution and P(worth exploring) for the GSV. What the model reads (text or pixels)
    is the perception back-end's business. ``confidence="token"`` is the white-box baseline's
    reading: the same two values from token probabilities instead of words."""

    def __init__(self, model: ChatModel, perception: Perception, m: int = M,
                 confidence: str = "verbalized") -> None:
        self.model, self.perception, self.m, self.confidence = model, perception, m, confidence

    def score(self, obs: Observation, prompts: list[PromptPoint], question: str) -> SemanticScore:
        request = self.perception.explore_request(obs, prompts)
        if self.confidence == "token":
            return explore_token_scores(self.model, question, request.view, request.directions,
                                        request.images or None)
        return explore_scores(self.model, question, request.view, request.directions,
                              request.images or None, m=self.m)
