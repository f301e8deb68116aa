"""``rclpy.qos`` of the stand-in: profiles and the policies the graph matches on."""

from __future__ import annotations

import enum


class ReliabilityPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2


class DurabilityPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2


class HistoryPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2


QoSReliabilityPolicy, QoSDurabilityPolicy, QoSHistoryPolicy = (ReliabilityPolicy, DurabilityPolicy,
                                                               HistoryPolicy)


class QoSProfile:
    """As rclpy's: ``history`` KEEP_LAST needs a ``depth``; the system defaults are reliable and
    volatile."""

    def __init__(self, **kwargs) -> None:
        self.history = HistoryPolicy(kwargs.get("history", HistoryPolicy.KEEP_LAST))
        if "depth" not in kwargs and self.history == HistoryPolicy.KEEP_LAST:
            raise TypeError("A QoSProfile with KEEP_LAST history must give a depth")
        self.depth = int(kwargs.get("depth", 1000))
        self.reliability = ReliabilityPolicy(kwargs.get("reliability", ReliabilityPolicy.RELIABLE))
        if self.reliability == ReliabilityPolicy.SYSTEM_DEFAULT:
            self.reliability = ReliabilityPolicy.RELIABLE
        self.durability = DurabilityPolicy(kwargs.get("durability", DurabilityPolicy.VOLATILE))
        if self.durability == DurabilityPolicy.SYSTEM_DEFAULT:
            self.durability = DurabilityPolicy.VOLATILE

    @property
    def durability_is_transient_local(self) -> bool:
        return self.durability == DurabilityPolicy.TRANSIENT_LOCAL


qos_profile_sensor_data = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5,
                                     reliability=ReliabilityPolicy.BEST_EFFORT,
                                     durability=DurabilityPolicy.VOLATILE)
qos_profile_system_default = QoSProfile(depth=10)
