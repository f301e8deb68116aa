"""``rclpy.clock`` of the stand-in: the system clock (rclpy's without ``use_sim_time``)."""

from __future__ import annotations

import enum
import time


class ClockType(enum.IntEnum):
    UNINITIALIZED = 0
    ROS_TIME = 1
    SYSTEM_TIME = 2
    STEADY_TIME = 3


class Clock:
    def __init__(self, *, clock_type: ClockType = ClockType.SYSTEM_TIME) -> None:
        self.clock_type = clock_type

    def now(self):
        from rclpy.time import Time

        return Time(nanoseconds=time.time_ns(), clock_type=self.clock_type)


class ROSClock(Clock):
    def __init__(self) -> None:
        super().__init__(clock_type=ClockType.ROS_TIME)
