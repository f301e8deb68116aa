"""The pixel network: RGB-D in, per-pixel category, colour and state logits out.

Input (B, 4, H, W): RGB scaled to [0, 1] and depth in metres / DEPTH_SCALE_M (0 = missing), at
half the frame's resolution (320x240 for a 640x480 frame). Output: three logit maps at the input
size: categories (``Vocabulary.categories``), colours (``Vocabulary.colours``) and states (index 0
"no state", then ``Vocabulary.states``).

The network is a small U-Net: a full-resolution stem, four stride-2 stages down to 1/16 (the
deeper ones depthwise-separable, the last with dilated convolutions for room-sized context),
a decoder that upsamples and concatenates the skip of each level, and 1x1 heads on the 1/2
level whose logits are upsampled bilinearly to the input size.

Weights are one float16 state dict (``.pt``) with a JSON file beside it (``.json``) holding the
vocabulary, the widths, the sha256 of the ``.pt`` and how they were trained. This module imports
torch, numpy and the error type only: inference reads the vocabulary from the JSON.
"""

from __future__ import annotations

import hashlib
import json
import pickle
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from efficienteqa.errors import EfficientEQAError, first_line
from efficienteqa.perception.pixels.segment import FLOOR_PREFIX

DEPTH_SCALE_M = 5.0  # depth channel = metres / this
VOID, WALL = 0, 1  # category indices of "no surface" and non-floor structure
IGNORE = 255  # label value the losses skip
DEFAULT_WIDTHS = (16, 32, 48, 64, 96)  # stem (1/1), 1/2, 1/4, 1/8, 1/16
# The most channels a level of a network read from disk may have: metadata naming more is
# refused before a network that size is allocated.
MAX_WIDTH = 4096
WEIGHTS_FORMAT = 1


@dataclass(frozen=True)
class Vocabulary:
    """What the network names: ``categories`` (0 "void", 1 "wall", "floor:<room type>"...,
    "door", then object categories), ``colours`` and ``states`` (the state head has one more
    class, index 0 = "no state")."""

    categories: tuple[str, ...]
    colours: tuple[str, ...]
    states: tuple[str, ...]

    def __post_init__(self) -> None:
        if self.categories[:2] != ("void", "wall"):
            raise ValueError("categories must start with 'void', 'wall'")
        for name in ("categories", "colours", "states"):
            values = getattr(self, name)
            if len(set(values)) != len(values):
                raise ValueError(f"duplicate names in {name}")
        if len(self.categories) > IGNORE:
            raise ValueError(f"at most {IGNORE} categories fit a uint8 label")

    @property
    def floor_types(self) -> tuple[str, ...]:
        """Room types with a floor class, in category order."""
        return tuple(c[len(FLOOR_PREFIX):] for c in self.categories if c.startswith(FLOOR_PREFIX))

    def index(self, category: str) -> int | None:
        try:
            return self.categories.index(category)
        except ValueError:
            return None

    def to_json(self) -> dict[str, list[str]]:
        return {"categories": list(self.categories), "colours": list(self.colours),
                "states": list(self.states)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Vocabulary:
        return cls(tuple(data["categories"]), tuple(data["colours"]), tuple(data["states"]))


def _conv_bn(cin: int, cout: int, stride: int = 1, groups: int = 1, dilation: int = 1,
             kernel: int = 3) -> nn.Sequential:
    pad = dilation * (kernel // 2)
    return nn.Sequential(nn.Conv2d(cin, cout, kernel, stride, pad, dilation, groups, bias=False),
                         nn.BatchNorm2d(cout), nn.ReLU(inplace=True))


class _Separable(nn.Sequential):
    """Depthwise 3x3 (stride, dilation) then pointwise 1x1, each with BN and ReLU."""

    def __init__(self, cin: int, cout: int, stride: int = 1, dilation: int = 1) -> None:
        super().__init__(_conv_bn(cin, cin, stride, groups=cin, dilation=dilation),
                         _conv_bn(cin, cout, kernel=1))


class PixelNet(nn.Module):
    """A small U-Net; ``widths`` = channels of the stem (1/1) and of the 1/2 ... 1/16 levels."""

    def __init__(self, vocab: Vocabulary, widths: tuple[int, ...] = DEFAULT_WIDTHS) -> None:
        super().__init__()
        if len(widths) != 5:
            raise ValueError(f"widths needs 5 numbers (1/1 ... 1/16), got {widths}")
        self.vocab, self.widths = vocab, tuple(int(w) for w in widths)
        c0, c1, c2, c3, c4 = self.widths
        self.stem = _conv_bn(4, c0)
        self.down1 = nn.Sequential(_conv_bn(c0, c1, stride=2), _conv_bn(c1, c1))
        self.down2 = nn.Sequential(_conv_bn(c1, c2, stride=2), _Separable(c2, c2))
        self.down3 = nn.Sequential(_Separable(c2, c3, stride=2), _Separable(c3, c3))
        self.down4 = nn.Sequential(_Separable(c3, c4, stride=2), _Separable(c4, c4, dilation=2),
                                   _Separable(c4, c4, dilation=4))
        self.context = nn.Sequential(nn.AdaptiveAvgPool2d(1), nn.Conv2d(c4, c4, 1), nn.ReLU())
        self.up3 = _Separable(c4 + c3, c3)
        self.up2 = _Separable(c3 + c2, c2)
        self.up1 = nn.Sequential(_conv_bn(c2 + c1 + c0, c1), _Separable(c1, c1))
        self.category_head = nn.Conv2d(c1, len(vocab.categories), 1)
        self.colour_head = nn.Conv2d(c1, len(vocab.colours), 1)
        self.state_head = nn.Conv2d(c1, len(vocab.states) + 1, 1)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Category, colour and state logits at the input size."""
        size = x.shape[-2:]
        return tuple(_up(logits, size) for logits in self.half_logits(x))  # type: ignore[return-value]

    def half_logits(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The three logit maps at half the input size (the heads' own resolution)."""
        f0 = self.stem(x)
        f1 = self.down1(f0)
        f2 = self.down2(f1)
        f3 = self.down3(f2)
        f4 = self.down4(f3)
        f4 = f4 + self.context(f4)
        y = self.up3(torch.cat([_up(f4, f3), f3], 1))
        y = self.up2(torch.cat([_up(y, f2), f2], 1))
        # the stem's full-resolution detail reaches the 1/2 level by 2x2 max pooling
        y = self.up1(torch.cat([_up(y, f1), f1, F.max_pool2d(f0, 2, ceil_mode=True)], 1))
        return self.category_head(y), self.colour_head(y), self.state_head(y)


def _up(x: torch.Tensor, like: torch.Tensor | Sequence[int]) -> torch.Tensor:
    size = like.shape[-2:] if isinstance(like, torch.Tensor) else like
    if tuple(x.shape[-2:]) == tuple(size):
        return x
    return F.interpolate(x, size=tuple(size), mode="bilinear", align_corners=False)


# -- frames in, labels out ----------------------------------------------------------------------
def half_size(rgb: np.ndarray, depth_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The network's view of a frame: RGB averaged over 2x2 blocks (uint8) and the depth of each
    block's lower-right pixel (the pixel ``[1::2, 1::2]`` that labels are read at)."""
    h, w = depth_m.shape
    h2, w2 = h // 2, w // 2
    blocks = rgb[0:2 * h2:2, 0:2 * w2:2].astype(np.uint16)
    blocks += rgb[1:2 * h2:2, 0:2 * w2:2]
    blocks += rgb[0:2 * h2:2, 1:2 * w2:2]
    blocks += rgb[1:2 * h2:2, 1:2 * w2:2]
    blocks += 2
    blocks >>= 2
    return blocks.astype(np.uint8), depth_m[1:2 * h2:2, 1:2 * w2:2]


def to_input(rgb: np.ndarray, depth_m: np.ndarray) -> torch.Tensor:
    """(H, W, 3) uint8 and (H, W) metres (or a batch of each) -> (B, 4, H, W) float32."""
    if rgb.ndim == 3:
        rgb, depth_m = rgb[None], depth_m[None]
    b, h, w = depth_m.shape
    x = np.empty((b, 4, h, w), np.float32)
    np.multiply(rgb.transpose(0, 3, 1, 2), np.float32(1 / 255), out=x[:, :3], casting="unsafe")
    depth = np.nan_to_num(np.asarray(depth_m, np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    np.multiply(np.maximum(depth, 0.0), np.float32(1 / DEPTH_SCALE_M), out=x[:, 3])
    return torch.from_numpy(x)


class Prediction(NamedTuple):
    """Per-pixel outputs at half the frame's size: category, colour and state indices (state 0 =
    no state, k = ``states[k - 1]``) and the category's softmax probability. The category is the
    argmax of the logits upsampled bilinearly; colour, state and confidence are read at the heads'
    resolution (a quarter of the pixels) and repeated 2x2."""

    category: np.ndarray
    colour: np.ndarray
    state: np.ndarray
    confidence: np.ndarray


def predict(net: PixelNet, rgb: np.ndarray, depth_m: np.ndarray) -> Prediction:
    """Run the network on one full-size frame (H, W, 3 uint8; H, W metres)."""
    small_rgb, small_depth = half_size(rgb, depth_m)
    net.eval()
    h, w = small_depth.shape
    with torch.inference_mode():
        cat_half, col, state = net.half_logits(to_input(small_rgb, small_depth))
        # channels-last makes the per-pixel max over ~100 categories a contiguous reduction
        cat = _up(cat_half.contiguous(memory_format=torch.channels_last), (h, w))
        category = cat.max(1).indices[0].numpy().astype(np.uint8)
        prob = torch.softmax(cat_half[0], 0).amax(0).numpy().astype(np.float16)
        colour = col[0].argmax(0).numpy().astype(np.uint8)
        states = state[0].argmax(0).numpy().astype(np.uint8)

    def full(a: np.ndarray) -> np.ndarray:
        return np.repeat(np.repeat(a, 2, 0), 2, 1)[:h, :w]

    return Prediction(category, full(colour), full(states), full(prob))


# -- weights on disk ----------------------------------------------------------------------------
def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def metadata_path(path: Path) -> Path:
    return Path(path).with_suffix(".json")


def save_weights(path: Path, net: PixelNet, vocab: Vocabulary, meta: dict[str, Any]) -> Path:
    """Write the float16 state dict to ``path`` and the metadata (``meta`` plus the vocabulary,
    widths and the file's sha256) to ``path`` with suffix .json. Returns the JSON's path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {k: (v.detach().to(torch.float16) if v.is_floating_point() else v.detach()).cpu()
             for k, v in net.state_dict().items()}
    torch.save(state, path)
    record = {**meta, "format": WEIGHTS_FORMAT, "vocabulary": vocab.to_json(),
              "widths": list(net.widths), "weights_file": path.name, "sha256": sha256_of(path),
              "bytes": path.stat().st_size}
    json_path = metadata_path(path)
    json_path.write_text(json.dumps(record, indent=2) + "\n")
    return json_path


def load_weights(path: Path) -> tuple[PixelNet, Vocabulary, dict[str, Any]]:
    """The network (float32, eval mode), its vocabulary and its metadata; the file's sha256 must
    match the metadata's. A pair whose checksum matches but whose metadata does not describe the
    network in the file (other widths or vocabulary, or a file that holds no state dict) is one
    line too: the checksum proves the two files belong together, not that they are right."""
    path, json_path = Path(path), metadata_path(Path(path))
    fix = "train them: efficienteqa perception train --data DIR --out PATH"
    if not path.is_file() or not json_path.is_file():
        missing = path if not path.is_file() else json_path
        raise EfficientEQAError(f"pixel perception weights missing: {missing}", fix=fix)
    try:
        meta = json.loads(json_path.read_text())
        vocab = Vocabulary.from_json(meta["vocabulary"])
        widths = tuple(meta["widths"])
        expected = meta["sha256"]
        if not all(type(w) is int and 0 < w <= MAX_WIDTH for w in widths):  # a bool is no width
            raise ValueError(f"widths must be whole numbers from 1 to {MAX_WIDTH}, not {widths}")
    except (ValueError, KeyError, TypeError) as exc:
        raise EfficientEQAError(f"unreadable weights metadata {json_path}: {exc}", fix=fix) from None
    if sha256_of(path) != expected:
        raise EfficientEQAError(f"pixel perception weights {path} do not match the sha256 in "
                                f"{json_path.name}", fix="restore both files from the package")
    try:
        net = PixelNet(vocab, widths)
        state = torch.load(path, map_location="cpu", weights_only=True)
        net.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in state.items()})
    except (pickle.UnpicklingError, RuntimeError, ValueError, TypeError, AttributeError,
            EOFError) as exc:  # not a state dict, or another network's (size mismatch)
        raise EfficientEQAError(f"pixel perception weights {path} do not fit the network "
                                f"{json_path.name} describes: {first_line(exc)}",
                                fix=f"restore both files from the package, or {fix}") from None
    net.eval()
    return net, vocab, meta
