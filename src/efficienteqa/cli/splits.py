"""``scenes verify`` and ``scenes export-walks``: the frozen splits on this machine."""

from __future__ import annotations

import time
from pathlib import Path

import typer

from efficienteqa.cli.app import console, scenes

# What verify compares, in its --help (``datasets.manifest.COMPARED`` in the manifest).
VERIFY_HELP = "\n\n".join((
    "Regenerate a frozen split's houses and questions here and compare them with its manifest.",
    "Compared byte for byte: the manifest's sha256 (over its content, and the digest committed in "
    "the code); the split file's questions against the manifest's; each house's digest (the "
    "generated house before rendering: rooms, doors, walls, every object's category, model, "
    "colour, state, room, position, size and yaw, numbers rounded to 1 mm) and its start pose; "
    "each question's id, wording, category, reference answer, alternatives, accepted answers, "
    "evidence ids, oracle steps and oracle pose (the last two are counted on quarter-size "
    "instance renders, so a renderer that draws an edge differently can change them).",
    "Compared loosely, since renders differ across Mesa versions: the start view's (640x480) "
    "pixels per instance id, within 1 % of the frame's pixels, and its median depth, within 1 cm. "
    "Rendered colours are not compared.",
    "One line per mismatch and exit code 1 where any is found. About 5 s a house.",
))
EXPORT_HELP = "\n\n".join((
    "Write each house's walk (frames with poses, in the recorded-walk folder format) and the "
    "questions, so answer-only methods are evaluated without the simulator: efficienteqa eval "
    "--eval.dataset OUT/questions.jsonl.",
    "A house's walk: four views at the start pose (turning 90 degrees), then the shortest paths "
    "through the oracle poses of the split's questions on the house, nearest first, a view at "
    "most every 3 m, each leg ending facing a question's evidence. The walk sees every "
    "question's evidence and is the same for every question of its house.",
))
SPLIT_NAMES = "synthetic-v1 (alias synthetic) or synthetic-test-v1 (alias synthetic-test)"


@scenes.command("verify", help=VERIFY_HELP)
def scenes_verify(
    split: list[str] = typer.Argument(None, help=f"The splits to check: {SPLIT_NAMES}; "
                                      "default both.", show_default=False),
    limit: int | None = typer.Option(None, help="Check only the first N houses (by seed) of "
                                     "each split: a quick check."),
    manifest: Path | None = typer.Option(None, help="Check this manifest file instead of the "
                                         "packaged one (one split)."),
) -> None:
    """Regenerate a frozen split's houses and questions here and compare them with its
    manifest (``VERIFY_HELP`` says what is compared)."""
    from efficienteqa.cli.progress import bar
    from efficienteqa.datasets.manifest import to_verify, verify

    chosen, given = to_verify(split or (), manifest, limit)
    failed = 0
    for s in chosen:
        with bar(f"{s.name}: houses", limit) as progress:
            done = verify(s, given, limit, progress=progress)
        for line in done.mismatches:
            console.print(f"[red]mismatch:[/red] {line}", highlight=False, soft_wrap=True)
        failed += len(done.mismatches)
        console.print(done.line(), highlight=False)
    if failed:
        raise typer.Exit(1)


@scenes.command("export-walks", help=EXPORT_HELP)
def scenes_export_walks(
    split: str = typer.Argument(..., help=f"The split: {SPLIT_NAMES}."),
    out: Path = typer.Argument(..., help="A new (or empty) folder."),
    limit: int | None = typer.Option(None, help="Only the split's first N questions (and the "
                                      "walks of their houses)."),
) -> None:
    """Write each house's walk and the questions (``EXPORT_HELP``; ``datasets.walks``)."""
    from efficienteqa.cli.progress import bar
    from efficienteqa.datasets.walks import export_walks

    start = time.perf_counter()
    with bar("houses") as progress:
        done = export_walks(split, out, limit, progress=progress)
    console.print(f"{done.questions} questions, {done.houses} walks, {done.frames} frames in "
                  f"{time.perf_counter() - start:.0f} s -> {done.path}", highlight=False,
                  soft_wrap=True)
