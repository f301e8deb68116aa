"""Where the model server is and how to talk to it: ``ClientConfig``, checked when made.

Apart from the client so that the modules the client is built from (errors, the request and
reply, the probe) can read the settings without importing the client itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from efficienteqa.errors import EfficientEQAError
from efficienteqa.models.base import Capabilities
from efficienteqa.models.images import IMAGE_DETAILS, IMAGE_FORMATS

_SERVE_FIX = "start it with `efficienteqa models serve` or check base_url"


@dataclass(frozen=True)
class ClientConfig:
    """Where the model is and how to talk to it. Prices in USD per 1,000 tokens (0 for local).

    ``api_key_env`` names the environment variable holding the key (None: send no key).
    ``max_retries``: retries after the first try, by the SDK (see ``models/client.py``);
    ``timeout_s``: the limit of each try.
    ``image_format``/``image_max_side``/``image_detail``: how images are sent (``encode_image``;
    ``detail`` goes in ``image_url.detail``, None: not sent, the server's default); all three
    are part of the cache key.
    ``cache_server``: the base URL to key cached replies by (a server named by URL), or None
    (the embedded local model, keyed as before server URLs were keyed; ``models/cache.py``).
    ``unreachable_fix``: what to do when the server cannot be reached (per back-end kind).
    """

    base_url: str = "http://127.0.0.1:8080/v1"
    model: str = "local"
    api_key_env: str | None = None
    timeout_s: float = 60.0
    max_retries: int = 4
    image_max_side: int = 512
    image_format: str = "png"  # "png" | "jpeg"
    image_detail: str | None = None  # "auto" | "low" | "high"; None: not sent
    capabilities: Capabilities = field(default_factory=Capabilities)
    price_prompt_per_1k: float = 0.0
    price_completion_per_1k: float = 0.0
    cache: bool = True
    cache_path: str | None = None  # None: cache_dir("responses")/responses.sqlite
    temperature: float | None = None  # replaces every request's temperature (the paper's T = 1)
    cache_server: str | None = None
    unreachable_fix: str = _SERVE_FIX
    probe_dir: str | None = None  # None: cache_dir("probes")

    def __post_init__(self) -> None:
        if self.image_format not in IMAGE_FORMATS:
            raise EfficientEQAError(f"unknown image format {self.image_format!r}",
                                    fix=f"use one of {', '.join(IMAGE_FORMATS)}")
        if self.image_detail is not None and self.image_detail not in IMAGE_DETAILS:
            raise EfficientEQAError(f"unknown image detail {self.image_detail!r}",
                                    fix=f"use one of {', '.join(IMAGE_DETAILS)}")
        if self.image_max_side < 16:
            raise EfficientEQAError(f"image max side {self.image_max_side} px is too small",
                                    fix="use at least 16 px, e.g. 512")
        if not (self.timeout_s > 0 and math.isfinite(self.timeout_s)):
            raise EfficientEQAError(f"timeout {self.timeout_s} s is not a positive number",
                                    fix="use e.g. --backends.timeout-s 60")
        if self.max_retries < 0:
            raise EfficientEQAError(f"retries {self.max_retries} is negative",
                                    fix="use 0 (one try) or more")

    @property
    def image_encoding(self) -> str:
        """The image encoding in the cache key: ``png@512`` (as before ``detail`` existed),
        ``jpeg@512``, ``jpeg@512/low``."""
        encoding = f"{self.image_format}@{self.image_max_side}"
        return encoding + (f"/{self.image_detail}" if self.image_detail else "")
