"""EfficientEQA: explore an unknown scene, stop early, answer a free-form question."""

__version__ = "0.1.0.dev0"
