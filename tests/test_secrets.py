"""No secret reaches Ray: ``runtime_env`` (which Ray writes in plain text to its session logs),
the other ``ray.init`` options and the objects handed to tasks hold no value of a secret-named
environment variable. A local Ray's workers still read the key, from the environment they
inherit; a run on a cluster says in one line that the nodes need it set."""

from __future__ import annotations

import logging
import pickle
import sys
from types import SimpleNamespace
from typing import Any

import pytest

from efficienteqa.eval.methods import RunSpec
from efficienteqa.eval.runner import is_secret_name, run_eval
from efficienteqa.stack import Stack
from test_eval_runner import questions, spec

FAKE_KEY = "sk-efficienteqa-test-7f3c91d2e0b84a6f"
FAKE_TOKEN = "tok-efficienteqa-test-5a0e44c1"


class Ref:
    def __init__(self, value: Any) -> None:
        self.value = value


class FakeRay(SimpleNamespace):
    """Stands in for the ``ray`` module: records what it is given, runs each task at once."""

    def __init__(self) -> None:
        super().__init__(inits=[], handed=[], on=False)

    def is_initialized(self) -> bool:
        return self.on

    def init(self, address: str | None = None, **options: Any) -> None:
        self.inits.append({"address": address, **options})
        self.on = True

    def remote(self, **options: Any) -> Any:
        def wrap(fn: Any) -> Any:
            def call(*args: Any) -> Ref:
                self.handed.append(args)
                return Ref(fn(*args))

            return SimpleNamespace(remote=call)

        return wrap

    def wait(self, refs: list, num_returns: int = 1) -> tuple[list, list]:
        return refs[:num_returns], refs[num_returns:]

    def get(self, ref: Ref) -> Any:
        return ref.value

    def shutdown(self) -> None:
        self.on = False


@pytest.fixture
def secrets(monkeypatch, tmp_path):
    """Distinctive fake secrets in the environment, beside settings the workers do need."""
    monkeypatch.setenv("OPENAI_API_KEY", FAKE_KEY)
    monkeypatch.setenv("EFFICIENTEQA_HUB_TOKEN", FAKE_TOKEN)
    monkeypatch.setenv("EFFICIENTEQA_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))


@pytest.mark.trial("4.3")
@pytest.mark.parametrize("address", [None, "ray://head.example:10001"])
def test_ray_is_given_no_secret_but_the_settings_workers_need(tmp_path, monkeypatch, secrets,
                                                              address):
    ray = FakeRay()
    monkeypatch.setitem(sys.modules, "ray", ray)
    result = run_eval(spec(), questions(3), tmp_path / "run", workers=2, address=address,
                      prepare=False)
    assert (result.ran, result.failed) == (3, 0)
    [options] = ray.inits
    assert options["address"] == address
    given = repr(options) + repr(ray.handed)
    for secret in (FAKE_KEY, FAKE_TOKEN):
        assert secret not in given
        assert secret.encode() not in pickle.dumps(ray.handed)  # what Ray would serialise
    env = options["runtime_env"]["env_vars"]
    assert not [name for name in env if is_secret_name(name)]
    assert env["EFFICIENTEQA_CACHE"] == str(tmp_path / "cache")
    assert env["XDG_CACHE_HOME"] == str(tmp_path / "xdg")
    assert "PYTHONPATH" in env


@pytest.mark.trial("N.14")
@pytest.mark.parametrize("address", [None, "ray://head.example:10001"])
def test_the_variable_named_as_the_key_reaches_no_runtime_env_whatever_its_name(
        tmp_path, monkeypatch, secrets, address):
    """Fault trial N.14: --backends.api-key-env EFFICIENTEQA_AUTH named a variable that neither
    looks secret nor is OPENAI_API_KEY, and Ray logged it with the runtime_env."""
    monkeypatch.setenv("EFFICIENTEQA_AUTH", FAKE_KEY)
    ray = FakeRay()
    monkeypatch.setitem(sys.modules, "ray", ray)
    keyed = RunSpec.of(method="eval_stubs:echo", dataset="toy", judge="openai:j@http://127.0.0.1:9/v1",
                    stack=Stack(vlm="openai:m@http://127.0.0.1:9/v1", api_key_env="EFFICIENTEQA_AUTH"))
    run_eval(keyed, questions(2), tmp_path / "run", workers=2, address=address, prepare=False)
    [options] = ray.inits
    assert FAKE_KEY not in repr(options) + repr(ray.handed)
    assert "EFFICIENTEQA_AUTH" not in options["runtime_env"]["env_vars"]
    assert "EFFICIENTEQA_CACHE" in options["runtime_env"]["env_vars"]  # the others still go


@pytest.mark.trial("4.4")
def test_a_urls_password_is_redacted_and_its_user_and_host_kept():
    from efficienteqa.redact import redact_urls, redacted

    assert redact_urls("openai:m@http://alice:pw@10.0.0.1:8000/v1") == \
        "openai:m@http://alice:***@10.0.0.1:8000/v1"
    assert redact_urls("at https://u:p@ss@h/v1/chat and http://b:q@h2?x=1 or x@y") == \
        "at https://u:***@h/v1/chat and http://b:***@h2?x=1 or x@y"  # an "@" in a password
    assert redact_urls("https://:tok@h/v1") == "https://:***@h/v1"
    for plain in ("http://h:8000/v1", "http://alice@h/v1", "local:qwen", "a:b@c"):
        assert redact_urls(plain) == plain
    assert redacted({"vlm": "http://a:b@h", "n": [1, ("http://c:d@h",)], "http://e:f@h": None}) == \
        {"vlm": "http://a:***@h", "n": [1, ["http://c:***@h"]], "http://e:***@h": None}


def test_secret_names():
    assert all(map(is_secret_name, ["OPENAI_API_KEY", "HF_TOKEN", "aws_secret_access_key",
                                    "DB_PASSWORD", "EFFICIENTEQA_HUB_TOKEN"]))
    assert not any(map(is_secret_name, ["EFFICIENTEQA_CACHE", "EFFICIENTEQA_HM_EQA",
                                        "XDG_CACHE_HOME", "PYTHONPATH"]))


def test_a_cluster_run_of_a_keyed_model_says_the_nodes_need_the_key(tmp_path, monkeypatch,
                                                                    secrets, caplog):
    monkeypatch.setitem(sys.modules, "ray", FakeRay())
    keyed = spec(stack=Stack(vlm="openai:gpt-4o"))
    with caplog.at_level(logging.WARNING, logger="efficienteqa.eval.runner"):
        run_eval(keyed, questions(1), tmp_path / "cluster", workers=2,
                 address="ray://head.example:10001", prepare=False)
    [record] = caplog.records
    message = record.getMessage()
    assert "OPENAI_API_KEY" in message and "\n" not in message and FAKE_KEY not in message
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="efficienteqa.eval.runner"):
        run_eval(keyed, questions(1), tmp_path / "local", workers=2, prepare=False)  # inherited
        run_eval(spec(), questions(1), tmp_path / "keyless", workers=2,  # local model, no key
                 address="ray://head.example:10001", prepare=False)
    assert not caplog.records
