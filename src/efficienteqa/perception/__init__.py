"""Perception back-ends. ``semantic``: the offline default (DESIGN 5) that turns the environment's
instance buffer into short factual text for a text-only language model; ``pixels``: the
project's own network over RGB-D; ``image``: the frames as images for an image VLM
(``--backends.perception rgb``).

The package imports nothing, so a light module under it (``pixels.jobs``, which the CLI reads
to make its options) loads no mapping or scipy.
"""
