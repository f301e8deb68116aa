"""The agent's commands: ask one question, evaluate a method on a dataset, grade, report."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.markup import escape

from efficienteqa.cli.app import app, console
from efficienteqa.cli.options import run_options
from efficienteqa.config.presets import Resolved
from efficienteqa.config.run import ASK_EVAL_FIELDS
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D
from efficienteqa.redact import redact_urls

if TYPE_CHECKING:
    from efficienteqa.ask import AskResult
    from efficienteqa.envs.habitat.scenes import HabitatStart

AGENT_SECTIONS = ("backends", "scene", "explore", "stop", "answer")
ASK_OUT = Path("out/ask")  # ask's folder without --out: a scratch folder each ask replaces
EPISODE_FILE = "episode.json"


def _parse_start(text: str | None) -> Pose2D | None:
    if text is None:
        return None
    fix = "give it as X,Y,YAW_DEG in metres and degrees, e.g. 2.5,3,90"
    try:
        x, y, yaw_deg = (float(v) for v in text.split(","))
    except ValueError:
        raise EfficientEQAError(f"cannot read the start pose {text!r}", fix=fix) from None
    if not all(math.isfinite(v) for v in (x, y, yaw_deg)):
        raise EfficientEQAError(f"the start pose {text!r} is not finite", fix=fix)
    return Pose2D(x, y, math.radians(yaw_deg))


def _same_question(a: str, b: str) -> bool:
    return " ".join(a.lower().split()) == " ".join(b.lower().split())


def check_ask_folder(out: Path, question: str, overwrite: bool) -> None:
    """Before any work: ``out`` can take this ask's episode. Its episode.json and report.html
    must be files to write, and an episode of another question there is not replaced unless
    ``overwrite`` (two asks into one --out left only the second, without a word). The same
    question asked again replaces its own episode: that is running it again."""
    import json

    for name in (EPISODE_FILE, "report.html"):
        if (out / name).is_dir():
            raise EfficientEQAError(f"{out / name} is a folder",
                                    fix="remove it, or use another --out folder")
    path = out / EPISODE_FILE
    if overwrite or not path.exists():
        return
    try:
        earlier = json.loads(path.read_text()).get("question")
    except (OSError, ValueError, AttributeError):  # unreadable: whose it is is not known
        earlier = None
    if isinstance(earlier, str) and _same_question(earlier, question):
        return
    asked = (f": {earlier[:60]!r}" + ("..." if len(earlier) > 60 else "")
             if isinstance(earlier, str) else "")
    raise EfficientEQAError(f"{out} holds the episode of another question{asked}",
                            fix="use another --out folder, or --overwrite to replace it")


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
    from efficienteqa.envs.habitat.scenes import HabitatStart
    from efficienteqa.records import check_writable

    r = run.run
    replace_rerun = overwrite  # given: the scratch folder's own replacing is not a rerun file's
    if out is None:  # the scratch folder: each ask without --out replaces its episode
        out, overwrite = ASK_OUT, True
    if r.eval.method != "efficienteqa":
        raise EfficientEQAError(f"ask runs efficienteqa; method {r.eval.method!r} is for eval",
                                fix="use efficienteqa eval --eval.method with this configuration")
    from efficienteqa.eval.plan import check_backends

    check_backends(r)
    start_pose, habitat_start, reference, known_as = _parse_start(start), None, None, None
    check_writable(out)  # before the episode, not after it
    if record is not None:
        from efficienteqa.envs.recorded.write import check_record_path

        check_record_path(record, layout=record_format)
    elif record_format is not None:
        raise EfficientEQAError("--record-format says how --record writes, and there is no "
                                "--record", fix="add --record PATH, or leave out --record-format")
    if episode is not None:
        from efficienteqa.datasets import find_question, load_dataset

        q = find_question(load_dataset(r.eval.dataset, path=r.eval.hm_eqa_path,
                                       assets=r.scene.assets), episode)
        question, scene, reference, known_as = q.question, q.scene, q.answer, q.original_question
        habitat_start = HabitatStart.from_source(q.source)
        start_pose = start_pose or (Pose2D(*q.start) if q.start is not None else None)
    if start_pose is not None and scene.startswith("recorded:"):
        raise EfficientEQAError("a recorded walk starts where it was recorded",
                                fix="leave out --start")
    if not question or not question.strip():  # "   " too: before the scene opens, not after
        raise EfficientEQAError("no question", fix='give one, e.g. efficienteqa ask "What colour is '
                                'the sofa?", or --episode ID with --eval.dataset')
    if rerun is not None:  # rerun missing, no viewer, an unwritable file: before the scene opens
        from efficienteqa.report.rerun_target import check_target

        check_target(rerun, overwrite=replace_rerun)
    try:
        done = _asked(run, question, scene, out, overwrite, start_pose, habitat_start, known_as,
                      rerun, replace_rerun, record, record_format)
    except KeyboardInterrupt as stop:  # Ctrl-C (on a robot, the documented stop)
        console.print(f"[yellow]interrupted[/yellow]{_interrupted(stop, out, rerun, record)}",
                      highlight=False, soft_wrap=True)
        raise typer.Exit(130) from None
    from efficienteqa.report.episode import episode_lines

    rec = done.record
    say = console.print
    lines = episode_lines(rec)  # as the README's demo block shows them
    if not rec.get("reference") and reference:
        lines.append(f"reference answer: {reference}")
    for n, line in enumerate(lines):
        say(f"[bold]answer:[/bold]{escape(line[len('answer:'):])}" if n == 0 else escape(line),
            highlight=False)
    shown = {k: v for k, v in rec["backends"].items() if v and k != "capabilities"}
    say(redact_urls(f"back-ends: {', '.join(f'{k}={v}' for k, v in shown.items())}"),
        highlight=False, soft_wrap=True)
    model = rec["model"]
    say(f"model calls: {model['calls']}" + (f"   cost: ${model['cost_usd']:.4f}"
                                            if model.get("cost_usd") else ""), highlight=False)
    say(f"episode: {done.episode_json}\nreport:  {done.report_html}", highlight=False,
        soft_wrap=True)
    failed = " ".join(done.warnings)
    if rerun is not None and rerun != "live" and str(rerun) not in failed:
        say(f"rerun:   {rerun}   (open it: rerun {rerun})", highlight=False, soft_wrap=True)
    if record is not None and str(record) not in failed:
        say(f"recorded: {record} (replay: --scene recorded:{record})", highlight=False,
            soft_wrap=True)
    for warning in done.warnings:  # a recording that a full disk cut short: not the episode
        say(f"[yellow]warning:[/yellow] {escape(warning)}", highlight=False, soft_wrap=True)


def _interrupted(stop: KeyboardInterrupt, out: Path, rerun: str | None,
                 record: Path | None) -> str:
    """The rest of the line that says an ask was interrupted: what was kept, and how to ask
    again (an ask is not resumed; its recordings are not written over)."""
    partial = getattr(stop, "partial_episode", None)
    kept = (f" at step {partial['steps']}: the episode so far (its steps and model calls) is in "
            f"{out / EPISODE_FILE}" if isinstance(partial, dict) else " before exploring began")
    again = []
    if record is not None and record.exists():
        kept += f", its frames in {record}"
        again.append("another --record path")
    if rerun is not None and rerun != "live" and Path(rerun).exists():
        kept += f", its rerun log in {rerun}"
        again.append("--overwrite (or another --rerun file)")
    return (f"{kept}; the same command asks again" + (f", with {' and '.join(again)}"
                                                      if again else ""))


def _asked(run: Resolved, question: str, scene: str, out: Path, overwrite: bool,
           start_pose: Pose2D | None, habitat_start: HabitatStart | None, known_as: str | None,
           rerun: str | None, replace_rerun: bool, record: Path | None,
           record_format: str | None) -> AskResult:
    """The ask command's episode, under the folder's lock: open the scene, explore with a
    progress bar, answer, write."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from efficienteqa.ask import ask
    from efficienteqa.envs.base import is_recording
    from efficienteqa.eval.records import run_lock
    from efficienteqa.scenes import open_scene
    from efficienteqa.trace import StepRecord

    r = run.run
    with run_lock(out):  # a second ask into the folder fails at once, not after exploring
        check_ask_folder(out, question, overwrite)
        with console.status(f"opening {scene}..."):
            opened = open_scene(scene, r.scene.assets, env=r.scene.env,
                                hm3d_root=r.scene.hm3d_root, noise=r.scene.noise,
                                start=habitat_start)
        if opened.note:
            console.print(opened.note, highlight=False, soft_wrap=True)
        try:
            columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                       TimeElapsedColumn(), TextColumn("{task.fields[info]}"))
            with Progress(*columns, console=console) as progress:
                what = "reading frames" if is_recording(opened.env) else "exploring"
                task = progress.add_task(what, total=r.agent.budget(opened.env), info="")

                def on_step(step: StepRecord, *_: object) -> None:
                    c = step.check
                    info = ("invalid frame" if c is None else
                            f"Sim {c.sim:.3f}" + (f"  z {c.z:+.2f}" if c.z is not None else ""))
                    progress.update(task, completed=step.step, info=info)

                return ask(question, opened, out, run=r, start=start_pose, on_step=on_step,
                           known_as=known_as, rerun=rerun, record=record,
                           record_format=record_format, replace_rerun=replace_rerun)
        finally:
            opened.env.close()


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
    from efficienteqa.datasets import load_dataset
    from efficienteqa.eval.plan import plan_run
    from efficienteqa.eval.records import check_resumable
    from efficienteqa.eval.runner import manifest, run_eval
    from efficienteqa.records import check_writable

    r, e = run.run, run.run.eval
    spec = plan_run(r, run.preset, run.preset_run.agent)  # the checks that need no scene
    check_writable(out)
    # a folder of another run is refused before the dataset's houses are built (minutes with
    # the furniture of --scene.assets sh3d); run_eval checks again under the folder's lock
    check_resumable(out, manifest(spec, 0))
    questions = load_dataset(e.dataset, path=e.hm_eqa_path, limit=e.limit,
                             closed_set=e.closed_set, assets=r.scene.assets)
    from efficienteqa.cli.progress import eval_progress

    ids = [q.id for q in questions]
    try:
        with eval_progress(console, e.method, ids, out) as on_episode:
            result = run_eval(spec, questions, out, workers=e.workers, address=e.address,
                              on_episode=on_episode)
    except KeyboardInterrupt:  # each episode done is a whole line already: say how to go on
        from efficienteqa.eval.records import read_episodes

        done = len(read_episodes(out / "episodes.jsonl").done & set(ids))
        console.print(f"[yellow]interrupted[/yellow]: {done} of {len(ids)} episodes are done in "
                      f"{out / 'episodes.jsonl'}; the same command resumes the others",
                      highlight=False, soft_wrap=True)
        raise typer.Exit(130) from None
    console.print(f"{result.ran} episodes run, {result.skipped} already done, {result.failed} "
                  f"failed, {result.wall_s:.0f} s ({result.episodes_per_hour:.0f} episodes/hour)",
                  highlight=False)
    console.print(f"results: {out / 'episodes.jsonl'}\nsummary: efficienteqa report {out}",
                  highlight=False, soft_wrap=True)
    if result.failed:  # a run with failed episodes is not a success (they resume on a re-run)
        from efficienteqa.cli.progress import say_failures

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
    from efficienteqa.eval.tables import (
        overview_rows,
        paired_differences,
        publish_run,
        read_summaries,
        run_folders,
        write_run_report,
    )
    from efficienteqa.records import check_writable

    summaries = read_summaries(folders)
    reference = None if paired_against is None else read_summaries([paired_against])[0]
    differences = paired_differences(summaries, reference)
    single = out is None and len(folders) == 1
    target = out or (folders[0] if len(folders) == 1 else folders[0].resolve().parent / "report")
    if not markdown:
        check_writable(target)  # before any file is written
    for folder, summary, difference in zip(run_folders(folders), summaries, differences):
        publish_run(folder, summary, difference)
    if markdown:
        sys.stdout.write(redact_urls(markdown_table(summaries, differences)))
        return
    md, page = write_run_report(summaries, target, stamp=not single)
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
