"""What the commands show while they run: a bar with ``eval``'s running scores, and its failures
after; a plain bar for the others."""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from pathlib import Path

from rich.console import Console

from efficienteqa.cli.app import console as app_console
from efficienteqa.redact import redact_urls


@contextmanager
def bar(what: str, total: int | None = None) -> Iterator[Callable[..., None]]:
    """A bar that goes when done; yields ``progress(done, total=None)`` to move it."""
    from rich.progress import Progress

    with Progress(console=app_console, transient=True) as shown:
        task = shown.add_task(what, total=total)
        yield lambda n, total=None: shown.update(task, completed=n, total=total)


@contextmanager
def eval_progress(console: Console, method: str, ids: Collection[str],
                  out: Path) -> Iterator[Callable[[dict], None]]:
    """A progress bar over the episodes ``ids`` (those already done in ``out`` counted; a line
    of another id is none of them, or the bar read "9/8"); yields the runner's
    ``on_episode``, which advances it and shows the scores so far."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from efficienteqa.eval.plan import episodes_done

    done_before = episodes_done(out, ids)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
               TextColumn("{task.fields[info]}"))
    scores: dict[str, list[float]] = {"rule": [], "choice": [], "judge": []}
    names = {"rule": "rule {:.1f}%", "choice": "letter {:.1f}%", "judge": "LLM-Match {:.1f}"}
    with Progress(*columns, console=console) as progress:
        task = progress.add_task(method, total=len(ids), completed=done_before, info="")

        def on_episode(row: dict) -> None:
            for key, values in scores.items():
                if row.get(key):
                    values.append(row[key]["value"])
            info = "  ".join(names[k].format(sum(v) / len(v)) for k, v in scores.items() if v)
            if row["status"] != "done":
                console.print(f"[yellow]{row['id']} failed:[/yellow] "
                              f"{redact_urls(str(row.get('error')))}", highlight=False,
                              soft_wrap=True)
            progress.update(task, advance=1, info=info)

        yield on_episode


def say_failures(console: Console, out: Path, failed: int, ids: Collection[str]) -> None:
    """The commonest errors of the failed episodes among ``ids`` (the questions of this
    command), and how to resume them."""
    from efficienteqa.eval.plan import commonest_errors

    for error, count in commonest_errors(out, ids):
        console.print(f"  {count} x {redact_urls(error)}", highlight=False, soft_wrap=True)
    console.print(f"[red]error:[/red] {failed} episode(s) failed (the commonest errors are "
                  "above, all in episodes.jsonl); the same command resumes them",
                  highlight=False, soft_wrap=True)
