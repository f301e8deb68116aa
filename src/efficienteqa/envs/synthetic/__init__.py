"""Procedural synthetic houses: the embedded default environment."""
