"""The agent's commands: ask one question, evaluate a method on a dataset, grade, report."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.markup import escape

from efficienteqa.ask_plan import ASK_OUT
from efficienteqa.cli.app import app, console
from efficienteqa.cli.options import run_options
from efficienteqa.config.presets import Resolved
from efficienteqa.config.run import ASK_EVAL_FIELDS
from efficienteqa.redact import redact_urls

if TYPE_CHECKING:
    from efficienteqa.scenes import Scene
    from efficienteqa.trace import StepHook

AGENT_SECTIONS = ("backends", "scene", "explore", "stop", "answer")


@app.command("ask")
@run_options(AGENT_SECTIONS, only={"eval": ASK_EVAL_FIELDS}, by_method=False)
def ask_command(
    run: Resolved,
    question: str | None = typer.Argument(None, help="The question, in free text (or --episode)."),
    scene: str = typer.Option("synthetic:0", help="synthetic:SEED (a generated house), "
                              "recorded:WALK.mcap or recorded:FOLDER (a recorded walk, read in "
                              "order), hm3d:SCENE (with --scene.env habitat) or "
                              "ros2[:PARAMS.toml] (a live robot on ROS 2 with Nav2).",
                              rich_help_panel="Question"),
    episode: str | None = typer.Option(None, help="Ask question ID (or row N) of --eval.dataset, "
                                       "in its scene, from its start pose.",
                                       rich_help_panel="Question"),
    start: str | None = typer.Option(None, help="Start pose X,Y,YAW_DEG (default: the scene's).",
                                     rich_help_panel="Question"),
    out: Path | None = typer.Option(None, help="Folder for episode.json and report.html "
                                    f"(default {ASK_OUT}, which each ask replaces). A folder "
                                    "given here that holds another question's episode is "
                                    "refused, unless --overwrite.", show_default=False,
                                    rich_help_panel="Output"),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace the episode of another "
                                   "question in --out, and an existing --rerun file.",
                                   rich_help_panel="Output"),
    rerun: str | None = typer.Option(None, help="Also log the episode to rerun: a FILE.rrd to "
                                     "open with `rerun FILE.rrd` (an existing one is replaced "
                                     "only with --overwrite), or live (spawn the viewer here; "
                                     "needs a screen). Needs the rerun extra.",
                                     rich_help_panel="Output"),
    record: Path | None = typer.Option(None, help="Also write the episode's frames as a recorded "
                                       "walk, in --record-format; replay it with --scene "
                                       "recorded:PATH.", rich_help_panel="Output"),
    record_format: str | None = typer.Option(None, help="How --record writes: mcap (one "
                                             "FILE.mcap: ROS 2 topics and TF), rosbag2 (a "
                                             "FOLDER as ros2 bag record writes it: "
                                             "metadata.yaml and FOLDER_0.mcap, for ros2 bag "
                                             "info and play) or frames (a FOLDER of images and "
                                             "poses.jsonl). Default: mcap for a path ending in "
                                             ".mcap, else frames.", show_default=False,
                                             rich_help_panel="Output"),
) -> None:
    """Explore a scene until the relevancy rule stops, answer, and write the episode report."""
    from efficienteqa.ask_plan import plan_ask, run_ask
    from efficienteqa.report.episode import ask_lines, interrupted_note

    p = plan_ask(run.run, question, scene, episode=episode, start=start, out=out,
                 overwrite=overwrite, rerun=rerun, record=record, record_format=record_format)
    try:
        done = run_ask(p, opening=lambda scene: console.status(f"opening {scene}..."),
                       progress=_progress)
    except KeyboardInterrupt as stop:  # Ctrl-C (on a robot, the documented stop)
        console.print(f"[yellow]interrupted[/yellow]{interrupted_note(stop, p.out, rerun, record)}",
                      highlight=False, soft_wrap=True)
        raise typer.Exit(130) from None
    lines = ask_lines(done.record, done.episode_json, done.report_html, reference=p.reference,
                      rerun=rerun, recorded=record, warnings=done.warnings)
    console.print(f"[bold]answer:[/bold]{escape(lines[0][len('answer:'):])}", highlight=False)
    for line in lines[1:]:
        console.print(escape(line), highlight=False, soft_wrap=True)
    for warning in done.warnings:  # a recording that a full disk cut short: not the episode
        console.print(f"[yellow]warning:[/yellow] {escape(warning)}", highlight=False,
                      soft_wrap=True)


@contextmanager
def _progress(opened: Scene, budget: int | None) -> Iterator[StepHook]:
    """The scene's note, then a bar over the episode's steps, each with its Sim and z."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from efficienteqa.envs.base import is_recording
    from efficienteqa.trace import StepRecord

    if opened.note:
        console.print(opened.note, highlight=False, soft_wrap=True)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn(), TextColumn("{task.fields[info]}"))
    with Progress(*columns, console=console) as bar:
        what = "reading frames" if is_recording(opened.env) else "exploring"
        task = bar.add_task(what, total=budget, info="")

        def on_step(step: StepRecord, *_: object) -> None:
            c = step.check
            info = ("invalid frame" if c is None else
                    f"Sim {c.sim:.3f}" + (f"  z {c.z:+.2f}" if c.z is not None else ""))
            bar.update(task, completed=step.step, info=info)

        yield on_step


@app.command("judge")
def judge_command(
    runs: list[Path] = typer.Argument(..., help="Run folders written by `efficienteqa eval`."),
    judge: str | None = typer.Option(None, help="The LLM-Match judge (a VLM spec). Default: eval's "
                                     "judge model (the local model, RunSpec.judge).",
                                     show_default=False),
    judge_mode: str | None = typer.Option(None, help="grade | yes-prob | openeqa | auto "
                                          "(default; see `eval --help`).", show_default=False),
) -> None:
    """Grade finished runs again with another judge (e.g. openai:gpt-4o); results are kept."""
    from efficienteqa.eval.judge_prompts import DEFAULT_JUDGE
    from efficienteqa.eval.plan import mode_of
    from efficienteqa.eval.runner import rejudge
    from efficienteqa.stack import parse_vlm

    judge = judge or DEFAULT_JUDGE  # the one default judge model, eval's
    parse_vlm(judge, images=False, flag="--judge")
    mode = mode_of(judge_mode, judge)
    for folder in runs:
        with console.status(f"grading {folder}..."):
            n, score = rejudge(folder, judge, mode)
        console.print(f"{folder}: {n} episodes graded by {redact_urls(judge)} ({mode}): "
                      f"LLM-Match {score:.1f}", highlight=False, soft_wrap=True)


@app.command("eval")
@run_options()
def eval_command(
    run: Resolved,
    out: Path = typer.Option(..., help="Run folder: run.json, episodes.jsonl, episodes/ (resumed "
                             "when it exists).", rich_help_panel="Output"),
) -> None:
    """Run a method on a dataset, resumably: one JSON line per episode, graded by the rule judge
    (synthetic) and by LLM-Match (with a judge model)."""
    from efficienteqa.cli.progress import eval_progress, say_failures
    from efficienteqa.eval.plan import episodes_done, plan_run, prepare_run
    from efficienteqa.eval.runner import run_eval

    e = run.run.eval
    spec = plan_run(run.run, run.preset, run.preset_run.agent)  # the checks that need no scene
    questions = prepare_run(spec, out)
    ids = [q.id for q in questions]
    try:
        with eval_progress(console, e.method, ids, out) as on_episode:
            result = run_eval(spec, questions, out, workers=e.workers, address=e.address,
                              on_episode=on_episode)
    except KeyboardInterrupt:  # each episode done is a whole line already: say how to go on
        console.print(f"[yellow]interrupted[/yellow]: {episodes_done(out, ids)} of {len(ids)} "
                      f"episodes are done in {out / 'episodes.jsonl'}; the same command resumes "
                      "the others", highlight=False, soft_wrap=True)
        raise typer.Exit(130) from None
    console.print(f"{result.ran} episodes run, {result.skipped} already done, {result.failed} "
                  f"failed, {result.wall_s:.0f} s ({result.episodes_per_hour:.0f} episodes/hour)",
                  highlight=False)
    console.print(f"results: {out / 'episodes.jsonl'}\nsummary: efficienteqa report {out}",
                  highlight=False, soft_wrap=True)
    if result.failed:  # a run with failed episodes is not a success (they resume on a re-run)
        say_failures(console, out, result.failed, ids)
        raise typer.Exit(1)


@app.command("report")
def report_command(
    folders: list[Path] = typer.Argument(..., help="Run folders written by `efficienteqa eval --out`."),
    out: Path | None = typer.Option(None, help="Folder for report.md, its plots and report.html "
                                    "(default: the run folder itself for one run, else "
                                    "FIRST_FOLDER/../report)."),
    paired_against: Path | None = typer.Option(None, "--paired-against", help="A reference run: "
                                               "each run's accuracy and steps against it, paired "
                                               "over the questions both answered (bootstrap 95% CI)."),
    markdown: bool = typer.Option(False, "--markdown", help="Print the Markdown table of the "
                                  "runs (as the README's results blocks hold it) instead of "
                                  "writing the report pages; each run folder still gets its "
                                  "summary.json and report.html."),
) -> None:
    """Tables and plots across evaluation runs (the paper's Tables I-III in form): Markdown and HTML.
    Every run folder also gets its summary.json and report.html (a published run, results/)."""
    from rich.table import Table

    from efficienteqa.eval.readme_tables import markdown_table
    from efficienteqa.eval.tables import overview_rows, publish_runs, write_run_report

    summaries, differences, target, stamp = publish_runs(folders, out, paired_against,
                                                         markdown=markdown)
    if markdown:
        sys.stdout.write(redact_urls(markdown_table(summaries, differences)))
        return
    md, page = write_run_report(summaries, target, stamp=stamp)
    header, rows = overview_rows(summaries)
    table = Table()
    for i, name in enumerate(header):  # names whole, numbers right-aligned
        table.add_column(name, no_wrap=i < 2, justify="left" if i < 2 else "right")
    for row in rows:
        table.add_row(*row)
    console.print(table)
    console.print(f"markdown: {md}\nhtml:     {page}", highlight=False, soft_wrap=True)


@app.command("config")
@run_options()
def config_command(run: Resolved) -> None:
    """Print the run's whole configuration as a --config file (TOML, every value, the preset and
    options given applied): what `eval` with the same options would run. A password in a
    server's URL is printed as *** (docs/servers.md), said in a comment first."""
    from efficienteqa.config.presets import to_toml

    text = to_toml(run.run)
    shown = redact_urls(text)
    if shown != text:
        shown = ("# a password in a server's URL is shown as ***: write it back before using "
                 "this file\n" + shown)
    sys.stdout.write(shown)
