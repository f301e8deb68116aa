"""The question as a model reads it (beyond the paper; DESIGN 9): ``reader`` asks the agent's own
chat model once per episode for the question's target, checked against the question's words,
with the rules of ``question.parse_question`` as the fallback; ``aliases`` matches the target's
words to what the perception names, by meaning."""
