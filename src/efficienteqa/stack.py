"""Build an agent from back-end names: the one place that turns configuration into objects.

The default stack is the offline one (DESIGN 5): semantic-sensor perception, Qwen2.5-Coder-1.5B on
the local llama.cpp server, MiniLM text relevancy. ``--backends.vlm openai:gpt-4o --backends.perception rgb
--backends.relevancy blip2-itm`` is the paper's stack, by configuration alone.
"""

from __future__ import annotations

import functools
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from efficienteqa.agent import Agent, AgentConfig
from efficienteqa.answer.rag import RagAnswerer
from efficienteqa.config.backends import IMAGE_FORMAT_AUTO, Stack
from efficienteqa.envs.base import Environment, looks_real
from efficienteqa.errors import EfficientEQAError
from efficienteqa.explore.module import SemanticScorer
from efficienteqa.explore.text_scorers import (
    LOGIT_WEIGHTS,
    DirectionScorer,
    LogitDirections,
)
from efficienteqa.explore.vlm_scorer import VLMScorer
from efficienteqa.models.backends import (
    CHAT_BACKENDS,
    ChatBackend,
    build_chat_model,
    read_capabilities,
)
from efficienteqa.models.base import ChatModel
from efficienteqa.models.images import IMAGE_DETAILS, IMAGE_FORMATS
from efficienteqa.models.recording import RecordingChatModel
from efficienteqa.perception.base import Perception
from efficienteqa.perception.sightings import ModelSightings
from efficienteqa.reading.adjacency import RoomAdjacency
from efficienteqa.reading.aliases import AliasResolver
from efficienteqa.reading.reader import ModelReader
from efficienteqa.reading.target import TargetReading
from efficienteqa.registry import Registry
from efficienteqa.relevancy.base import SCORERS, RelevancyScorer, check_device, make_scorer
from efficienteqa.stop.gate import AnswerGate, ModelGate, RulesGate, SightingsGate
from efficienteqa.vc.grouping import Grouper, LLMGrouper, RuleGrouper
from efficienteqa.vc.parse import M

MINILM_KINDS = ("minilm", "minilm-match")


def parse_vlm(spec: str, images: bool, cache: bool = True,
              temperature: float | None = None, *, timeout_s: float | None = None,
              retries: int | None = None, api_key_env: str | None = None,
              image_format: str | None = None, image_max_side: int | None = None,
              image_detail: str | None = None, capabilities: str | None = None,
              flag: str = "--backends.vlm") -> ChatBackend:
    """The back-end of a VLM spec and the server options (None, and an ``image_format`` of
    ``IMAGE_FORMAT_AUTO``: ``ChatBackend``'s default); a bad value fails here, in one line,
    before anything is built. ``flag``: the option that named it, for its errors ("--judge")."""
    kind, _, rest = spec.partition(":")
    model, _, url = rest.partition("@")
    if kind not in CHAT_BACKENDS or not model:
        raise EfficientEQAError(f"cannot read {flag} {spec!r}",
                                fix="use local:MODEL or openai:MODEL[@BASE_URL], "
                                    "e.g. local:qwen2.5-coder-1.5b or openai:gpt-4o")
    if temperature is not None and not 0.0 <= temperature <= 2.0:
        raise EfficientEQAError(f"temperature {temperature} is outside 0-2",
                                fix="use e.g. --backends.temperature 1 (the paper's) or leave it out (0)")
    if timeout_s is not None and not (timeout_s > 0 and math.isfinite(timeout_s)):
        raise EfficientEQAError(f"timeout {timeout_s} s is not a positive number",
                                fix="use e.g. --backends.timeout-s 60")
    if retries is not None and retries < 0:
        raise EfficientEQAError(f"retries {retries} is negative", fix="use --backends.retries 0 or more")
    if image_format == IMAGE_FORMAT_AUTO:
        image_format = None
    if image_format is not None and image_format not in IMAGE_FORMATS:
        choices = " | ".join((IMAGE_FORMAT_AUTO, *IMAGE_FORMATS))
        raise EfficientEQAError(f"unknown image format {image_format!r}",
                                fix=f"use --backends.image-format {choices}")
    if image_detail is not None and image_detail not in IMAGE_DETAILS:
        raise EfficientEQAError(f"unknown image detail {image_detail!r}",
                                fix=f"use --backends.image-detail {', '.join(IMAGE_DETAILS)}")
    if image_max_side is not None and image_max_side < 16:
        raise EfficientEQAError(f"image max side {image_max_side} px is too small",
                                fix="use --backends.image-max-side 16 or more (e.g. 512)")
    if capabilities is not None:
        if kind != "openai":
            raise EfficientEQAError(f"--backends.capabilities describes an openai: server; {spec} is the "
                                    "embedded one, whose capabilities are known",
                                    fix="leave out --backends.capabilities, or use --backends.vlm "
                                        "openai:MODEL@URL")
        read_capabilities(Path(capabilities), images)  # a bad file fails here, before the work
    if kind == "local" and not url:  # its server starts on demand: $EFFICIENTEQA_SERVER_IDLE_S
        from efficienteqa.models.local.keeper import idle_seconds

        idle_seconds()  # a bad value fails here, not after the scene is built
    options: dict[str, Any] = {"timeout_s": timeout_s, "retries": retries,
                               "api_key_env": api_key_env, "image_format": image_format,
                               "image_max_side": image_max_side, "image_detail": image_detail,
                               "capabilities_file": capabilities}
    return ChatBackend(kind=kind, model=model, base_url=url or None, images=images, cache=cache,
                       temperature=temperature, flag=flag,
                       **{k: v for k, v in options.items() if v is not None})


# Relevancy scorers that read a frame's description, and the ones that need no weights of their
# own: known by name, so a stack that cannot work is refused before any scene is built.
TEXT_RELEVANCY = ("minilm", "minilm-match", "overlap")
_HUB_ID = re.compile(r"[\w.-]+(?:/[\w.-]+)?")  # a Hugging Face model id: NAME or OWNER/NAME
IMAGE_RELEVANCY = ("blip2-itm", "clip", "siglip")


def default_relevancy(perception: str, weights: str | None = None) -> str:
    """The relevancy scorer of a run that names none: MiniLM over the text descriptions, and
    over images BLIP-2 ITM (the paper's) when its weights are on this machine (``weights``, a
    local copy, or the Hugging Face cache), else ``vlm-match``, the VLM judging each frame."""
    if perception != "rgb":
        return "minilm"
    from efficienteqa.relevancy.blip2 import DEFAULT_MODEL_ID

    return "blip2-itm" if weights or _in_hf_cache(DEFAULT_MODEL_ID) else "vlm-match"


def _in_hf_cache(model_id: str) -> bool:
    try:
        from huggingface_hub import try_to_load_from_cache
    except ImportError:
        return False
    return isinstance(try_to_load_from_cache(model_id, "config.json"), str)


def check_stack(stack: Stack) -> None:
    """One clear error for a stack that cannot run, before anything slow: an unknown perception
    or relevancy scorer, or a text relevancy scorer with a perception that gives images."""
    if stack.perception not in PERCEPTIONS:
        raise EfficientEQAError(f"unknown perception {stack.perception!r}",
                                fix=f"use one of {', '.join(PERCEPTIONS.names())}")
    known = (*SCORERS.names(), "vlm-match")
    if stack.relevancy not in known:
        raise EfficientEQAError(f"unknown relevancy scorer {stack.relevancy!r}",
                                fix=f"use one of {', '.join(known)}")
    check_device(stack.device)  # a misspelt device: now, not once the scene is open
    if stack.relevancy in IMAGE_RELEVANCY:  # a GPU that is not here: now, not per episode
        from efficienteqa.relevancy.base import resolve_device

        resolve_device(stack.device)
    if stack.relevancy_weights is not None:
        check_relevancy_weights(stack.relevancy, stack.relevancy_weights)
    SIGHTINGS.check(stack.sightings)
    if stack.sightings == "perception" and stack.perception == "rgb":
        raise EfficientEQAError("rgb perception gives no sightings of its own",
                                fix="use --backends.sightings model (one call to the VLM per step)")
    if stack.relevancy in TEXT_RELEVANCY and stack.perception == "rgb":
        raise EfficientEQAError(
            f"relevancy scorer {stack.relevancy!r} reads text, but --backends.perception rgb gives images",
            fix="use --backends.relevancy vlm-match (the VLM judges each frame) or blip2-itm (BLIP-2 "
                "weights), or --backends.perception semantic")


def check_relevancy_weights(kind: str, weights: str) -> None:
    """One line, before torch or any model loads, when ``weights`` names no folder a scorer of
    ``kind`` could load: MiniLM reads only a local sentence-transformers folder (a missing one
    failed after some 16 s of loading, in a Hugging Face traceback); an image scorer also takes
    a Hub model id ("Salesforce/blip2-itm-vit-g"), which its loader looks up."""
    if kind not in (*MINILM_KINDS, *IMAGE_RELEVANCY) or Path(weights).is_dir():
        return
    if kind in IMAGE_RELEVANCY and not Path(weights).exists() and _HUB_ID.fullmatch(weights):
        return
    raise EfficientEQAError(f"relevancy weights {weights!r} are not a folder",
                            fix="give the folder that holds the relevancy model's weights, or "
                                "leave out --backends.relevancy-weights"
                                + (" for the installed MiniLM" if kind in MINILM_KINDS else ""))


def _semantic(env: Environment, **_: Any) -> Perception:
    labels = getattr(env, "scene_labels", None)
    if labels is None:
        raise EfficientEQAError(
            f"semantic-sensor perception needs object labels, which {type(env).__name__} "
            "does not give", fix="use --backends.perception rgb with an image VLM")
    from efficienteqa.perception.semantic import SemanticPerception

    return SemanticPerception(labels())


def _rgb(**_: Any) -> Perception:
    from efficienteqa.perception.image import ImagePerception

    return ImagePerception()


def _pixels(**_: Any) -> Perception:
    from efficienteqa.perception.pixels.backend import PixelPerception

    return PixelPerception.load(room_votes=True)  # the agent resets them every episode


PERCEPTIONS: Registry[Perception] = Registry("perception")
PERCEPTIONS.register("semantic", _semantic)
PERCEPTIONS.register("rgb", _rgb)
PERCEPTIONS.register("pixels", _pixels)

GROUPINGS: Registry[Grouper] = Registry("grouping")
GROUPINGS.register("rules", lambda **_: RuleGrouper())
GROUPINGS.register("llm", lambda model, relevancy: LLMGrouper(
    model, embedder=getattr(relevancy, "embed", None)))


# Semantic scorers of the explore module (DESIGN 3.3, 8). "vlm" is the paper's:
# the agent's own model with verbalized confidence (or token probabilities when the config asks
# for them). "direction-logit" reads the semantic perception's direction texts without a model;
# the direction experiment (experiments/direction_bench.py) chose it for the offline stack, whose
# 1.5B text model gives the same confidences at every step, over the baselines it keeps.
EXPLORE_SCORERS: Registry[SemanticScorer] = Registry("explore scorer")
EXPLORE_SCORERS.register("vlm", lambda model, perception, config: VLMScorer(
    model, perception, confidence=config.answer.confidence))
EXPLORE_SCORERS.register("direction-logit", lambda perception, **_: DirectionScorer(
    LogitDirections(LOGIT_WEIGHTS, name="direction-logit"), perception))
OFFLINE_EXPLORE_SCORER = "direction-logit"
EXPLORE_SCORER_LABELS = {
    "direction-logit": "direction-logit (no model: features of the direction texts, weights "
                       "fitted on training houses)",
}


def explore_scorer_name(stack: Stack, perception: Perception, config: AgentConfig) -> str:
    """The explore scorer a stack uses: its ``explore_scorer``, or for "auto" the VLM's when it
    reads images or token probabilities are asked for (the white-box baseline), else
    ``OFFLINE_EXPLORE_SCORER``. A text scorer needs text directions."""
    name = stack.explore_scorer
    if name == "auto":
        text = perception.modality == "text" and config.answer.confidence != "token"
        return OFFLINE_EXPLORE_SCORER if text else "vlm"
    if name not in EXPLORE_SCORERS:
        raise EfficientEQAError(f"unknown explore scorer {name!r}",
                                fix=f"use auto or one of {', '.join(EXPLORE_SCORERS.names())}")
    if name != "vlm" and perception.modality != "text":
        raise EfficientEQAError(f"explore scorer {name!r} reads direction texts, which "
                                f"{perception.name} perception does not give",
                                fix="use --backends.perception semantic, or --backends.explore-scorer vlm")
    return name


def explore_scorer_label(name: str, model: ChatModel, config: AgentConfig) -> str:
    """What the back-ends record: the scorer and where its values come from."""
    if name == "vlm":
        how = "token probabilities" if config.answer.confidence == "token" else "verbalized confidence"
        return f"vlm ({how} of {model.name})"
    return EXPLORE_SCORER_LABELS.get(name, name)


ANSWER_LABELS = {"direct": "direct (one hinted answer, confidence its token probability)",
                 "paper": "paper (M verbalized guesses, grouped; DESIGN 3.5)"}


def answer_name(config: AgentConfig, model: ChatModel) -> str:
    """How the agent answers: ``config.answer.answer``, or for "auto" the direct answer when the model
    gives logprobs and the answer reads retrieved frames, else the paper's. ExploreEQA's
    answer at every step (``answer_at="best-step"``) is always the paper's."""
    if config.answer.answer_at != "retrieval":
        if config.answer.answer == "direct":
            raise EfficientEQAError("the direct answer reads the retrieved frames, and this "
                                    "method answers at every step", fix="use --answer.answer paper")
        return "paper"
    if config.answer.answer == "auto":
        return "direct" if model.capabilities.logprobs else "paper"
    return config.answer.answer


def answer_label(answer: str, config: AgentConfig, model: ChatModel) -> str:
    """The record's name of the answer, saying when the paper's answer stands in for the direct
    one because the server gives no token probabilities (a probed capability)."""
    label = ANSWER_LABELS[answer]
    if answer == "paper" and config.answer.answer == "auto" and config.answer.answer_at == "retrieval" \
            and not model.capabilities.logprobs:
        label += f"; fallback: {model.name} gives no token probabilities"
    return label


def build_perception(name: str, env: Environment) -> Perception:
    return PERCEPTIONS.build(name, env=env)


def build_grouper(name: str, model: ChatModel, relevancy: RelevancyScorer) -> Grouper:
    return GROUPINGS.build(name, model=model, relevancy=relevancy)


def _own_or_model(perception: Perception, model: ChatModel, **_: Any) -> Perception:
    return perception if hasattr(perception, "sightings") else ModelSightings(perception, model)


# Where the steering and the sightings gate learn what a frame shows (``Stack.sightings``): the
# perception's own, or one call per step to the chat model (``perception.sightings``); "auto":
# the perception's own where it has them (semantic, pixels), else the model's (rgb). A factory
# gets the perception, the (recorded) chat model and the environment.
SIGHTINGS: Registry[Perception] = Registry("sightings source")
SIGHTINGS.register("auto", _own_or_model)
SIGHTINGS.register("perception", lambda perception, **_: perception)
SIGHTINGS.register("model", lambda perception, model, **_: ModelSightings(perception, model))


def sightings_label(perception: Perception) -> str:
    """What the record says of where the sightings come from."""
    if not isinstance(perception, ModelSightings):
        return "perception" if hasattr(perception, "sightings") else "none"
    return (f"model (one call per step to {perception.model.name}, reading "
            f"{'the image' if perception.images else 'the description'})")


GATE_LABELS = {"none": "none",
               "rules": "rules (the question's target in the frame's description)",
               "sightings": "sightings (the question's target in the model's sightings)",
               "model": "model (one yes/no call to {model} on a flagged frame)"}


def build_gate(name: str, perception: Perception, model: ChatModel,
               instances: bool = True) -> AnswerGate | None:
    """The answerability gate ``name`` (stop.gate.GATES): None for "none"; "auto" is "rules"
    where the perception describes objects, "sightings" where it gives sightings only (a VLM's),
    else "model". ``instances``: the rules and sightings gates read count groups from the
    perception's instance map (``StopConfig.count_from``)."""
    if name == "none":
        return None
    sights = hasattr(perception, "sightings")
    describes = hasattr(perception, "describe") and sights
    if name == "auto":
        name = "rules" if describes else "sightings" if sights else "model"
    reads = {"sightings": (sights, "sightings", "--backends.sightings model, or --stop.gate model"),
             "rules": (describes, "object descriptions",
                       "--stop.gate model (one yes/no call to the VLM)")}
    if name in reads:
        able, what, fix = reads[name]
        if not able:
            raise EfficientEQAError(f"the {name} gate reads {what}, which {perception.name} "
                                    "perception does not give", fix=f"use {fix}")
        gate = SightingsGate if name == "sightings" else RulesGate
        return gate(perception, instances)  # type: ignore[arg-type]
    from efficienteqa.relevancy.vlm_match import VLMMatchScorer

    return ModelGate(VLMMatchScorer(model, perception.modality))


@functools.cache
def build_relevancy(kind: str, device: str = "auto", weights: str | None = None,
                    allow_download: bool = False) -> RelevancyScorer:
    """One scorer per kind (and options) and process: loading a model takes seconds, and an
    evaluation runs many episodes in each worker. The image scorers load ``weights`` (a local
    folder; None: the default model from the Hugging Face cache, or downloaded when
    ``allow_download``) onto ``device`` (``relevancy.base.resolve_device``); MiniLM reads
    ``weights`` as its sentence-transformers folder and stays on the CPU unless a device is named."""
    if kind in IMAGE_RELEVANCY:
        return make_scorer(kind, model_id_or_path=weights, device=device,
                           allow_download=allow_download)
    if kind in MINILM_KINDS:
        # One torch thread is the fastest for a few short texts on a small busy CPU (relevancy.text).
        options: dict[str, Any] = {"path": weights} if weights else {}
        if device != "auto":
            from efficienteqa.relevancy.base import resolve_device

            options["device"] = resolve_device(device)[0]
        return make_scorer(kind, num_threads=1, **options)
    return make_scorer(kind)


def perception_vocabulary(perception: Perception) -> tuple[str, ...]:
    """The object categories ``perception`` can name (reading.aliases): the pixel network's
    classes (its weights' vocabulary, less void, wall and floors), else the scene's labels'
    categories (``categories()`` where the labels give it, else their id -> label table)."""
    if perception.name == "pixels":
        import json

        from efficienteqa.perception.pixels.backend import WEIGHTS
        from efficienteqa.perception.pixels.net import metadata_path

        names = json.loads(metadata_path(WEIGHTS).read_text())["vocabulary"]["categories"]
        return tuple(c for c in names if c not in ("void", "wall") and ":" not in c)
    labels = getattr(perception, "labels", None)
    if callable(getattr(labels, "categories", None)):
        return tuple(labels.categories())  # type: ignore[union-attr]
    table = getattr(labels, "_labels", None)  # HouseLabels, HabitatLabels: id -> ObjectLabel
    return tuple(sorted({o.category for o in table.values()})) if isinstance(table, dict) else ()


def build_reading(config: AgentConfig, perception: Perception, model: ChatModel,
                  relevancy: RelevancyScorer) -> TargetReading | None:
    """How the agent reads the question's target (``AgentConfig.reading``/``matching``); None
    for the rules and the words alone (no call, nothing to load), unless the steering asks
    for the rooms next to the named one (``TargetConfig.near_rooms``)."""
    near = config.explore.steering == "target" and config.explore.target_config().near_rooms
    if (config.explore.reading, config.explore.matching) == ("rules", "words") and not near:
        return None
    reader = ModelReader(model) if config.explore.reading != "rules" else None
    resolver = None
    if config.explore.matching == "meaning":  # MiniLM's sentence embeddings, loaded offline
        embed = getattr(relevancy, "embed", None) or build_relevancy("minilm").embed  # type: ignore[attr-defined]
        resolver = AliasResolver(embed, model)
    return TargetReading(config.explore.reading, config.explore.matching, reader, resolver,
                         perception_vocabulary(perception),
                         RoomAdjacency(model) if near else None)


@dataclass
class BuiltAgent:
    agent: Agent
    model: RecordingChatModel
    backends: dict[str, Any]


@functools.cache
def say_once(note: str) -> None:
    """``note`` on stderr, once a process (an evaluation builds an agent per episode)."""
    print(note, file=sys.stderr, flush=True)


def build_agent(env: Environment, stack: Stack, config: AgentConfig, environment: str,
                model: ChatModel | None = None, relevancy: RelevancyScorer | None = None
                ) -> BuiltAgent:
    """``environment`` names the scene back-end for the record; ``model``/``relevancy`` replace
    the configured ones (tests pass stubs)."""
    perception = build_perception(stack.perception, env)
    if perception.name == "pixels" and looks_real(env):
        from efficienteqa.perception.pixels.backend import REAL_FRAMES_NOTE

        say_once(REAL_FRAMES_NOTE)
    vlm_backend = stack.vlm if model is None else "injected"
    if model is None:
        model = build_chat_model(parse_vlm(stack.vlm, images=perception.modality == "image",
                                           cache=stack.cache, temperature=stack.temperature,
                                           **stack.server_options()))
    if perception.modality == "image" and not model.capabilities.images:
        raise EfficientEQAError(f"model {model.name!r} cannot read images",
                                fix="use --backends.perception semantic, or an image VLM such as "
                                    "--backends.vlm openai:gpt-4o")
    recorder = RecordingChatModel(model)
    perception = SIGHTINGS.build(stack.sightings, perception=perception, model=recorder, env=env)
    if relevancy is None and stack.relevancy == "vlm-match":  # the agent's own model as ITM
        from efficienteqa.relevancy.vlm_match import VLMMatchScorer

        relevancy = VLMMatchScorer(recorder, perception.modality)
    relevancy = relevancy or build_relevancy(stack.relevancy, stack.device,
                                             stack.relevancy_weights, stack.allow_download)
    scorer_name = explore_scorer_name(stack, perception, config)
    scorer = (EXPLORE_SCORERS.build(scorer_name, model=recorder, perception=perception,
                                    config=config) if config.explore.explorer == "sfe" else None)
    answer = answer_name(config, model)
    if config.answer.confidence == "token" or answer == "direct":
        from efficienteqa.vc.logprobs import require_logprobs

        require_logprobs(model)
    # Answering every step (ExploreEQA) asks for one answer per frame, not M.
    m = 1 if config.answer.answer_at == "best-step" else M
    answerer = RagAnswerer(recorder, build_grouper(stack.grouping, recorder, relevancy), m=m,
                           confidence=config.answer.confidence, direct=answer == "direct",
                           probability=config.answer.answer_probability,
                           token_prompt=config.answer.token_answer)
    gate = build_gate(config.stop.gate, perception, recorder,
                      instances=config.stop.count_from == "instances")
    agent = Agent(perception, scorer, relevancy, answerer, config, exchanges=recorder, gate=gate,
                  reading=build_reading(config, perception, recorder, relevancy))
    backends = {"environment": environment, "perception": perception.name, "vlm": model.name,
                "vlm_backend": vlm_backend,
                "relevancy": relevancy.name, "grouping": stack.grouping,
                "explore_scorer": (explore_scorer_label(scorer_name, model, config)
                                   if scorer is not None else None),
                "answer": answer_label(answer, config, model), "judge": None,
                "capabilities": model.capabilities.to_dict(),
                "sightings": sightings_label(perception),
                "gate": GATE_LABELS[gate.name if gate is not None else "none"].format(
                    model=model.name)}
    return BuiltAgent(agent, recorder, backends)
