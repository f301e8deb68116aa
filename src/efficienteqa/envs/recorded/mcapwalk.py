"""What an MCAP walk is to both its reader (``rosbag``) and its writer (``write``): the topics
that carry a simulated walk's truth, the options a walk is read with, and the one-line check
that the mcap packages (the ``robot`` extra) are installed. Kept apart so that writing a walk
does not load the code that reads one.
"""

from __future__ import annotations

from dataclasses import dataclass

from efficienteqa.errors import EfficientEQAError

INSTANCE_TOPIC = "/efficienteqa/instance"
LABELS_TOPIC = "/efficienteqa/labels"
FIX_MCAP = "pip install 'efficienteqa[robot]' (the mcap and mcap-ros2-support packages)"


def require_mcap() -> None:
    """One line when the ``robot`` extra is not installed."""
    try:
        import mcap.reader  # noqa: F401
        import mcap_ros2.decoder  # noqa: F401
    except ImportError:
        raise EfficientEQAError("MCAP recordings need the mcap packages, which are not "
                                "installed", fix=FIX_MCAP) from None


@dataclass(frozen=True)
class McapOptions:
    """How to read an MCAP walk: topics (None: found by type), the world frame, tolerances."""

    colour: str | None = None
    depth: str | None = None
    info: str | None = None
    world: str = "map"
    depth_tolerance_ms: float = 50.0
    tf_tolerance_ms: float = 50.0

