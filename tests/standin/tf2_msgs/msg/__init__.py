"""``tf2_msgs/msg``: ``TFMessage``."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class TFMessage:
    transforms: list = field(default_factory=list)
