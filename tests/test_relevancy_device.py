"""The image relevancy scorers' device, local weights and downloads, from the
command line (``--device``, ``--relevancy-weights``, ``--allow-download``) to the model.

No real weights exist on this machine: a tiny random BLIP-2 saved to a folder stands in for a
local copy, and loaders are replaced where a GPU or the Hub would be needed."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

from efficienteqa.errors import EfficientEQAError
from efficienteqa.relevancy.base import make_scorer, resolve_device
from efficienteqa.stack import Stack, build_relevancy
from test_relevancy import QUESTION, blip2, images, torch  # noqa: F401 - fixtures


@pytest.fixture
def gpus(monkeypatch, torch):  # noqa: F811
    """torch sees two GPUs."""
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 2)


@pytest.fixture(autouse=True)
def fresh_scorers():
    build_relevancy.cache_clear()
    yield
    build_relevancy.cache_clear()


def test_auto_is_the_cpu_without_a_gpu(monkeypatch, torch):  # noqa: F811
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert resolve_device("auto") == ("cpu", None)
    assert resolve_device("cpu") == ("cpu", None)
    with pytest.raises(EfficientEQAError) as err:
        resolve_device("cuda")
    assert "--device cpu" in err.value.fix


def test_auto_is_the_gpu_in_half_precision(gpus):
    assert resolve_device("auto") == ("cuda", "float16")
    assert resolve_device("cuda:1") == ("cuda:1", "float16")
    assert resolve_device("cuda", "float32") == ("cuda", "float32")
    assert resolve_device("cpu") == ("cpu", None)
    for bad in ("cuda:2", "gpu", "cuda:x"):
        with pytest.raises(EfficientEQAError) as err:
            resolve_device(bad)
        assert "--device" in err.value.fix and "\n" not in str(err.value)


@pytest.mark.parametrize("kind", ["blip2-itm", "clip", "siglip"])
def test_missing_weights_name_the_command_line_fixes(torch, kind):  # noqa: F811
    with pytest.raises(EfficientEQAError) as err:
        make_scorer(kind, model_id_or_path="efficienteqa-tests/not-a-cached-model", device="cpu")
    fix = err.value.fix
    assert "--backends.relevancy-weights" in fix and "--backends.allow-download" in fix
    assert "allow_download=True" not in fix  # a keyword no command line can give


class _FakeModel:
    """What ``from_pretrained`` returns: records where it was moved."""

    def __init__(self) -> None:
        self.moved_to: list[str] = []

    def to(self, device):
        self.moved_to.append(device)
        return self

    def eval(self):
        return self


def _fake_loader(calls: list, result):
    def load(path, **kwargs):
        calls.append((path, kwargs))
        return result
    return SimpleNamespace(from_pretrained=load)


@pytest.mark.parametrize("kind, model_cls, processor_cls", [
    ("blip2-itm", "Blip2ForImageTextRetrieval", "Blip2Processor"),
    ("clip", "AutoModel", "AutoProcessor"),
    ("siglip", "AutoModel", "AutoProcessor")])
def test_the_device_weights_and_download_reach_the_model(gpus, torch, monkeypatch, kind,  # noqa: F811
                                                         model_cls, processor_cls):
    """``Stack`` -> ``build_relevancy`` -> ``make_scorer`` -> the loader: a GPU seen by torch
    takes the model in float16, from the folder given, downloading only when allowed."""
    import transformers

    model, model_calls, processor_calls = _FakeModel(), [], []
    monkeypatch.setattr(transformers, model_cls, _fake_loader(model_calls, model))
    monkeypatch.setattr(transformers, processor_cls, _fake_loader(processor_calls, object()))
    stack = Stack(perception="rgb", relevancy=kind, device="auto",
                  relevancy_weights="/weights/copy", allow_download=True)
    scorer = build_relevancy(stack.relevancy, stack.device, stack.relevancy_weights,
                             stack.allow_download)
    assert scorer.name == "/weights/copy" and model.moved_to == ["cuda"]
    (path, kwargs), = model_calls
    assert path == "/weights/copy" and kwargs["dtype"] == torch.float16
    assert kwargs["local_files_only"] is False
    assert processor_calls[0][0] == "/weights/copy"
    build_relevancy.cache_clear()
    build_relevancy(kind, "cuda:1")  # the default model, from the cache only
    path, kwargs = model_calls[-1]
    assert path != "/weights/copy" and kwargs["local_files_only"] is True
    assert model.moved_to[-1] == "cuda:1"


def test_a_local_weights_folder_is_loaded_on_the_cpu(blip2, images, tmp_path, torch):  # noqa: F811
    """A BLIP-2 ITM saved to a folder (what ``hf download --local-dir`` gives) is scored from
    ``--relevancy-weights DIR``, and gives the scores of the model saved."""
    folder = tmp_path / "blip2-copy"
    blip2.model.save_pretrained(folder)
    blip2.processor.save_pretrained(folder)
    scorer = build_relevancy("blip2-itm", "cpu", str(folder))
    assert scorer.name == str(folder)
    assert next(scorer.model.parameters()).device.type == "cpu"
    assert scorer.score_many(QUESTION, images) == pytest.approx(
        blip2.score_many(QUESTION, images), abs=1e-5)
    assert np.all(scorer.score_many(QUESTION, images) >= 0)


@pytest.mark.parametrize("command", ["ask", "eval"])
def test_the_options_reach_the_stack(command, monkeypatch, tmp_path):
    """``--device``, ``--relevancy-weights`` and ``--allow-download`` on ``ask`` and ``eval``
    become the run's ``Stack`` (and so ``build_relevancy``'s arguments); left out, the defaults."""
    import efficienteqa.ask
    import efficienteqa.eval.runner
    import efficienteqa.scenes
    from efficienteqa import cli

    seen: list[Stack] = []

    class Stop(Exception):
        pass

    def fake_ask(*args, run, **kwargs):
        seen.append(run.backends)
        raise Stop

    def fake_run_eval(spec, *args, **kwargs):
        seen.append(spec.stack)
        raise Stop

    monkeypatch.setattr("efficienteqa.relevancy.base.resolve_device",  # no GPU needed here
                        lambda device="auto", dtype=None: (device, dtype))
    monkeypatch.setattr(efficienteqa.ask, "ask", fake_ask)
    monkeypatch.setattr(efficienteqa.eval.runner, "run_eval", fake_run_eval)
    monkeypatch.setattr(efficienteqa.scenes, "open_scene", lambda *a, **k: SimpleNamespace(
        env=SimpleNamespace(close=lambda: None), note=""))
    head = (["ask", "Where is the sofa?", "--max-steps", "3"] if command == "ask"
            else ["eval", "--limit", "1"])
    given = ["--relevancy", "blip2-itm", "--perception", "rgb", "--vlm", "openai:gpt-4o",
             "--device", "cuda:1", "--relevancy-weights", str(tmp_path), "--allow-download"]
    for options, expected in ((given, ("cuda:1", str(tmp_path), True)),
                              ([], ("auto", None, False))):
        result = CliRunner().invoke(cli.app, [*head, *options, "--out", str(tmp_path / "out")],
                                    env={"OPENAI_API_KEY": "sk-test"})
        assert isinstance(result.exception, Stop), result.output
        stack = seen.pop()  # left out, a setting is None: build_agent reads it as the default
        assert (stack.device or "auto", stack.relevancy_weights,
                bool(stack.allow_download)) == expected


def test_a_gpu_that_is_not_here_is_refused_before_the_work():
    """Checked with the stack, not when the scorer is built in each episode."""
    from efficienteqa.stack import Stack, check_stack

    if pytest.importorskip("torch").cuda.is_available():
        pytest.skip("this machine has a GPU")
    with pytest.raises(EfficientEQAError, match="torch sees no GPU"):
        check_stack(Stack(perception="rgb", relevancy="blip2-itm", device="cuda:0"))
    check_stack(Stack(perception="rgb", relevancy="vlm-match", device="cuda:0"))  # no model
