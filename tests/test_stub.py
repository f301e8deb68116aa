"""The deterministic stub chat model."""

import math

import numpy as np
import pytest

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import Capabilities, ChatModel, Message
from efficienteqa.models.stub import StubChatModel, StubScriptExhausted, confident_logprobs


def test_scripted_list_in_order_and_recorded():
    model: ChatModel = StubChatModel(["A", "two words"])
    first = model.chat([Message("user", "pick a door")], max_tokens=4, seed=1)
    second = model.chat([Message("system", "be brief"), Message("user", "why")], temperature=0.5)
    assert (first.text, second.text) == ("A", "two words")
    assert [r.seed for r in model.requests] == [1, None] and model.requests[0].max_tokens == 4
    assert model.requests[1].messages[0].text == "be brief"
    assert (first.prompt_tokens, first.completion_tokens) == (3, 1)
    assert (model.usage.calls, model.usage.prompt_tokens, model.usage.completion_tokens) == (2, 6, 3)
    assert first.logprobs is None and first.model == "stub" and not first.cached


def test_script_exhausted_is_clear_and_not_a_model_failure():
    model = StubChatModel(["only"])
    model.chat([Message("user", "1")])
    with pytest.raises(StubScriptExhausted, match="1 scripted replies but was called 2 times"):
        model.chat([Message("user", "2")])
    assert not issubclass(StubScriptExhausted, EfficientEQAError)


def test_callable_script_sees_messages():
    model = StubChatModel(lambda messages: messages[-1].text.upper())
    assert [model.chat([Message("user", t)]).text for t in ("a", "b", "c")] == ["A", "B", "C"]


def test_fake_logprobs():
    model = StubChatModel(["yes B"])
    tokens = model.chat([Message("user", "q")], logprobs=3).logprobs
    assert [t.token for t in tokens] == ["yes", "B"]
    assert tokens[1].top[0] == ("B", math.log(0.9)) and len(tokens[1].top) == 3
    assert math.fsum(math.exp(lp) for _, lp in tokens[1].top) == pytest.approx(1.0)
    assert confident_logprobs("x", 1)[0].top == (("x", math.log(0.9)),)


def test_custom_logprobs_and_capabilities():
    model = StubChatModel(["A"], capabilities=Capabilities(), logprob_fn=lambda text, k: [])
    assert model.chat([Message("user", "q")], logprobs=2).logprobs is None  # no capability
    with pytest.raises(EfficientEQAError, match="does not accept images"):
        model.chat([Message("user", "q", (np.zeros((2, 2, 3), np.uint8),))])
    custom = StubChatModel(["A"], logprob_fn=lambda text, k: [])
    assert custom.chat([Message("user", "q")], logprobs=2).logprobs == []
