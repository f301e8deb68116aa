"""A sentence-transformers folder of a BERT encoder with mean pooling, run in plain torch.

all-MiniLM-L6-v2 is such a folder: BERT (6 layers, 384 wide, 12 heads), the mean of the token
vectors under the attention mask, then L2 normalisation. Loading it through sentence-transformers
imports transformers' whole model zoo first, about 5 s of a command's start; this reads the same
weights (``model.safetensors``) and tokenizer (``tokenizer.json``, with the ``tokenizers``
library) and computes the same embeddings (equal to float32 rounding; a test holds them to the
library's) in about a tenth of that. ``load`` returns None for any other kind of folder, which
sentence-transformers then loads.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np


def _mean_pooled_bert(folder: Path) -> list[str] | None:
    """The module names of ``folder`` when it is a BERT encoder whose modules are Transformer,
    mean Pooling and (optionally) Normalize, with the files this encoder reads; else None."""
    try:
        modules = [m["type"].rsplit(".", 1)[-1]
                   for m in json.loads((folder / "modules.json").read_text())]
        pooling = json.loads((folder / "1_Pooling" / "config.json").read_text())
        config = json.loads((folder / "config.json").read_text())
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    mean_only = pooling.get("pooling_mode_mean_tokens") and not any(
        v for k, v in pooling.items() if k.startswith("pooling_mode_") and k != "pooling_mode_mean_tokens")
    ours = (modules in (["Transformer", "Pooling"], ["Transformer", "Pooling", "Normalize"])
            and bool(mean_only) and config.get("model_type") == "bert"
            and config.get("hidden_act") == "gelu"
            and config.get("position_embedding_type", "absolute") == "absolute"
            and (folder / "model.safetensors").is_file() and (folder / "tokenizer.json").is_file())
    return modules if ours else None


class BertEncoder:
    """``encode`` as ``SentenceTransformer.encode`` does it for a mean-pooled BERT folder."""

    def __init__(self, folder: Path, device: str = "cpu", normalize: bool = True) -> None:
        import torch
        from safetensors import SafetensorError
        from safetensors.torch import load_file
        from tokenizers import Tokenizer

        config = json.loads((folder / "config.json").read_text())
        self.heads = int(config["num_attention_heads"])
        self.layers = int(config["num_hidden_layers"])
        self.eps = float(config.get("layer_norm_eps", 1e-12))
        self.normalize = normalize
        try:
            limit = int(json.loads((folder / "sentence_bert_config.json").read_text())
                        ["max_seq_length"])
        except (OSError, ValueError, KeyError, TypeError):
            limit = int(config.get("max_position_embeddings", 512))
        self.device = torch.device(device)
        try:
            weights = load_file(str(folder / "model.safetensors"), device="cpu")
        except SafetensorError as exc:  # cut or not weights at all
            raise ValueError(f"model.safetensors is unreadable ({exc})") from None
        self.w = {k.removeprefix("bert."): v.to(self.device, torch.float32)
                  for k, v in weights.items() if v.is_floating_point()}
        try:
            self.tokenizer = Tokenizer.from_file(str(folder / "tokenizer.json"))
        except Exception as exc:  # tokenizers raises plain Exception on a bad file
            raise ValueError(f"tokenizer.json is unreadable ({exc})") from None
        self.tokenizer.enable_truncation(max_length=limit)
        self.tokenizer.no_padding()

    def _layer_norm(self, x: Any, name: str) -> Any:
        import torch.nn.functional as F

        return F.layer_norm(x, x.shape[-1:], self.w[f"{name}.weight"], self.w[f"{name}.bias"],
                            self.eps)

    def _linear(self, x: Any, name: str) -> Any:
        import torch.nn.functional as F

        return F.linear(x, self.w[f"{name}.weight"], self.w[f"{name}.bias"])

    def _forward(self, ids: Any, mask: Any) -> Any:
        """The last hidden states (batch, tokens, width) of token ids under ``mask``."""
        import torch
        import torch.nn.functional as F

        w = self.w
        n = ids.shape[1]
        h = (w["embeddings.word_embeddings.weight"][ids]
             + w["embeddings.position_embeddings.weight"][:n]
             + w["embeddings.token_type_embeddings.weight"][0])
        h = self._layer_norm(h, "embeddings.LayerNorm")
        batch, width = h.shape[0], h.shape[2]
        size = width // self.heads
        blocked = (1.0 - mask[:, None, None, :].to(h.dtype)) * torch.finfo(h.dtype).min
        for i in range(self.layers):
            name = f"encoder.layer.{i}"

            def heads(x: Any) -> Any:
                return x.view(batch, n, self.heads, size).transpose(1, 2)

            q, k, v = (heads(self._linear(h, f"{name}.attention.self.{p}"))
                       for p in ("query", "key", "value"))
            scores = q @ k.transpose(-1, -2) / math.sqrt(size) + blocked
            context = (scores.softmax(-1) @ v).transpose(1, 2).reshape(batch, n, width)
            h = self._layer_norm(h + self._linear(context, f"{name}.attention.output.dense"),
                                 f"{name}.attention.output.LayerNorm")
            inner = F.gelu(self._linear(h, f"{name}.intermediate.dense"))
            h = self._layer_norm(h + self._linear(inner, f"{name}.output.dense"),
                                 f"{name}.output.LayerNorm")
        return h

    def encode(self, sentences: list[str], batch_size: int = 32,
               normalize_embeddings: bool = False, **_: Any) -> np.ndarray:
        """(N, width) float32 sentence embeddings, in the order given."""
        import torch

        out = []
        with torch.inference_mode():
            for start in range(0, len(sentences), batch_size):
                encoded = self.tokenizer.encode_batch(list(sentences[start:start + batch_size]))
                n = max(len(e.ids) for e in encoded)
                ids = torch.zeros((len(encoded), n), dtype=torch.long)
                mask = torch.zeros((len(encoded), n), dtype=torch.long)
                for row, e in enumerate(encoded):
                    ids[row, :len(e.ids)] = torch.tensor(e.ids)
                    mask[row, :len(e.ids)] = 1
                ids, mask = ids.to(self.device), mask.to(self.device)
                hidden = self._forward(ids, mask)
                weights = mask[:, :, None].to(hidden.dtype)
                pooled = (hidden * weights).sum(1) / weights.sum(1).clamp(min=1e-9)
                if self.normalize or normalize_embeddings:
                    pooled = torch.nn.functional.normalize(pooled, p=2, dim=1)
                out.append(pooled.cpu().numpy())
        width = self.w["embeddings.word_embeddings.weight"].shape[1]
        return np.concatenate(out).astype(np.float32) if out else np.zeros((0, width), np.float32)


def load(folder: Path, device: str = "cpu") -> BertEncoder | None:
    """The encoder of ``folder`` run in plain torch, or None when it is not a mean-pooled BERT
    folder (sentence-transformers loads those)."""
    modules = _mean_pooled_bert(folder)
    return None if modules is None else BertEncoder(folder, device, "Normalize" in modules)
