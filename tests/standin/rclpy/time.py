"""``rclpy.time`` of the stand-in."""

from __future__ import annotations

from rclpy.clock import ClockType
from rclpy.duration import Duration


class Time:
    def __init__(self, *, seconds: float = 0, nanoseconds: int = 0,
                 clock_type: ClockType = ClockType.SYSTEM_TIME) -> None:
        total = int(seconds * 1e9) + int(nanoseconds)
        if total < 0:
            raise ValueError("Total nanoseconds value is too low to store in a Time object")
        self._nanoseconds = total
        self.clock_type = clock_type

    @property
    def nanoseconds(self) -> int:
        return self._nanoseconds

    def seconds_nanoseconds(self) -> tuple[int, int]:
        return self._nanoseconds // 10**9, self._nanoseconds % 10**9

    def to_msg(self):
        from builtin_interfaces.msg import Time as TimeMsg

        sec, nanosec = self.seconds_nanoseconds()
        return TimeMsg(sec=sec, nanosec=nanosec)

    @classmethod
    def from_msg(cls, msg, clock_type: ClockType = ClockType.ROS_TIME) -> Time:
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec, clock_type=clock_type)

    def __add__(self, other: Duration) -> Time:
        return Time(nanoseconds=self._nanoseconds + other.nanoseconds, clock_type=self.clock_type)

    def __sub__(self, other):
        if isinstance(other, Time):
            return Duration(nanoseconds=self._nanoseconds - other.nanoseconds)
        return Time(nanoseconds=self._nanoseconds - other.nanoseconds, clock_type=self.clock_type)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Time) and other.nanoseconds == self._nanoseconds

    def __lt__(self, other: Time) -> bool:
        return self._nanoseconds < other.nanoseconds

    def __le__(self, other: Time) -> bool:
        return self._nanoseconds <= other.nanoseconds

    def __hash__(self) -> int:
        return hash(self._nanoseconds)
