"""The relevancy contract Sim(I_t, Q) of DESIGN 3.4 and a registry of back-ends.

A scorer compares a question with one observation: an RGB frame (image scorers: BLIP-2 ITM, CLIP,
SigLIP) or the frame's text description (text scorers: MiniLM, MiniLM calibrated to a match
probability, word overlap). Higher means more relevant; each back-end documents its range.
Back-ends are imported only when built, so importing this module costs nothing.

The image scorers load Hugging Face weights: from the cache, from a local folder
(``--backends.relevancy-weights DIR``) or, only when allowed (``--backends.allow-download``),
from the Hub; they run on ``--backends.device`` (``resolve_device``: "auto" is the GPU torch
sees, else the CPU, and half precision on a GPU).
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Sequence
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np

from efficienteqa.errors import EfficientEQAError
from efficienteqa.registry import Registry

Modality = Literal["image", "text"]


@runtime_checkable
class RelevancyScorer(Protocol):
    name: str  # model id or back-end name, recorded with every result
    modality: Modality  # what an observation must be: an RGB array or its description

    def score(self, question: str, *, image: np.ndarray | None = None,
              text: str | None = None) -> float:
        """Sim of one observation: ``image`` (H, W, 3) uint8 RGB or ``text``, per ``modality``.
        Back-ends that subclass this protocol inherit this batch-of-one default."""
        return float(self.score_many(question, [observation_of(self, image, text)])[0])

    def score_many(self, question: str, items: Sequence[np.ndarray | str]) -> np.ndarray:
        """Sims (N,) float64 of N observations, in one batch where the back-end allows."""
        ...


def observation_of(scorer: RelevancyScorer, image: np.ndarray | None, text: str | None
                   ) -> np.ndarray | str:
    """The argument of ``score`` that matches the scorer's modality, or a clear ValueError."""
    item = image if scorer.modality == "image" else text
    if item is None:
        raise ValueError(f"{scorer.name} scores {scorer.modality}s: pass {scorer.modality}=...")
    return item


def check_question(question: str) -> str:
    if not question or not question.strip():
        raise EfficientEQAError("empty question", fix="pass the question text to score against")
    return question.strip()


def require(module: str, extra: str) -> Any:
    """Import an optional dependency, or fail with one line naming the extra to install."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise EfficientEQAError(f"this relevancy scorer needs the Python package {module!r}",
                                fix=f"pip install 'efficienteqa[{extra}]'") from exc


def weights_missing(model_id: str, exc: BaseException) -> EfficientEQAError:
    """One line saying the weights of ``model_id`` are not on this machine and how to get them:
    the command-line options that give them."""
    del exc  # the library's own message spans many lines; the cause stays chained
    return EfficientEQAError(
        f"weights of {model_id!r} are not in the Hugging Face cache or at that path",
        fix=f"run `hf download {model_id} --local-dir DIR` on a machine with internet and pass "
            "--backends.relevancy-weights DIR, or let it download with --backends.allow-download")


DEVICES = "auto, cpu, cuda or cuda:N"
_DEVICE = re.compile(r"auto|cpu|cuda(?::[0-9]+)?")


def check_device(device: str) -> str:
    """``device`` lower-cased, or one clear error when it names no device a scorer runs on
    (no torch needed: checked before anything slow)."""
    name = (device or "auto").strip().lower()
    if not _DEVICE.fullmatch(name):
        raise EfficientEQAError(f"unknown device {device!r}", fix=f"use --device {DEVICES}")
    return name


def resolve_device(device: str = "auto", dtype: str | None = None) -> tuple[str, str | None]:
    """The torch device and dtype an image scorer runs with. ``device``: "auto" (the GPU when
    torch sees one, else the CPU), "cpu", "cuda" or "cuda:N". ``dtype`` None: "float16" on a
    GPU (BLIP-2 ViT-g in float32 needs twice the memory and time), the checkpoint's own on the
    CPU (half precision there is slow or unsupported). A GPU asked for and not seen is a clear
    error, not a silent CPU run."""
    name = check_device(device)
    torch = require("torch", "vision")
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    elif name.startswith("cuda"):
        index = int(name.partition(":")[2] or 0)
        if not torch.cuda.is_available() or index >= torch.cuda.device_count():
            raise EfficientEQAError(f"torch sees no GPU {name!r} on this machine",
                                    fix="use --device cpu (or auto), or install a CUDA build "
                                        "of torch")
    if dtype is None and name.startswith("cuda"):
        dtype = "float16"
    return name, dtype


SCORERS: Registry[RelevancyScorer] = Registry("relevancy scorer")
SCORERS.register("minilm", "efficienteqa.relevancy.text:MiniLMScorer.from_package")
SCORERS.register("minilm-match", "efficienteqa.relevancy.text:MiniLMMatchScorer.from_package")
SCORERS.register("overlap", "efficienteqa.relevancy.text:WordOverlapScorer")
SCORERS.register("blip2-itm", "efficienteqa.relevancy.blip2:Blip2ItmScorer.from_pretrained")
SCORERS.register("clip", "efficienteqa.relevancy.clip:ClipScorer.from_pretrained", family="clip")
SCORERS.register("siglip", "efficienteqa.relevancy.clip:ClipScorer.from_pretrained", family="siglip")
DEFAULT_KIND = "minilm"


def scorer_kinds() -> tuple[str, ...]:
    return SCORERS.names()


def make_scorer(kind: str = DEFAULT_KIND, **kwargs: Any) -> RelevancyScorer:
    """Build a scorer by name: "minilm" (offline default), "minilm-match" (MiniLM calibrated to a
    match probability), "overlap" (deterministic, no model),
    "blip2-itm" (the paper's), "clip", "siglip". ``kwargs`` go to the back-end's factory
    (e.g. ``model_id_or_path=`` a local folder, ``device=`` as ``resolve_device`` reads it,
    ``allow_download=``)."""
    return SCORERS.build(kind, **kwargs)
