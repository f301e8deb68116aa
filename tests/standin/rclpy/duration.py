"""``rclpy.duration`` of the stand-in."""

from __future__ import annotations


class Duration:
    def __init__(self, *, seconds: float = 0, nanoseconds: int = 0) -> None:
        self._nanoseconds = int(seconds * 1e9) + int(nanoseconds)

    @property
    def nanoseconds(self) -> int:
        return self._nanoseconds

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Duration) and other.nanoseconds == self.nanoseconds

    def __lt__(self, other: Duration) -> bool:
        return self.nanoseconds < other.nanoseconds

    def __hash__(self) -> int:
        return hash(self._nanoseconds)

    def to_msg(self):
        from builtin_interfaces.msg import Duration as DurationMsg

        return DurationMsg(sec=self._nanoseconds // 10**9, nanosec=self._nanoseconds % 10**9)
