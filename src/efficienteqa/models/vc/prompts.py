"""Prompt templates: package text files under ``models/prompts``."""

from __future__ import annotations

import functools
from importlib import resources


@functools.cache
def load_prompt(name: str) -> str:
    """The prompt template ``prompts/<name>.txt`` (package data)."""
    return (resources.files("efficienteqa.models") / "prompts" / f"{name}.txt").read_text("utf-8")
