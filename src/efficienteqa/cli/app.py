"""The ``efficienteqa`` command's typer apps and console, shared by its command modules."""

from __future__ import annotations

from typing import Any

import typer
from rich.console import Console
from typer.core import TyperGroup


class Commands(TyperGroup):
    """The commands, each ended by Ctrl-C with a line that says so and exit 130: Typer ends an
    interrupted command silently (exit 130) before ``cli.main`` could say anything. ``ask``
    and ``eval`` say more (what was kept, how to go on) before this."""

    def invoke(self, ctx: Any) -> Any:
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt:
            console.print("[yellow]interrupted[/yellow]", highlight=False)
            raise typer.Exit(130) from None


app = typer.Typer(add_completion=False, no_args_is_help=True, cls=Commands,
                  help="EfficientEQA: explore a house, stop early, answer a question.")
scenes = typer.Typer(no_args_is_help=True, help="Synthetic houses: generate one, verify the frozen "
                     "splits, export their walks.")
app.add_typer(scenes, name="scenes")
models = typer.Typer(no_args_is_help=True,
                     help="Local language models (gguf from PyPI) and the llama.cpp server.")
app.add_typer(models, name="models")
perception = typer.Typer(no_args_is_help=True,
                         help="Pixel perception: render its training frames, train its network.")
app.add_typer(perception, name="perception")
console = Console()
