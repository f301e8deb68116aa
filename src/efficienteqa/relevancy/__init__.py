"""Image-question relevancy Sim(I_t, Q) (DESIGN 3.4) behind one protocol.

Back-ends: "minilm" (text, offline default), "overlap" (text, no model), "blip2-itm" (the
paper's), "clip", "siglip". Each is imported only when ``make_scorer`` builds it.
"""

from efficienteqa.relevancy.base import RelevancyScorer, make_scorer, scorer_kinds

__all__ = ["RelevancyScorer", "make_scorer", "scorer_kinds"]
