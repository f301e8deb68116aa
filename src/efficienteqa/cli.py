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
models = typer.Typer(no_args_is_help=True,
                     help="Local language models (gguf from PyPI) and the llama.cpp server.")
app.add_typer(models, name="models")
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


@models.command("install")
def models_install(
    names: list[str] = typer.Argument(None, help="Models to install (default: qwen2.5-coder-1.5b)."),
    all_models: bool = typer.Option(False, "--all", help="Install every registered model."),
) -> None:
    """Download, assemble and verify model files into the cache (idempotent)."""
    from efficienteqa.models.local import DEFAULT_MODEL, LOCAL_MODELS, install_model

    chosen = list(LOCAL_MODELS) if all_models else (names or [DEFAULT_MODEL])
    for name in chosen:
        start = time.perf_counter()
        path = install_model(name, progress=True)
        console.print(f"{name}: {path} ({path.stat().st_size / 1e6:.0f} MB, "
                      f"{time.perf_counter() - start:.1f} s)", highlight=False, soft_wrap=True)


@models.command("runtime")
def models_runtime() -> None:
    """Make llama.cpp importable: the cached portable wheel, built once if absent (4-5 min)."""
    from efficienteqa.models.local import ensure_llama_cpp

    start = time.perf_counter()
    ensure_llama_cpp(progress=True)
    console.print(f"llama.cpp runtime ready ({time.perf_counter() - start:.1f} s)")


@models.command("serve")
def models_serve(
    name: str = typer.Argument("qwen2.5-coder-1.5b", help="The model to serve."),
    port: int | None = typer.Option(None, help="Port on 127.0.0.1 (default 8765, or a free one)."),
    threads: int = typer.Option(2, help="CPU threads."),
    ctx: int = typer.Option(4096, help="Context length in tokens."),
) -> None:
    """Start (or reuse) the detached llama.cpp OpenAI-compatible server."""
    from efficienteqa.models.local import serve

    start = time.perf_counter()
    with console.status(f"starting the llama.cpp server for {name}..."):
        info = serve(name, port=port, threads=threads, ctx=ctx)
    console.print(f"{name} at {info.base_url} (pid {info.pid}, ready in "
                  f"{time.perf_counter() - start:.1f} s, log {info.log})", highlight=False, soft_wrap=True)


@models.command("stop")
def models_stop(name: str | None = typer.Argument(None, help="The model whose server to stop "
                                                   "(default: every server).")) -> None:
    """Stop local llama.cpp servers."""
    from efficienteqa.models.local import stop

    stopped = stop(name)
    for info in stopped:
        console.print(f"stopped {info.name} (pid {info.pid}, port {info.port})")
    if not stopped:
        console.print("no server running")


@models.command("status")
def models_status() -> None:
    """Installed models and running servers."""
    from rich.table import Table

    from efficienteqa.models.local import LOCAL_MODELS, is_installed, running

    servers = {info.name: info for info in running()}
    table = Table("model", "installed", "server")
    for name, entry in LOCAL_MODELS.items():
        info = servers.get(name)
        server = "-" if info is None else (f"{info.base_url} (pid {info.pid})"
                                           + ("" if info.healthy() else " not answering"))
        table.add_row(name, f"yes, {entry.size_mb} MB" if is_installed(name) else "no", server)
    console.print(table)

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
