"""The ``efficienteqa`` command's typer apps and console, shared by its command modules."""

from __future__ import annotations

import typer
from rich.console import Console

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="EfficientEQA: explore a house, stop early, answer a question.")
scenes = typer.Typer(no_args_is_help=True, help="Synthetic houses: generate one.")
app.add_typer(scenes, name="scenes")
models = typer.Typer(no_args_is_help=True,
                     help="Local language models (gguf from PyPI) and the llama.cpp server.")
app.add_typer(models, name="models")
perception = typer.Typer(no_args_is_help=True,
                         help="Pixel perception: render its training frames, train its network.")
app.add_typer(perception, name="perception")
console = Console()
