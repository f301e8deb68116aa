"""The ``efficienteqa`` command: parse, build, call a library function, print."""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from efficienteqa.envs.synthetic.house import DEFAULT_ASSETS
from efficienteqa.errors import EfficientEQAError
from efficienteqa.geometry import Pose2D
from efficienteqa.models.local.weights import DEFAULT_MODEL
from efficienteqa.stop.rules import GATED_MIN_STEP, StopConfig  # light: help texts show its defaults

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


# The dataset of `ask --episode` and `eval` when neither the command line nor a preset names one.
DEFAULT_DATASET = "synthetic"

PRESET_HELP = ("A named configuration shipped with the package (efficienteqa/configs/NAME.toml): "
               "paper (the paper's set-up: HM-EQA's first 100 in Habitat-Sim, GPT-4o at T=1 on "
               "RGB, BLIP-2 ITM, Z_th 3, K 5) | paper-offline (the paper's algorithm on the "
               "offline stack) | a main-table row: default, explore-eqa, explore-eqa-blackbox, "
               "explore-eqa-verbalized-prompt, explore-eqa-per-token, frontier-only, random, "
               "blind. Fills only options not given.")
CONFIG_HELP = ("A configuration file: TOML, one option = value a line, the options' names with "
               "underscores (min_stop_step = 10), base = \"PRESET\" to start from a preset. "
               "Fills options not given on the command line, before --preset.")
ENV_HELP = "synthetic (generated houses) | habitat (Habitat-Sim + HM3D; needs --hm3d-root)."
HM3D_HELP = "Folder holding the HM3D scene folders, e.g. 00800-TEEsavR23oF/ (see docs/habitat.md)."

# The panels of `ask --help` and `eval --help`.
QUESTION, METHOD, BACKENDS, BEYOND, OUTPUT = ("Question", "Method", "Back-ends",
                                              "Beyond the paper (DESIGN 8-9)", "Output")


def _option(panel: str, *args: Any, **kwargs: Any) -> Any:
    return typer.Option(*args, rich_help_panel=panel, **kwargs)


# The options of an agent run, declared once for `ask` and `eval`. Left out, an option is None
# and takes the default of its dataclass (presets.build_stack / build_config): no default is
# written twice.
ZTh = Annotated[float | None, _option(METHOD, "--z-th", help="Stop when a frame's relevancy z-score "
                                           f"exceeds this (default {StopConfig.z_th:g}), with no "
                                           "answerability gate or the model gate; refused with a "
                                           "gate that judges every frame (see --z-gated).",
                                           show_default=False)]
ZGated = Annotated[float | None, _option(BEYOND, "--z-gated", help="The z-score a frame that an "
                                              "answerability gate judging every frame (rules, "
                                              "sightings: the default) passed must exceed to stop "
                                              f"the robot (default {StopConfig.z_gated:g}).",
                                              show_default=False)]
MinStopStep = Annotated[int | None, _option(METHOD, help="Never stop before this step (default "
                                                 f"{GATED_MIN_STEP}; the paper's: 10).",
                                                 show_default=False)]
StopRuleOpt = Annotated[str | None, _option(METHOD,
    "--stop-rule", help="paper (DESIGN 3.4) | lookback | robust | floor, or parts joined by '+' "
    f"(e.g. lookback+floor); default {StopConfig.rule}.", show_default=False)]
NoEarlyStop = Annotated[bool, _option(METHOD, "--no-early-stop", help="Explore to the budget.")]
TopK = Annotated[int | None, _option(METHOD, "--top-k", help="Frames retrieved for the answer "
                                          "(the paper's K).", show_default=False)]
MaxSteps = Annotated[int | None, _option(METHOD, help="Step budget (default int(sqrt(area)*3)).")]
RefusalRetries = Annotated[int | None, _option(BEYOND,
    help="Re-plans within one step after the environment refuses a move (left out: the agent's "
    "default; 0: a refused move spends the step, as in the paper's set-up).", show_default=False)]
StopClearance = Annotated[float | None, _option(BEYOND,
    "--stop-clearance-m", help="Clearance (m) the planner wants where a move ends (left out: the "
    "explorer's default; 0: stop where the 3 m cut falls, as in the paper's set-up).", show_default=False)]
Prompts = Annotated[str | None, _option(BEYOND,
    help="Where lettered prompt points may lie: default (from 1 m away, so more steps ask) or "
    "paper (2-10 m, DESIGN 3.3).", show_default=False)]
Exploration = Annotated[str | None, _option(BEYOND,
    help="The frontier explorer's options beyond the paper: default, or paper (DESIGN 3.2's "
    "explorer, every one off).", show_default=False)]
Gate = Annotated[str | None, _option(BEYOND,
    help="The answerability gate a relevancy stop must pass: auto (default: rules with a "
    "perception that describes objects, sightings with the VLM's sightings, else model), rules "
    "(the question's target in the frame's description), sightings (the target in the frame's "
    "sightings), model (one yes/no call to the VLM) or none (the paper's stop).",
    show_default=False)]
Steering = Annotated[str | None, _option(BEYOND,
    help="target (default: go to the room the question names, inspect what it asks about, "
    "look around on entering) or none (the paper's exploration).", show_default=False)]
Reading = Annotated[str | None, _option(BEYOND,
    help="How the question's target is read: rules (no call), model (one call to the VLM, "
    "checked against the question's words) or rules+rooms (default: the rules' target, the "
    "VLM's likely rooms for a question naming none; one call). Read only where the steering or "
    "a gate reads it.", show_default=False)]
Matching = Annotated[str | None, _option(BEYOND,
    help="How the question's words match the perception's categories: words or meaning "
    "(default: embeddings, and one yes/no call to the VLM for unsure pairs).",
    show_default=False)]
DistinctViews = Annotated[bool | None, _option(BEYOND,
    "--distinct-views/--repeated-views", help="Retrieve K different views (default), or the K "
    "most relevant frames even when they repeat one view (DESIGN 3.5).", show_default=False)]
GateFinal = Annotated[bool | None, _option(BEYOND,
    "--gate-final/--no-gate-final", help="Stop at a frame the rules gate finds answers outright "
    "(a count group wholly in view) without waiting for a relevancy outlier (default), or only "
    "at outliers.", show_default=False)]
AnswerOpt = Annotated[str | None, _option(METHOD,
    "--answer", help="How the retrieved frames are answered: auto (default: direct when the model "
    "gives logprobs), direct (one answer with a hint for the question's form, confidence its token "
    "probability) or paper (M verbalized guesses, grouped; DESIGN 3.5).", show_default=False)]
AnswerProbability = Annotated[str | None, _option(METHOD,
    "--answer-probability", help="How a token-probability answer's confidence (white-box "
    "ExploreEQA's, the direct answer's) is read: product (default: the whole answer's "
    "probability) or per-token (its tokens' geometric mean, length-normalised).",
    show_default=False)]
StepWeight = Annotated[str | None, _option(METHOD,
    "--step-weight", help="ExploreEQA's answer: what weighs each step's answer: relevancy "
    "(default: the relevancy scorer's Sim, no extra call) or confident (the VLM's own P(yes) to "
    "'are you confident about answering with this view?', one call a frame, as ExploreEQA's "
    "code; the paper preset's).", show_default=False)]
TokenAnswer = Annotated[str | None, _option(METHOD,
    "--token-answer", help="White-box ExploreEQA's per-frame prompt: short (default: one line) or "
    "verbalized (DESIGN 3.5's prompt with one guess, as black-box asks, read by its token "
    "probability).", show_default=False)]
Seed = Annotated[int | None, _option(METHOD, help="Seed of the explorer's frontier sampling.",
                                          show_default=False)]
Vlm = Annotated[str | None, _option(BACKENDS, help="local:MODEL (default local:qwen2.5-coder-1.5b), or "
                                         "openai:MODEL[@BASE_URL] (key: see --api-key-env).",
                                         show_default=False)]
# The model server's options (Stack fields; None: ChatBackend's defaults).
TimeoutS = Annotated[float | None, _option(BACKENDS,
    "--timeout-s", help="Seconds the model server has for each try of a call (default 120); a "
    "hung server costs this times the tries.", show_default=False)]
Retries = Annotated[int | None, _option(BACKENDS,
    help="Retries of a model call after the first try, on timeouts, refused connections, 429 "
    "and 5xx (default 4).", show_default=False)]
ApiKeyEnv = Annotated[str | None, _option(BACKENDS,
    "--api-key-env", help="The environment variable whose key is sent to the --vlm server, or "
    "none. Default: OPENAI_API_KEY for api.openai.com only; no key for any other server.",
    show_default=False)]
ImageFormat = Annotated[str | None, _option(BACKENDS,
    "--image-format", help="auto | png | jpeg (default auto: jpeg, quality 90, for openai: "
    "servers, about 6 times smaller than PNG; png for the local one).", show_default=False)]
ImageMaxSide = Annotated[int | None, _option(BACKENDS,
    "--image-max-side", help="Images are shrunk to this longer side in px (default 512).",
    show_default=False)]
CapabilitiesFile = Annotated[str | None, _option(BACKENDS,
    "--capabilities", help="A JSON file of what the --vlm openai: server can do, e.g. "
    '{"logprobs": true, "json_schema": false, "images": true, "max_images": 1}, in place of '
    "asking it (for a server whose answers mislead the probe; a flag left out is off).",
    show_default=False)]
ImageDetail = Annotated[str | None, _option(BACKENDS,
    "--image-detail", help="auto | low | high: OpenAI's image_url.detail (default: not sent, "
    "the server's own).", show_default=False)]
Temperature = Annotated[float | None, _option(BACKENDS, help="The VLM's sampling temperature for every "
                                                   "call (default 0).", show_default=False)]
PerceptionOpt = Annotated[str | None, _option(BACKENDS,
    "--perception", help="semantic (object labels as text; default) | pixels (RGB-D read by the "
    "project's own network, described as text) | rgb (images, needs an image VLM).",
    show_default=False)]
SightingsOpt = Annotated[str | None, _option(BACKENDS,
    "--sightings", help="Where the steering and the sightings gate learn what a frame shows of "
    "rooms and of the question's target: auto (default: the perception's own; with rgb, the "
    "VLM's) | perception | model (one call to the VLM per step: boxes over the image, or "
    "numbers of the description's objects).", show_default=False)]
Relevancy = Annotated[str | None, _option(BACKENDS,
    help="minilm (default over text) | minilm-match (MiniLM calibrated to a match probability) | "
    "overlap | vlm-match (the VLM answers 'does this view show it?'; default over images) | "
    "blip2-itm (default over images where its weights are) | clip | siglip.",
    show_default=False)]
Device = Annotated[str | None, _option(BACKENDS,
    "--device", help="Where an image relevancy model (blip2-itm, clip, siglip) runs: auto "
    "(default: the GPU torch sees, in float16, else the CPU) | cpu | cuda | cuda:N.",
    show_default=False)]
RelevancyWeights = Annotated[str | None, _option(BACKENDS,
    "--relevancy-weights", metavar="DIR", help="A local folder with the relevancy model's "
    "weights, e.g. from `hf download Salesforce/blip2-itm-vit-g --local-dir DIR` (default: the "
    "model's Hugging Face cache).", show_default=False)]
AllowDownload = Annotated[bool | None, _option(BACKENDS,
    "--allow-download/--no-download", help="Let missing relevancy weights download from the "
    "Hugging Face Hub (default: no; the error names the model).", show_default=False)]
ExploreScorer = Annotated[str | None, _option(METHOD,
    help="Where the semantic values come from: auto (default: the VLM's verbalized confidence "
    "when it reads images or with token confidence, else direction-logit) | vlm | "
    "direction-logit (no model: features of the direction texts).",
    show_default=False)]
Grouping = Annotated[str | None, _option(METHOD, help="How equivalent answers are grouped: llm "
                                              "(default) | rules.", show_default=False)]
Cache = Annotated[bool | None, _option(BACKENDS, "--cache/--no-cache", help="Replay identical model "
                                            "requests from the response cache (default on).",
                                            show_default=False)]
Env = Annotated[str | None, _option(BACKENDS, help=ENV_HELP + " Default synthetic.", show_default=False)]
Hm3dRoot = Annotated[Path | None, _option(BACKENDS, help=HM3D_HELP)]
HmEqaPath = Annotated[Path | None, _option(QUESTION, help="Folder with HM-EQA's questions.csv and "
                                                "scene_init_poses.csv (default: downloaded).")]
Assets = Annotated[str, _option(BACKENDS, help="'sh3d' (furniture package) or 'builtin' (boxes).")]
Preset = Annotated[str | None, _option(METHOD, help=PRESET_HELP, show_default=False)]
ConfigFile = Annotated[Path | None, _option(METHOD, "--config", metavar="FILE", help=CONFIG_HELP,
                                                 show_default=False)]
Dataset = Annotated[str | None, _option(QUESTION, help="synthetic (the fixed split; default) | "
                                             "synthetic-paraphrase (its first 48 re-phrased) | "
                                             "synthetic:SEEDS (e.g. synthetic:0-9) | hm-eqa.",
                                             show_default=False)]
ClosedSet = Annotated[bool, _option(QUESTION, "--closed-set", help="HM-EQA's four-choice mode (all 500 "
                                         "questions): graded by the chosen letter; the default "
                                         "judge is then none.")]


# Options a configuration cannot set: what the command reads it from, and where its output goes.
_NOT_CONFIGURABLE = ("ctx", "question", "preset", "config_file", "out")


def _option_types() -> dict[str, type]:
    """The options of ``ask`` and ``eval`` a configuration may set, each with its type (from
    the commands' signatures: the options are declared once)."""
    import typing

    types: dict[str, type] = {}
    for command in (ask_command, eval_command):
        for name, hint in typing.get_type_hints(command).items():
            if name in _NOT_CONFIGURABLE or name == "return":
                continue
            kinds = [a for a in typing.get_args(hint) if a is not type(None)] or [hint]
            types[name] = kinds[0]
    return types


def _options(ctx: typer.Context) -> dict:
    """The command's options, those left out on the command line filled from --config, then
    from --preset: each option set once, whatever the source."""
    from efficienteqa.presets import fill, judge_follows_vlm, load_config, load_preset

    params = dict(ctx.params)
    left_out = ("DEFAULT", "DEFAULT_MAP")  # by name: typer may bring its own click
    given = {k for k in params
             if getattr(ctx.get_parameter_source(k), "name", "DEFAULT") not in left_out}
    types = _option_types()
    values: dict = {}
    if params.get("preset") is not None:
        values.update(load_preset(params["preset"], types))
    if params.get("config_file") is not None:
        values.update(load_config(params["config_file"], types))
    options = judge_follows_vlm(fill(params, values, given), values, given)
    if "method" in values and "method" not in params:
        options["method"] = values["method"]  # ask refuses another method
    return options


@app.command("ask")
def ask_command(
    ctx: typer.Context,
    question: str | None = typer.Argument(None, help="The question, in free text (or --episode)."),
    scene: str = _option(QUESTION, "synthetic:0", help="synthetic:SEED (a generated house) or "
                              "hm3d:SCENE (with --env habitat)."),
    episode: str | None = _option(QUESTION, None, help="Ask question ID (or row N) of --dataset, in its "
                                       "scene, from its start pose."),
    dataset: str | None = _option(QUESTION, None, help="The dataset of --episode: synthetic (default) | "
                                       "hm-eqa | synthetic:SEEDS.", show_default=False),
    start: str | None = _option(QUESTION, None, help="Start pose X,Y,YAW_DEG (default: the scene's)."),
    hm_eqa_path: HmEqaPath = None,
    preset: Preset = None,
    config_file: ConfigFile = None,
    z_th: ZTh = None,
    min_stop_step: MinStopStep = None,
    stop_rule: StopRuleOpt = None,
    no_early_stop: NoEarlyStop = False,
    top_k: TopK = None,
    max_steps: MaxSteps = None,
    answer: AnswerOpt = None,
    answer_probability: AnswerProbability = None,
    token_answer: TokenAnswer = None,
    step_weight: StepWeight = None,
    explorer: str | None = _option(METHOD, None, help="sfe (default) | frontier-only | random.",
                                        show_default=False),
    grouping: Grouping = None,
    explore_scorer: ExploreScorer = None,
    seed: Seed = None,
    vlm: Vlm = None,
    temperature: Temperature = None,
    timeout_s: TimeoutS = None,
    retries: Retries = None,
    api_key_env: ApiKeyEnv = None,
    image_format: ImageFormat = None,
    image_max_side: ImageMaxSide = None,
    image_detail: ImageDetail = None,
    capabilities: CapabilitiesFile = None,
    perception: PerceptionOpt = None,
    sightings: SightingsOpt = None,
    relevancy: Relevancy = None,
    device: Device = None,
    relevancy_weights: RelevancyWeights = None,
    allow_download: AllowDownload = None,
    env: Env = None,
    hm3d_root: Hm3dRoot = None,
    assets: Assets = DEFAULT_ASSETS,
    cache: Cache = None,
    refusal_retries: RefusalRetries = None,
    stop_clearance_m: StopClearance = None,
    prompts: Prompts = None,
    distinct_views: DistinctViews = None,
    exploration: Exploration = None,
    gate: Gate = None,
    z_gated: ZGated = None,
    gate_final: GateFinal = None,
    steering: Steering = None,
    reading: Reading = None,
    matching: Matching = None,
    out: Path = _option(OUTPUT, Path("out/ask"), help="Folder for episode.json and report.html."),
) -> None:
    """Explore a scene until the relevancy rule stops, answer, and write the episode report."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from efficienteqa.agent import StepRecord
    from efficienteqa.ask import ask
    from efficienteqa.envs.habitat.scenes import HabitatStart
    from efficienteqa.presets import build_config, build_stack
    from efficienteqa.records import check_writable
    from efficienteqa.scenes import open_scene
    from efficienteqa.stack import check_stack, parse_vlm

    o = _options(ctx)
    if (o.get("method") or "efficienteqa") != "efficienteqa":
        raise EfficientEQAError(f"ask runs efficienteqa; method {o['method']!r} is for eval",
                                fix="use efficienteqa eval --method with this configuration")
    scene, episode, start, assets = o["scene"], o["episode"], o["start"], o["assets"]
    config, stack = build_config(o), build_stack(o)
    # Bad input fails before the scene is built.
    check_stack(stack)
    parse_vlm(stack.vlm, images=stack.perception == "rgb", temperature=stack.temperature,
              **stack.server_options())
    start_pose, habitat_start, reference, known_as = _parse_start(start), None, None, None
    check_writable(out)  # before the episode, not after it
    if episode is not None:
        from efficienteqa.datasets import find_question, load_dataset

        q = find_question(load_dataset(o["dataset"] or DEFAULT_DATASET, path=o["hm_eqa_path"],
                                       assets=assets), episode)
        question, scene, reference, known_as = q.question, q.scene, q.answer, q.original_question
        habitat_start = HabitatStart.from_source(q.source)
        start_pose = start_pose or (Pose2D(*q.start) if q.start is not None else None)
    if not question:
        raise EfficientEQAError("no question", fix='give one, e.g. efficienteqa ask "What colour is '
                                'the sofa?", or --episode ID with --dataset')
    with console.status(f"opening {scene}..."):
        opened = open_scene(scene, assets, env=o["env"] or "synthetic", hm3d_root=o["hm3d_root"],
                            start=habitat_start)
    try:
        budget = config.budget(opened.env)
        columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                   TimeElapsedColumn(), TextColumn("{task.fields[info]}"))
        with Progress(*columns, console=console) as progress:
            task = progress.add_task("exploring", total=budget, info="")

            def on_step(record: StepRecord, *_: object) -> None:
                c = record.check
                info = ("invalid frame" if c is None else
                        f"Sim {c.sim:.3f}" + (f"  z {c.z:+.2f}" if c.z is not None else ""))
                progress.update(task, completed=record.step, info=info)

            done = ask(question, opened, out, stack=stack, config=config,
                       start=start_pose, on_step=on_step, known_as=known_as)
    finally:
        opened.env.close()
    r, rec = done.result, done.record
    oracle = rec.get("oracle_steps")
    console.print(f"[bold]answer:[/bold] {r.answer or '(none)'}  (confidence {r.confidence:.2f})",
                  highlight=False)
    console.print(f"steps: {r.steps} of {r.budget}" + (f" (oracle {oracle})" if oracle else "")
                  + f"   stop: {r.stop_reason}   time: {r.wall_s:.0f} s", highlight=False)
    reference = rec["reference"]["answer"] if rec.get("reference") else reference
    if reference:
        console.print(f"reference answer: {reference}", highlight=False)
    shown = {k: v for k, v in rec["backends"].items() if v and k != "capabilities"}
    console.print(f"back-ends: {', '.join(f'{k}={v}' for k, v in shown.items())}",
                  highlight=False, soft_wrap=True)
    model = rec["model"]
    console.print(f"model calls: {model['calls']}" + (f"   cost: ${model['cost_usd']:.4f}"
                                                      if model.get("cost_usd") else ""),
                  highlight=False)
    console.print(f"episode: {done.episode_json}\nreport:  {done.report_html}", highlight=False,
                  soft_wrap=True)


def _judge_mode(mode: str | None, judge: str) -> str:
    """The mode of ``judge`` for eval and judge alike: left out, ``eval.judge.DEFAULT_JUDGE_MODE``
    ("auto": token probabilities for the small local models, the 1-5 grade otherwise)."""
    from efficienteqa.eval.judge import DEFAULT_JUDGE_MODE, judge_mode

    return judge_mode(mode or DEFAULT_JUDGE_MODE, judge)


@app.command("judge")
def judge_command(
    runs: list[Path] = typer.Argument(..., help="Run folders written by `efficienteqa eval`."),
    judge: str | None = typer.Option(None, help="The LLM-Match judge (a VLM spec). Default: eval's "
                                     "judge model (the local model, RunSpec.judge).",
                                     show_default=False),
    judge_mode: str | None = typer.Option(None, help="grade | yes-prob | openeqa | auto (default; see `eval "
                                          "--help`).", show_default=False),
) -> None:
    """Grade finished runs again with another judge (e.g. openai:gpt-4o); results are kept."""
    from efficienteqa.eval.judge import DEFAULT_JUDGE
    from efficienteqa.eval.runner import rejudge
    from efficienteqa.stack import parse_vlm

    judge = judge or DEFAULT_JUDGE  # the one default judge model, eval's
    parse_vlm(judge, images=False, flag="--judge")
    mode = _judge_mode(judge_mode, judge)
    for run in runs:
        with console.status(f"grading {run}..."):
            n, score = rejudge(run, judge, mode)
        console.print(f"{run}: {n} episodes graded by {judge} ({mode}): LLM-Match {score:.1f}",
                      highlight=False, soft_wrap=True)


@app.command("eval")
def eval_command(
    ctx: typer.Context,
    dataset: Dataset = None,
    limit: int | None = _option(QUESTION, None, help="Only the first N questions of the dataset."),
    hm_eqa_path: HmEqaPath = None,
    closed_set: ClosedSet = False,
    preset: Preset = None,
    config_file: ConfigFile = None,
    method: str = _option(METHOD, "efficienteqa", help="efficienteqa | explore-eqa | "
                               "explore-eqa-blackbox | blind | frontier-only | random | module:function."),
    z_th: ZTh = None,
    min_stop_step: MinStopStep = None,
    stop_rule: StopRuleOpt = None,
    no_early_stop: NoEarlyStop = False,
    top_k: TopK = None,
    max_steps: MaxSteps = None,
    answer: AnswerOpt = None,
    answer_probability: AnswerProbability = None,
    token_answer: TokenAnswer = None,
    step_weight: StepWeight = None,
    seed: Seed = None,
    grouping: Grouping = None,
    explore_scorer: ExploreScorer = None,
    workers: int = _option(BACKENDS, 1, help="Episodes in parallel; more than 1 runs on Ray."),
    address: str | None = _option(BACKENDS, None, help="A Ray cluster address (default: a local Ray)."),
    vlm: Vlm = None,
    temperature: Temperature = None,
    timeout_s: TimeoutS = None,
    retries: Retries = None,
    api_key_env: ApiKeyEnv = None,
    image_format: ImageFormat = None,
    image_max_side: ImageMaxSide = None,
    image_detail: ImageDetail = None,
    capabilities: CapabilitiesFile = None,
    perception: PerceptionOpt = None,
    sightings: SightingsOpt = None,
    relevancy: Relevancy = None,
    device: Device = None,
    relevancy_weights: RelevancyWeights = None,
    allow_download: AllowDownload = None,
    judge: str | None = _option(BACKENDS, None, help="The LLM-Match judge (a VLM spec), or 'rule'/'none' "
                                     "for no model. Synthetic questions are always graded by the "
                                     "rule judge too. Default: rule for synthetic datasets, "
                                     "the local judge model (RunSpec.judge) for hm-eqa.", show_default=False),
    judge_mode: str | None = _option(BACKENDS, None, help="grade (the judge says 1-5 by the project's "
                                          "rubric) | yes-prob (1 + 4 P(yes) for 'same answer?') | "
                                          "openeqa (OpenEQA's LLM-Match protocol; the paper preset's) "
                                          "| auto (default: yes-prob for local models, else grade).",
                                          show_default=False),
    env: Env = None,
    hm3d_root: Hm3dRoot = None,
    assets: Assets = DEFAULT_ASSETS,
    cache: Cache = None,
    refusal_retries: RefusalRetries = None,
    stop_clearance_m: StopClearance = None,
    prompts: Prompts = None,
    distinct_views: DistinctViews = None,
    exploration: Exploration = None,
    gate: Gate = None,
    z_gated: ZGated = None,
    gate_final: GateFinal = None,
    steering: Steering = None,
    reading: Reading = None,
    matching: Matching = None,
    out: Path = _option(OUTPUT, ..., help="Run folder: run.json, episodes.jsonl, episodes/ (resumed "
                             "when it exists)."),
    reports: bool = _option(OUTPUT, False, "--reports", help="Also write each episode's report.html."),
) -> None:
    """Run a method on a dataset, resumably: one JSON line per episode, graded by the rule judge
    (synthetic) and by LLM-Match (with a judge model)."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from efficienteqa.datasets import load_dataset
    from efficienteqa.eval.methods import METHODS, RunSpec, default_judge, resolve
    from efficienteqa.eval.records import read_episodes
    from efficienteqa.eval.runner import run_eval
    from efficienteqa.presets import build_config, build_stack, given, named_configuration
    from efficienteqa.records import check_writable
    from efficienteqa.stack import check_stack, parse_vlm

    o = _options(ctx)
    preset, preset_values = named_configuration(o["preset"], o["config_file"], _option_types())
    method, closed_set, assets, hm3d_root = o["method"], o["closed_set"], o["assets"], o["hm3d_root"]
    resolve(method)  # bad input fails before anything slow
    stack = build_stack(o)
    check_stack(stack)
    build_config(o)  # a value the agent refuses (--top-k 0, --z-th nan): here, not per episode
    parse_vlm(stack.vlm, images=stack.perception == "rgb", temperature=stack.temperature,
              **stack.server_options())
    dataset = o["dataset"] or DEFAULT_DATASET
    if closed_set and dataset != "hm-eqa":
        raise EfficientEQAError(f"--closed-set is HM-EQA's multiple-choice mode; {dataset} has no "
                                "choices", fix="use --dataset hm-eqa, or leave out --closed-set")
    if closed_set and method in METHODS and method != "blind":
        raise EfficientEQAError(f"method {method!r} answers open-ended only; --closed-set is "
                                "answered by blind (or a module:function method that sets "
                                "extra['letter'])", fix="use --method blind")
    judge_spec = o["judge"] or ("none" if closed_set else default_judge(dataset))
    if judge_spec == "rule" and not dataset.startswith("synthetic"):
        raise EfficientEQAError(f"the rule judge grades synthetic questions only, not {dataset}",
                                fix="give a judge model (--judge local:MODEL or openai:MODEL)")
    judge_spec = None if judge_spec in ("none", "rule") else judge_spec
    if judge_spec:
        parse_vlm(judge_spec, images=False, flag="--judge")
    check_writable(out)
    questions = load_dataset(dataset, path=o["hm_eqa_path"], limit=o["limit"], closed_set=closed_set,
                             assets=assets)
    spec = RunSpec(method=method, dataset=dataset, stack=stack, config=build_config(o),
                   closed_set=closed_set,
                   judge=judge_spec, judge_mode=_judge_mode(o["judge_mode"], judge_spec or ""),
                   preset=preset, preset_config=build_config(preset_values),
                   reports=o["reports"], assets=assets,
                   hm3d_root=str(hm3d_root) if hm3d_root is not None else None,
                   **given(o, ["env"]))
    done_before = len(read_episodes(out / "episodes.jsonl").done)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
               TextColumn("{task.fields[info]}"))
    with Progress(*columns, console=console) as progress:
        task = progress.add_task(method, total=len(questions), completed=min(done_before, len(questions)),
                                 info="")
        scores: list[float] = []
        rules: list[float] = []
        letters: list[float] = []

        def on_episode(row: dict) -> None:
            if row.get("judge"):
                scores.append(row["judge"]["value"])
            if row.get("rule"):
                rules.append(row["rule"]["value"])
            if row.get("choice"):
                letters.append(row["choice"]["value"])
            info = "  ".join([*([f"rule {sum(rules) / len(rules):.1f}%"] if rules else []),
                              *([f"letter {sum(letters) / len(letters):.1f}%"] if letters else []),
                              *([f"LLM-Match {sum(scores) / len(scores):.1f}"] if scores else [])])
            if row["status"] != "done":
                console.print(f"[yellow]{row['id']} failed:[/yellow] {row.get('error')}",
                              highlight=False, soft_wrap=True)
            progress.update(task, advance=1, info=info)

        result = run_eval(spec, questions, out, workers=o["workers"], address=o["address"],
                          on_episode=on_episode)
    console.print(f"{result.ran} episodes run, {result.skipped} already done, {result.failed} failed, "
                  f"{result.wall_s:.0f} s ({result.episodes_per_hour:.0f} episodes/hour)",
                  highlight=False)
    console.print(f"results: {out / 'episodes.jsonl'}\nsummary: efficienteqa report {out}",
                  highlight=False, soft_wrap=True)
    if result.failed:  # a run with failed episodes is not a success (they resume on a re-run)
        from collections import Counter

        why = Counter(str(r.get("error")) for r in read_episodes(out / "episodes.jsonl").rows()
                      if r.get("status") != "done")
        for error, count in why.most_common(3):
            console.print(f"  {count} x {error}", highlight=False, soft_wrap=True)
        console.print(f"[red]error:[/red] {result.failed} episode(s) failed (the commonest errors "
                      "are above, all in episodes.jsonl); the same command resumes them",
                      highlight=False, soft_wrap=True)
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

    from efficienteqa.eval.tables import (
        markdown_table,
        overview_rows,
        paired_differences,
        publish_run,
        read_summaries,
        run_folders,
        write_run_report,
    )

    summaries = read_summaries(folders)
    reference = None if paired_against is None else read_summaries([paired_against])[0]
    differences = paired_differences(summaries, reference)
    for folder, summary, difference in zip(run_folders(folders), summaries, differences):
        publish_run(folder, summary, difference)
    if markdown:
        sys.stdout.write(markdown_table(summaries, differences))
        return
    single = out is None and len(folders) == 1
    target = out or (folders[0] if len(folders) == 1 else folders[0].resolve().parent / "report")
    md, page = write_run_report(summaries, target, stamp=not single)
    header, rows = overview_rows(summaries)
    table = Table()
    for i, name in enumerate(header):  # names whole, numbers right-aligned
        table.add_column(name, no_wrap=i < 2, justify="left" if i < 2 else "right")
    for row in rows:
        table.add_row(*row)
    console.print(table)
    console.print(f"markdown: {md}\nhtml:     {page}", highlight=False, soft_wrap=True)


@scenes.command("generate")
def scenes_generate(
    seed: int = typer.Option(0, help="The house seed; a seed fully determines a house."),
    out: Path = typer.Option(Path("out/scene"), help="Output folder."),
    assets: str = typer.Option(DEFAULT_ASSETS, help="'sh3d' (furniture package) or 'builtin' (boxes)."),
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
    """Download, assemble and verify model files into the cache, and make the llama.cpp
    runtime that serves them importable (built once, 4-5 min, when no wheel is cached); idempotent."""
    from efficienteqa.models.local import DEFAULT_MODEL, LOCAL_MODELS, ensure_llama_cpp, install_model

    chosen = list(LOCAL_MODELS) if all_models else (names or [DEFAULT_MODEL])
    unknown = [name for name in chosen if name not in LOCAL_MODELS]
    if unknown:  # before anything slow
        raise EfficientEQAError(f"unknown local model {unknown[0]!r}",
                                fix=f"choose one of: {', '.join(LOCAL_MODELS)}")
    # The runtime first: a missing compiler is one line before a gigabyte is downloaded.
    ensure_llama_cpp(progress=True)
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

    from efficienteqa.models.local import LOCAL_MODELS, is_installed, running

    servers = {info.name: info for info in running()}
    table = Table("model", "installed", "server")
    for name, entry in LOCAL_MODELS.items():
        info = servers.get(name)
        server = "-" if info is None else (f"{info.base_url} (pid {info.pid})"
                                           + ("" if info.healthy() else " not answering"))
        table.add_row(name, f"yes, {entry.size_mb} MB" if is_installed(name) else "no", server)
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
) -> None:
    """Render RGB-D frames with per-pixel category, colour and state labels at half size."""
    from efficienteqa.perception.pixels.dataset import parse_seeds, render_dataset

    houses = parse_seeds(seeds)
    start = time.perf_counter()
    meta = render_dataset(houses, out, frames_per_house, seed, workers=workers,
                          recolour_share=recolour_share)
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
    from efficienteqa.perception.pixels.train import TrainConfig, check_data, check_writable, train

    if steps < 1 or batch < 1 or threads < 1 or checkpoint_every < 0:
        raise EfficientEQAError("--steps, --batch and --threads must be at least 1, "
                                "--checkpoint-every at least 0")
    try:
        width_list = tuple(int(w) for w in widths.split(","))
    except ValueError:
        raise EfficientEQAError(f"cannot read --widths {widths!r}", fix="give 5 numbers such as "
                                "16,32,64,96,160") from None
    if len(width_list) != 5 or min(width_list) < 1:
        raise EfficientEQAError(f"--widths needs 5 positive numbers, got {widths!r}")
    check_data(data)
    check_writable(out)
    # DATA: the folder 'perception dataset' wrote (its houses are in the record's "data"); a
    # path on this machine would mean nothing on another. --resume and --device do not change
    # the result's recipe (the record says where it ran and whether it resumed).
    command = " ".join(["efficienteqa", "perception", "train", "--data", "DATA", "--out",
                        str(out), "--steps", str(steps), "--seed", str(seed), "--batch",
                        str(batch), "--minutes", f"{minutes:g}", "--threads", str(threads),
                        "--widths", ",".join(map(str, width_list)), "--device", device])
    record = train(data, out, TrainConfig(steps=steps, seed=seed, batch=batch, minutes=minutes,
                                          threads=threads, widths=width_list, device=device,
                                          checkpoint_every=checkpoint_every, resume=resume),
                   command=command)
    val = record["validation"] or {}
    figures = ", ".join(f"{k} {val[k]}" for k in ("pixel_accuracy", "mean_iou", "colour_accuracy",
                                                  "state_accuracy") if val.get(k) is not None)
    console.print(f"{record['steps_done']} steps in {record['minutes']:.1f} min -> {out}"
                  + (f"; validation: {figures}" if figures else ""), highlight=False,
                  soft_wrap=True)


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
) -> None:
    """Measure pixel perception against the semantic sensor on held-out houses: objects in view
    found and right per category, size and distance, recoloured objects and objects of meshes
    held out of training apart; colour, state and the floor's room type."""
    from rich.progress import Progress

    from efficienteqa.datasets.synthetic import parse_seeds
    from efficienteqa.perception.pixels.backend import PixelPerception
    from efficienteqa.perception.pixels.evaluate import (
        check_heldout,
        evaluate,
        heldout_frames,
        markdown_table,
        read_poses,
        write_scores,
    )
    from efficienteqa.records import check_writable, code_version

    try:
        houses = parse_seeds(seeds)
    except ValueError as exc:
        raise EfficientEQAError(f"cannot read the house seeds {seeds!r} ({exc})",
                                fix="give a range such as 100-129") from None
    check_heldout(houses)
    if frames_per_house < 1:
        raise EfficientEQAError("--frames-per-house must be at least 1")
    if out is not None:
        check_writable(out.parent)
    walks = read_poses(poses) if poses is not None else None
    perception = PixelPerception.load(weights)
    held_out = frozenset(perception.record.get("data", {}).get("heldout_model_keys", []))
    frames = heldout_frames(houses, frames_per_house, seed, walks, held_out)
    total = len(houses) * frames_per_house
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("frames", total=total)
        scores = evaluate(frames, perception, progress=lambda n: bar.update(task, completed=n))
    figures = scores.to_json()
    if out is not None:
        write_scores(scores, out, {"houses": seeds,
                                   "frames_per_house": frames_per_house, "seed": seed,
                                   "poses": "walks " + poses.name if poses else "training-style",
                                   "weights": str(weights or "committed"),
                                   "code_version": code_version()})
    console.print(markdown_table(figures), highlight=False, soft_wrap=True)
    console.print(f"{figures['frames']} frames of houses {seeds}; "
                  f"floor room type {figures['floor_room_type']}; median "
                  f"{figures['median_ms']} ms a frame" + (f" -> {out}" if out else ""),
                  highlight=False, soft_wrap=True)


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
    from dataclasses import replace

    from rich.progress import Progress

    from efficienteqa.perception.pixels.backend import WEIGHTS, PixelPerception
    from efficienteqa.perception.pixels.dataset import VALIDATION_SEEDS, parse_seeds
    from efficienteqa.perception.pixels.evaluate import heldout_frames
    from efficienteqa.perception.pixels.thresholds import (
        GRID,
        MIN_OBJECTS,
        choose,
        collect,
        overall,
        write_thresholds,
    )

    houses = parse_seeds(seeds)
    if houses.start not in VALIDATION_SEEDS or houses.stop - 1 not in VALIDATION_SEEDS:
        raise EfficientEQAError(f"houses {seeds} are not validation houses",
                                fix=f"choose on houses within {VALIDATION_SEEDS.start}-"
                                    f"{VALIDATION_SEEDS.stop - 1}")
    if frames_per_house < 1:
        raise EfficientEQAError("--frames-per-house must be at least 1")
    path = weights or WEIGHTS
    unthresholded = PixelPerception.load(path).classify
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("frames", total=len(houses) * frames_per_house)
        candidates = collect(heldout_frames(houses, frames_per_house, seed),
                             lambda rgb, depth: replace(unthresholded(rgb, depth),
                                                        min_confidence={}),
                             progress=lambda n: bar.update(task, completed=n))
    chosen = choose(candidates)
    for category, c in chosen.items():
        console.print(f"{category}: {c['threshold']:.2f} ({c['objects']} objects; found "
                      f"{c['recall_at_default']:.0%} -> {c['recall']:.0%}, right "
                      f"{c['precision_at_default']:.0%} -> {c['precision']:.0%})",
                      highlight=False, soft_wrap=True)
    before = overall(candidates, {})
    after = overall(candidates, {c: v["threshold"] for c, v in chosen.items()})
    console.print(f"all: found {before[0]:.1%} -> {after[0]:.1%}, right {before[1]:.1%} -> "
                  f"{after[1]:.1%} (houses {seeds}, {frames_per_house} frames each)",
                  highlight=False, soft_wrap=True)
    if write:
        about = {"houses": seeds, "frames_per_house": frames_per_house, "seed": seed,
                 "grid": list(GRID), "min_objects": MIN_OBJECTS, "criterion": "best F1",
                 "found_right_before": [round(v, 4) for v in before],
                 "found_right_after": [round(v, 4) for v in after]}
        console.print(f"recorded in {write_thresholds(path, chosen, about)}", highlight=False)


@perception.command("table")
def perception_table(
    figures: Path = typer.Argument(..., help="A JSON file written by 'perception evaluate "
                                   "--out'."),
) -> None:
    """Print the figures of a pixel-perception evaluation as the markdown table docs/perception.md
    holds (a test checks the two agree)."""
    import json

    from efficienteqa.perception.pixels.evaluate import markdown_table

    try:
        data = json.loads(figures.read_text())
    except (OSError, ValueError) as exc:
        raise EfficientEQAError(f"cannot read {figures}: {exc}") from None
    print(markdown_table(data))


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
