"""Contrastive image-text relevancy (DESIGN 5): CLIP and SigLIP via transformers.

CLIP: cosine similarity of the projected, L2-normalised image and text embeddings, in [-1, 1].
SigLIP: the sigmoid of its pairwise logit (scaled cosine plus bias), a match probability in
[0, 1]; the question is padded to the tokenizer's maximum length, as SigLIP was trained.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from efficienteqa.relevancy.base import (
    Modality,
    RelevancyScorer,
    check_question,
    require,
    resolve_device,
    weights_missing,
)

Family = Literal["clip", "siglip"]
DEFAULT_MODEL_IDS: dict[str, str] = {
    "clip": "openai/clip-vit-base-patch32",
    "siglip": "google/siglip-base-patch16-224",
}
EXTRA = "vision"


class ClipScorer(RelevancyScorer):
    """CLIP or SigLIP relevancy of RGB frames (H, W, 3) uint8. ``from_pretrained`` loads real
    weights; ``from_model`` injects a model and a processor (with ``tokenizer`` and
    ``image_processor``), as tests do with tiny random ones."""

    modality: Modality = "image"

    def __init__(self, model: Any, processor: Any, family: Family, name: str,
                 batch_size: int = 16) -> None:
        if family not in DEFAULT_MODEL_IDS:
            raise ValueError(f"family must be 'clip' or 'siglip', got {family!r}")
        self.model = model.eval()
        self.processor = processor
        self.family = family
        self.name = name
        self.batch_size = batch_size

    @classmethod
    def from_model(cls, model: Any, processor: Any, family: Family = "clip",
                   name: str | None = None, **kwargs: Any) -> ClipScorer:
        return cls(model, processor, family, name or f"{family} (injected)", **kwargs)

    @classmethod
    def from_pretrained(cls, model_id_or_path: str | None = None, family: Family = "clip",
                        device: str = "auto", allow_download: bool = False,
                        dtype: str | None = None, **kwargs: Any) -> ClipScorer:
        """Load from the Hugging Face cache or a local folder; downloads only when allowed.
        ``device`` and ``dtype`` as ``resolve_device`` reads them (float16 on a GPU)."""
        transformers = require("transformers", EXTRA)
        torch = require("torch", EXTRA)
        model_id = model_id_or_path or DEFAULT_MODEL_IDS[family]
        device, dtype = resolve_device(device, dtype)
        try:
            processor = transformers.AutoProcessor.from_pretrained(
                model_id, local_files_only=not allow_download)
            model = transformers.AutoModel.from_pretrained(
                model_id, local_files_only=not allow_download,
                dtype=getattr(torch, dtype) if dtype else None)
        except OSError as exc:
            raise weights_missing(model_id, exc) from exc
        return cls(model.to(device), processor, family, model_id, **kwargs)

    def score_many(self, question: str, items: Sequence[np.ndarray | str]) -> np.ndarray:
        torch = require("torch", EXTRA)
        images = [np.asarray(im) for im in items]
        if not images:
            return np.zeros(0)
        weight = next(self.model.parameters())
        device, dtype = weight.device, weight.dtype
        padding = "max_length" if self.family == "siglip" else True
        text = self.processor.tokenizer([check_question(question)], padding=padding,
                                        truncation=True, return_tensors="pt")
        text = {k: v.to(device) for k, v in text.items() if k in ("input_ids", "attention_mask")}
        if self.family == "siglip":
            text.pop("attention_mask", None)  # SigLIP pools the last position and was trained unmasked
        out = []
        with torch.inference_mode():
            for s in range(0, len(images), self.batch_size):
                pixels = self.processor.image_processor(images[s:s + self.batch_size],
                                                        return_tensors="pt")["pixel_values"]
                result = self.model(pixel_values=pixels.to(device, dtype), **text)
                logits = result.logits_per_image[:, 0].float()  # (n,) one text
                if self.family == "siglip":
                    scores = torch.sigmoid(logits)
                else:
                    scores = (result.image_embeds.float() @ result.text_embeds.float().T)[:, 0]
                out.append(scores.cpu().numpy())
        return np.concatenate(out).astype(np.float64)
