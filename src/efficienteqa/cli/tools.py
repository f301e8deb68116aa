"""The commands beside the agent's: synthetic houses, local models, pixel perception."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from efficienteqa.cli.app import console, models, perception, scenes
from efficienteqa.cli.options import job_options
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS
from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.local.weights import DEFAULT_MODEL
from efficienteqa.perception.pixels.jobs import DatasetJob, MeasureJob, ThresholdJob, TrainJob


@scenes.command("generate")
def scenes_generate(
    seed: int = typer.Option(0, help="The house seed; a seed fully determines a house."),
    out: Path = typer.Option(Path("out/scene"), help="Output folder."),
    assets: str = typer.Option(DEFAULT_ASSETS, help="'sh3d' (the furniture package's CC0 "
                               "catalogue), 'sh3d-all' (with its CC-BY catalogues; writes "
                               "ATTRIBUTION.md) or 'builtin' (boxes)."),
    cc_by: bool = typer.Option(False, "--cc-by", help="The same as --assets sh3d-all."),
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
    """Download, assemble and verify model files into the cache, and make the llama.cpp
    runtime that serves them importable (built once, 4-5 min, when no wheel is cached); idempotent."""
    from efficienteqa.models.local import install_models

    for name, path, seconds in install_models(names or (), every=all_models):
        console.print(f"{name}: {path} ({path.stat().st_size / 1e6:.0f} MB, {seconds:.1f} s)",
                      highlight=False, soft_wrap=True)


@models.command("runtime")
def models_runtime() -> None:
    """Make llama.cpp importable: the cached portable wheel, built once if absent (4-5 min)."""
    from efficienteqa.models.local import ensure_llama_cpp

    start = time.perf_counter()
    ensure_llama_cpp(progress=True)
    console.print(f"llama.cpp runtime ready ({time.perf_counter() - start:.1f} s)")


@models.command("serve")
def models_serve(
    name: str = typer.Argument(DEFAULT_MODEL, help="The model to serve."),
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

    from efficienteqa.models.local import status_rows

    table = Table("model", "installed", "server")
    for row in status_rows():
        table.add_row(*row)
    console.print(table)


@perception.command("dataset")
@job_options(DatasetJob)
def perception_dataset(job: DatasetJob) -> None:
    """Render RGB-D frames with per-pixel category, colour and state labels at half size."""
    from efficienteqa.perception.pixels.dataset import render_dataset
    from efficienteqa.perception.pixels.houses import parse_seeds

    houses = parse_seeds(job.seeds)
    start = time.perf_counter()
    meta = render_dataset(houses, job.out, job.frames_per_house, job.seed, workers=job.workers,
                          assets=job.assets, recolour_share=job.recolour_share)
    console.print(f"{len(houses)} houses, {len(houses) * job.frames_per_house} frames in "
                  f"{(time.perf_counter() - start) / 60:.1f} min -> {job.out} ({meta['frames']} "
                  "frames in all)", highlight=False, soft_wrap=True)


@perception.command("train")
@job_options(TrainJob)
def perception_train(job: TrainJob) -> None:
    """Train the pixel network on rendered frames; validate on houses 3900-3909."""
    from efficienteqa.perception.pixels.train import train_as_asked, trained_line

    console.print(trained_line(train_as_asked(job), job.out), highlight=False, soft_wrap=True)


@perception.command("evaluate")
@job_options(MeasureJob)
def perception_evaluate(job: MeasureJob) -> None:
    """Measure pixel perception against the semantic sensor on held-out houses: objects in view
    found and right per category, size and distance, recoloured objects, objects of meshes
    held out of training and (with --assets sh3d-all) of unseen catalogues apart; colour,
    state and the floor's room type."""
    from efficienteqa.cli.progress import bar
    from efficienteqa.datasets.synthetic import parse_seeds
    from efficienteqa.perception.pixels.evaluate import measure, measured_lines

    try:
        houses = parse_seeds(job.seeds)
    except ValueError as exc:
        raise EfficientEQAError(f"cannot read the house seeds {job.seeds!r} ({exc})",
                                fix="give a range such as 100-129") from None
    with bar("frames") as progress:
        figures = measure(job, houses, progress=progress)
    for line in measured_lines(figures, job.seeds, job.out):
        console.print(line, highlight=False, soft_wrap=True)


@perception.command("thresholds")
@job_options(ThresholdJob)
def perception_thresholds(job: ThresholdJob) -> None:
    """Choose each category's region threshold on validation houses (best F1 of objects found
    and regions right) and, with --write, record them with the weights."""
    from efficienteqa.cli.progress import bar
    from efficienteqa.perception.pixels.thresholds import choose_on

    with bar("frames") as progress:
        done = choose_on(job, progress=progress)
    for line in done.lines():
        console.print(line, highlight=False, soft_wrap=True)
    if job.write:
        console.print(f"recorded in {done.write()}", highlight=False)


@perception.command("table")
def perception_table(
    figures: Path = typer.Argument(..., help="A JSON file written by 'perception evaluate "
                                   "--out'."),
) -> None:
    """Print the figures of a pixel-perception evaluation as the markdown table docs/perception.md
    holds (a test checks the two agree)."""
    from efficienteqa.perception.pixels.evaluate import read_table

    print(read_table(figures))
