"""The ``efficienteqa`` command: parse, build, call a library function, print."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import typer
from rich.console import Console

from efficienteqa.errors import EfficientEQAError

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="EfficientEQA: explore a house, stop early, answer a question.")
scenes = typer.Typer(no_args_is_help=True, help="Synthetic houses: generate and preview.")
app.add_typer(scenes, name="scenes")
console = Console()


@scenes.command("generate")
def scenes_generate(
    seed: int = typer.Option(0, help="The house seed; a seed fully determines a house."),
    out: Path = typer.Option(Path("out/scene"), help="Output folder."),
    assets: str = typer.Option("sh3d", help="'sh3d' (furniture package) or 'builtin' (boxes)."),
    cc_by: bool = typer.Option(False, "--cc-by", help="Also use the CC-BY catalogues "
                               "(writes ATTRIBUTION.md)."),
) -> None:
    """Write house.json, questions.jsonl, map.png and views.png for one seed."""
    from efficienteqa.scenes import write_scene

    start = time.perf_counter()
    with console.status(f"generating house {seed}..."):
        files = write_scene(seed, out, assets, cc_by)
    console.print(
        f"house {seed}: {files.n_rooms} rooms, {files.n_objects} objects, "
        f"{files.n_questions} questions in {time.perf_counter() - start:.1f} s"
    )
    for path in (files.house, files.questions, files.map_png, files.views_png):
        console.print(f"  {path}")


def main() -> None:
    """Entry point: user-fixable errors become one red line and exit code 1."""
    try:
        app()
    except EfficientEQAError as exc:
        console.print(f"[red]error:[/red] {exc}", highlight=False, soft_wrap=True)
        sys.exit(1)
    except KeyboardInterrupt:
        console.print("[yellow]interrupted[/yellow]")
        sys.exit(130)


if __name__ == "__main__":
    main()
