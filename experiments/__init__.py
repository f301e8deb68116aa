"""Experiments: the studies behind the figures of results/ and docs/ (exploration, stopping,
answering, ablations, the main table). Run from the repository root as modules, e.g.
``python -m experiments.explore_bench steering``; shared set-up is in ``experiments.common``.
The timing benchmarks are in ``benchmarks/``.
"""
