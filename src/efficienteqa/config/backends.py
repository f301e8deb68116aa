"""Which back-ends an episode uses: ``Stack``, the ``backends`` section of a run's configuration
(``config.run.RunConfig``). Names only, no objects: ``stack.py`` builds them. Light to import, so
the CLI can make its options from the fields without loading a model back-end.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from efficienteqa.config.knobs import knob
from efficienteqa.models.local.weights import DEFAULT_MODEL

# The image format that follows the server: ChatBackend's own per-kind choice (jpeg for openai:
# servers, png for the local one).
IMAGE_FORMAT_AUTO = "auto"


@dataclass(frozen=True)
class Stack:
    """Which back-ends an episode uses. ``vlm``: "local:MODEL" or "openai:MODEL[@BASE_URL]";
    ``cache``: replay identical model requests from the response cache (off for timings);
    ``temperature``: the VLM's sampling temperature for every call (0: greedy);
    ``explore_scorer``: where the semantic values come from (``EXPLORE_SCORERS``; "auto": the
    VLM's verbalized confidence when it reads images or token probabilities are asked for,
    else ``OFFLINE_EXPLORE_SCORER``).

    The model server's options (None: ``ChatBackend``'s default; see its docstring):
    ``timeout_s`` and ``retries`` of each call, ``api_key_env`` (the variable whose key is sent,
    or "none"), ``image_format`` (``IMAGE_FORMAT_AUTO`` | png | jpeg; auto: jpeg for openai:
    servers, png for the local one), ``image_max_side`` (px) and ``image_detail`` (auto | low |
    high), ``capabilities`` (a JSON file of what an openai: server can do, in place of its
    probe: ``models.backends.read_capabilities``). ``server_options()`` gives them as
    ``parse_vlm``'s keywords.

    The relevancy model's (``build_relevancy``): ``device`` (auto | cpu | cuda | cuda:N; auto:
    the GPU torch sees, in float16, else the CPU), ``relevancy_weights`` (a local folder with
    its weights) and ``allow_download`` (fetch them from the Hugging Face Hub when missing)."""

    vlm: str = knob(f"local:{DEFAULT_MODEL}", help="local:MODEL (the embedded llama.cpp "
                    "server) | openai:MODEL (OpenAI) | openai:MODEL@BASE_URL (any "
                    "OpenAI-compatible server, e.g. "
                    "openai:gpt-4o or openai:Qwen/Qwen2-VL-7B@http://localhost:8000/v1; key: see "
                    "backends.api_key_env).")
    perception: str = knob("semantic", help="semantic (object labels as text) | pixels (RGB-D "
                           "read by the project's own network, described as text) | rgb "
                           "(images, needs an image VLM).")
    sightings: str = knob("auto", beyond=True, help="Where the steering and the sightings gate "
                          "learn what a frame shows of rooms and of the question's target: auto "
                          "(the perception's own; with rgb, the VLM's) | perception | model (one "
                          "call to the VLM per step).")
    relevancy: str = knob("minilm", help="minilm (over text) | minilm-match | overlap | "
                          "vlm-match (the VLM answers 'does this view show it?'; default over "
                          "images without BLIP-2's weights) | blip2-itm (the paper's; default over "
                          "images where its weights are) | clip | siglip.")
    grouping: str = knob("llm", help="How equivalent answers are grouped: llm | rules.")
    cache: bool = knob(True, help="Replay identical model requests from the response cache.")
    temperature: float = knob(0.0, help="The VLM's sampling temperature for every call.")
    explore_scorer: str = knob("auto", help="Where the semantic values come from: auto (the "
                               "VLM's verbalized confidence when it reads images or with token "
                               "confidence, else direction-logit) | vlm | direction-logit (no "
                               "model: features of the direction texts).")
    timeout_s: float | None = knob(None, help="Seconds the model server has for each try of a "
                                   "call (default 120).")
    retries: int | None = knob(None, help="Retries of a model call after the first try, on "
                               "timeouts, refused connections, 429 and 5xx (default 4).")
    api_key_env: str | None = knob(None, help="The environment variable whose key is sent to "
                                   "the openai: server, or none (default: OPENAI_API_KEY for "
                                   "api.openai.com only).")
    image_format: str = knob(IMAGE_FORMAT_AUTO, help="auto (jpeg, quality 90, for openai: "
                             "servers; png for the local one) | png | jpeg.")
    image_max_side: int = knob(512, help="Images are shrunk to this longer side in px.")
    image_detail: str | None = knob(None, help="auto | low | high: OpenAI's image_url.detail "
                                    "(default: not sent).")
    capabilities: str | None = knob(None, help="A JSON file of what the openai: server can do, "
                                    'e.g. {"logprobs": true, "json_schema": false, "images": '
                                    "true}, in place of asking it.")
    device: str = knob("auto", help="Where an image relevancy model runs: auto (the GPU torch "
                       "sees, in float16, else the CPU) | cpu | cuda | cuda:N.")
    relevancy_weights: str | None = knob(None, help="A local folder with the relevancy model's "
                                         "weights (default: its Hugging Face cache).")
    allow_download: bool = knob(False, off="no_download", help="Let missing relevancy weights "
                                "download from the Hugging Face Hub.")

    def server_options(self) -> dict[str, Any]:
        return {"timeout_s": self.timeout_s, "retries": self.retries,
                "api_key_env": self.api_key_env, "image_format": self.image_format,
                "image_max_side": self.image_max_side, "image_detail": self.image_detail,
                "capabilities": self.capabilities}
