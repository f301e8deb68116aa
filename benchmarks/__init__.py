"""Timing benchmarks: speed and memory of the renderer, the map, the models, the houses, the
agent and the Ray runner. Run from the repository root as modules, e.g.
``python -m benchmarks.render_bench``. The studies behind published figures are in
``experiments/``.
"""
