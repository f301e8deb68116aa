"""The paper's relevancy (DESIGN 3.4): BLIP-2 image-text matching, P(match | frame, question).

``Blip2ForImageTextRetrieval`` with its ITM head: the Q-Former attends to the frame while reading
the question (truncated to 32 tokens, the Q-Former's text length in training); the two logits are
averaged over the query tokens and the softmax's "match" entry (index 1) is the score, in [0, 1].
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from efficienteqa.relevancy.base import (
    Modality,
    RelevancyScorer,
    check_question,
    require,
    resolve_device,
    weights_missing,
)

DEFAULT_MODEL_ID = "Salesforce/blip2-itm-vit-g"
MAX_TEXT_TOKENS = 32
EXTRA = "vision"


class Blip2ItmScorer(RelevancyScorer):
    """BLIP-2 ITM relevancy of RGB frames (H, W, 3) uint8. Use ``from_pretrained`` for real
    weights or ``from_model`` to inject a model and processor (tests build tiny random ones)."""

    modality: Modality = "image"

    def __init__(self, model: Any, processor: Any, name: str = DEFAULT_MODEL_ID,
                 max_text_tokens: int = MAX_TEXT_TOKENS, batch_size: int = 8) -> None:
        self.model = model.eval()
        self.processor = processor
        self.name = name
        self.max_text_tokens = max_text_tokens
        self.batch_size = batch_size

    @classmethod
    def from_model(cls, model: Any, processor: Any, name: str = "blip2-itm (injected)",
                   **kwargs: Any) -> Blip2ItmScorer:
        return cls(model, processor, name=name, **kwargs)

    @classmethod
    def from_pretrained(cls, model_id_or_path: str | None = None, device: str = "auto",
                        allow_download: bool = False, dtype: str | None = None,
                        **kwargs: Any) -> Blip2ItmScorer:
        """Load from the Hugging Face cache or a local folder (None: ``DEFAULT_MODEL_ID``);
        downloads only when allowed. ``device`` and ``dtype`` as ``resolve_device`` reads them:
        "auto" is float16 on a GPU (the Q-Former stays float32, as transformers keeps it)."""
        torch = require("torch", EXTRA)
        transformers = require("transformers", EXTRA)
        model_id_or_path = model_id_or_path or DEFAULT_MODEL_ID
        device, dtype = resolve_device(device, dtype)
        local_only = not allow_download
        try:
            processor = transformers.Blip2Processor.from_pretrained(
                model_id_or_path, local_files_only=local_only)
            model = transformers.Blip2ForImageTextRetrieval.from_pretrained(
                model_id_or_path, local_files_only=local_only,
                dtype=getattr(torch, dtype) if dtype else None)
        except OSError as exc:
            raise weights_missing(model_id_or_path, exc) from exc
        return cls(model.to(device), processor, name=model_id_or_path, **kwargs)

    def score_many(self, question: str, items: Sequence[np.ndarray | str]) -> np.ndarray:
        torch = require("torch", EXTRA)
        images = [np.asarray(im) for im in items]
        if not images:
            return np.zeros(0)
        input_ids, attention_mask = self._question_tokens(check_question(question))
        device = next(self.model.parameters()).device
        dtype = self.model.vision_model.dtype
        out = []
        with torch.inference_mode():
            for s in range(0, len(images), self.batch_size):
                batch = images[s:s + self.batch_size]
                pixels = self.processor.image_processor(batch, return_tensors="pt")["pixel_values"]
                n = len(batch)
                logits = self.model(pixel_values=pixels.to(device, dtype),
                                    input_ids=input_ids.to(device).expand(n, -1),
                                    attention_mask=attention_mask.to(device).expand(n, -1),
                                    use_image_text_matching_head=True).logits_per_image
                out.append(logits.float().softmax(dim=-1)[:, 1].cpu().numpy())
        return np.concatenate(out).astype(np.float64)

    def _question_tokens(self, question: str) -> tuple[Any, Any]:
        """(1, L) ids and mask of the question. Where the checkpoint expects image placeholder
        tokens before the text (``image_token_index`` set), they are prepended here rather than
        by the processor, so old and new processor configs give the same input."""
        torch = require("torch", EXTRA)
        tokens = self.processor.tokenizer(question, truncation=True,
                                          max_length=self.max_text_tokens, return_tensors="pt")
        ids, mask = tokens["input_ids"], tokens["attention_mask"]
        config = self.model.config
        if config.image_token_index is not None:
            n = config.num_query_tokens
            ids = torch.cat([torch.full((1, n), config.image_token_index, dtype=ids.dtype), ids], 1)
            mask = torch.cat([torch.ones((1, n), dtype=mask.dtype), mask], 1)
        return ids, mask
