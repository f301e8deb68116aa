"""Prompt templates: package text files, each in a ``prompts/`` folder beside the package that
uses it (``explore/prompts/explore.txt``, ``answer/prompts/answer.txt``, ``vc/prompts/group.txt``)."""

from __future__ import annotations

import functools
from importlib import resources

HOME = "efficienteqa.vc"  # where a template named without its package lives (grouping)


@functools.cache
def load_prompt(name: str, package: str = HOME) -> str:
    """The template ``<package>/prompts/<name>.txt`` (package data), e.g.
    ``load_prompt("answer", "efficienteqa.answer")``."""
    return (resources.files(package) / "prompts" / f"{name}.txt").read_text("utf-8")
