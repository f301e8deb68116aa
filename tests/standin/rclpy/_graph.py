"""The stand-in's ROS graph, one per process: topics, latched messages, action servers,
lifecycle states, and the other processes that run while anything spins."""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any


class Graph:
    def __init__(self) -> None:
        self.running = False
        self.subscriptions: list[Any] = []
        self.latched: dict[str, list[tuple[Any, Any]]] = {}  # topic -> [(publisher, message)]
        self.processes: list[Callable[[], None]] = []
        self.action_servers: dict[str, Any] = {}
        self.lifecycle: dict[str, str] = {}  # fully qualified node name -> state label
        self.arrivals = itertools.count()
        self._in_process = False

    def start(self) -> None:
        self.__init__()  # type: ignore[misc]  # a fresh graph per context
        self.running = True

    def stop(self) -> None:
        self.running = False

    def run_processes(self) -> None:
        """The other processes' turn (not re-entered: a process that spins runs alone)."""
        if self._in_process:
            return
        self._in_process = True
        try:
            for process in list(self.processes):
                process()
        finally:
            self._in_process = False

    def deliver(self, publisher: Any, msg: Any) -> None:
        if publisher.qos.durability_is_transient_local:
            kept = self.latched.setdefault(publisher.topic, [])
            kept.append((publisher, msg))
            mine = [m for m in kept if m[0] is publisher]
            if len(mine) > publisher.qos.depth:
                kept.remove(mine[0])
        for sub in self.subscriptions:
            if sub.topic == publisher.topic and compatible(publisher, sub):
                sub.receive(msg, next(self.arrivals))

    def subscribe(self, sub: Any) -> None:
        self.subscriptions.append(sub)
        if sub.qos.durability_is_transient_local:
            for publisher, msg in self.latched.get(sub.topic, []):
                if compatible(publisher, sub):
                    sub.receive(msg, next(self.arrivals))


def compatible(publisher: Any, sub: Any) -> bool:
    """Whether ROS 2 would connect them: the same type; a reliable subscription needs a reliable
    publisher, a transient-local one a transient-local publisher."""
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

    if publisher.msg_type is not sub.msg_type:
        return False
    if (sub.qos.reliability == ReliabilityPolicy.RELIABLE
            and publisher.qos.reliability == ReliabilityPolicy.BEST_EFFORT):
        return False
    return not (sub.qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
                and publisher.qos.durability != DurabilityPolicy.TRANSIENT_LOCAL)


GRAPH = Graph()
