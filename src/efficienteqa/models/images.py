"""Images as the chat request carries them: a ``data:`` URL of a PNG or JPEG, shrunk to a size.

Apart from the client because the report and ``ask`` encode frames too, without a model server:
importing this loads numpy and PIL, not the ``openai`` SDK.
"""

from __future__ import annotations

import base64
import io

import numpy as np
from PIL import Image

from efficienteqa.errors import EfficientEQAError

IMAGE_FORMATS = ("png", "jpeg")
IMAGE_DETAILS = ("auto", "low", "high")


def encode_image(image: np.ndarray, max_side: int = 512, fmt: str = "png") -> str:
    """A ``data:`` URL of an RGB uint8 (H, W, 3) image, longer side shrunk to ``max_side`` px."""
    array = np.asarray(image)
    if array.ndim not in (2, 3) or array.size == 0:
        raise EfficientEQAError(f"image must be an (H, W, 3) array, got shape {array.shape}")
    if array.dtype != np.uint8:
        array = np.clip(array, 0, 255).astype(np.uint8)
    pil = Image.fromarray(array)
    if max(pil.size) > max_side:
        scale = max_side / max(pil.size)
        size = (max(1, round(pil.width * scale)), max(1, round(pil.height * scale)))
        pil = pil.resize(size, Image.Resampling.LANCZOS)
    buffer = io.BytesIO()
    if fmt == "jpeg":
        pil.convert("RGB").save(buffer, format="JPEG", quality=90)
    else:
        pil.save(buffer, format="PNG")
    return f"data:image/{fmt};base64,{base64.b64encode(buffer.getvalue()).decode()}"
