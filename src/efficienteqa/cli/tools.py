"""The commands beside the agent's: synthetic houses, local models, pixel perception."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from efficienteqa.cli.app import console, models, perception, scenes
from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS
from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.local.weights import DEFAULT_MODEL


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
def perception_dataset(
    seeds: str = typer.Option(..., help="House seeds, e.g. 3000-3199 (within 3000-3999, the "
                              "houses reserved for perception; 3900-3909 validate)."),
    out: Path = typer.Option(..., help="Output folder (shards and meta.json; runs merge)."),
    frames_per_house: int = typer.Option(20, "--frames-per-house", help="Views per house."),
    seed: int = typer.Option(0, help="Seed of the views (with each house seed)."),
    workers: int = typer.Option(2, help="Rendering processes."),
    recolour_share: float = typer.Option(0.5, "--recolour-share", help="Share of colourable "
                                         "objects recoloured in training houses (3000-3899)."),
    assets: str = typer.Option(DEFAULT_ASSETS, help="The houses' furniture: sh3d (the CC0 "
                               "catalogue) or sh3d-all (every catalogue of the package; "
                               "training houses then never show the KatorLegaz catalogue)."),
) -> None:
    """Render RGB-D frames with per-pixel category, colour and state labels at half size."""
    from efficienteqa.perception.pixels.dataset import render_dataset
    from efficienteqa.perception.pixels.houses import parse_seeds

    houses = parse_seeds(seeds)
    start = time.perf_counter()
    meta = render_dataset(houses, out, frames_per_house, seed, workers=workers,
                          assets=assets, recolour_share=recolour_share)
    console.print(f"{len(houses)} houses, {len(houses) * frames_per_house} frames in "
                  f"{(time.perf_counter() - start) / 60:.1f} min -> {out} ({meta['frames']} "
                  "frames in all)", highlight=False, soft_wrap=True)


@perception.command("train")
def perception_train(
    data: Path = typer.Option(..., help="A folder written by 'perception dataset'."),
    out: Path = typer.Option(Path("src/efficienteqa/perception/pixels/weights/pixels.pt"),
                             help="The weights file (.pt; its .json is written beside it)."),
    steps: int = typer.Option(4000, help="Optimiser steps (fixes the result with --seed)."),
    seed: int = typer.Option(0, help="Seed of initialisation and crops."),
    batch: int = typer.Option(8, help="Crops per step."),
    minutes: float = typer.Option(90.0, help="Stop early after this long (a guard; recorded)."),
    threads: int = typer.Option(2, help="Torch CPU threads."),
    widths: str = typer.Option("16,32,64,96,160", help="Channels of the 1/1 ... 1/16 levels."),
    device: str = typer.Option("auto", help="auto (cuda where torch sees one) | cpu | cuda."),
    resume: bool = typer.Option(False, "--resume", help="Continue from the checkpoint beside "
                                "--out (same options and data)."),
    checkpoint_every: int = typer.Option(250, "--checkpoint-every", help="Steps between "
                                         "checkpoints (0: none)."),
) -> None:
    """Train the pixel network on rendered frames; validate on houses 3900-3909."""
    from efficienteqa.perception.pixels.train import train_as_asked, trained_line

    record = train_as_asked(data, out, steps=steps, seed=seed, batch=batch, minutes=minutes,
                            threads=threads, widths=widths, device=device, resume=resume,
                            checkpoint_every=checkpoint_every)
    console.print(trained_line(record, out), highlight=False, soft_wrap=True)


@perception.command("evaluate")
def perception_evaluate(
    seeds: str = typer.Option("100-129", help="Houses to measure on, e.g. 100-129 (the "
                              "evaluation split); never the network's training houses."),
    frames_per_house: int = typer.Option(8, "--frames-per-house", help="Views per house."),
    seed: int = typer.Option(0, help="Seed of the views (with each house seed)."),
    weights: Path | None = typer.Option(None, help="Weights to measure (default: the "
                                        "committed ones)."),
    out: Path | None = typer.Option(None, help="Write the figures here as JSON."),
    poses: Path | None = typer.Option(None, help="Measure at the poses of recorded walks (a "
                                      "file of experiments/walk_poses.py), frames spread "
                                      "evenly over each house's walk."),
    assets: str = typer.Option(DEFAULT_ASSETS, help="The houses' furniture: sh3d (the CC0 "
                               "catalogue the network trains on) or sh3d-all (with the CC-BY "
                               "catalogues, whose objects are measured apart)."),
    close_reads: int | None = typer.Option(None, "--close-reads", help="Supports read again "
                                           "a frame, on a crop around each (default: the "
                                           "pixel perception's own; 0 is off)."),
) -> None:
    """Measure pixel perception against the semantic sensor on held-out houses: objects in view
    found and right per category, size and distance, recoloured objects, objects of meshes
    held out of training and (with --assets sh3d-all) of unseen catalogues apart; colour,
    state and the floor's room type."""
    from efficienteqa.cli.progress import bar
    from efficienteqa.datasets.synthetic import parse_seeds
    from efficienteqa.perception.pixels.evaluate import measure, measured_lines

    try:
        houses = parse_seeds(seeds)
    except ValueError as exc:
        raise EfficientEQAError(f"cannot read the house seeds {seeds!r} ({exc})",
                                fix="give a range such as 100-129") from None
    with bar("frames") as progress:
        figures = measure(houses, seeds=seeds, frames_per_house=frames_per_house, seed=seed,
                          weights=weights, out=out, poses=poses, assets=assets,
                          close_reads=close_reads, progress=progress)
    for line in measured_lines(figures, seeds, out):
        console.print(line, highlight=False, soft_wrap=True)


@perception.command("thresholds")
def perception_thresholds(
    seeds: str = typer.Option("3900-3909", help="Validation houses to choose on (within "
                              "3900-3909)."),
    frames_per_house: int = typer.Option(10, "--frames-per-house", help="Views per house."),
    seed: int = typer.Option(0, help="Seed of the views (with each house seed)."),
    weights: Path | None = typer.Option(None, help="Weights to choose for (default: the "
                                        "committed ones); their .json records the choice."),
    write: bool = typer.Option(False, "--write", help="Record the thresholds in the weights' "
                               ".json (else only print them)."),
) -> None:
    """Choose each category's region threshold on validation houses (best F1 of objects found
    and regions right) and, with --write, record them with the weights."""
    from efficienteqa.cli.progress import bar
    from efficienteqa.perception.pixels.thresholds import choose_on

    with bar("frames") as progress:
        done = choose_on(seeds, frames_per_house=frames_per_house, seed=seed, weights=weights,
                         progress=progress)
    for line in done.lines():
        console.print(line, highlight=False, soft_wrap=True)
    if write:
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
