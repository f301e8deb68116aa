"""``rclpy.node`` of the stand-in: a node's subscriptions, publishers, clock and logger."""

from __future__ import annotations

import logging
from collections import deque

from rclpy import _graph
from rclpy.clock import ROSClock
from rclpy.qos import QoSProfile


def _profile(qos_profile) -> QoSProfile:
    """A profile, or a history depth (rclpy's shorthand: reliable, volatile)."""
    if isinstance(qos_profile, QoSProfile):
        return qos_profile
    if isinstance(qos_profile, int) and not isinstance(qos_profile, bool):
        return QoSProfile(depth=qos_profile)
    raise TypeError("qos_profile must be a QoSProfile or a history depth")


class Publisher:
    def __init__(self, node: Node, msg_type, topic: str, qos: QoSProfile) -> None:
        self.node, self.msg_type, self.topic, self.qos = node, msg_type, topic, qos

    def publish(self, msg) -> None:
        if not isinstance(msg, self.msg_type):
            raise TypeError(f"Expected {self.msg_type.__name__}, got {type(msg).__name__}")
        _graph.GRAPH.deliver(self, msg)


class Subscription:
    def __init__(self, node: Node, msg_type, topic: str, callback, qos: QoSProfile) -> None:
        self.node, self.msg_type, self.topic, self.callback, self.qos = (node, msg_type, topic,
                                                                         callback, qos)
        self.queue: deque = deque(maxlen=max(qos.depth, 1))  # KEEP_LAST: the newest

    def receive(self, msg, arrival: int) -> None:
        self.queue.append((arrival, msg))


class Node:
    def __init__(self, node_name: str, *, context=None, cli_args=None, namespace=None,
                 use_global_arguments=True, enable_rosout=True, start_parameter_services=True,
                 parameter_overrides=None, allow_undeclared_parameters=False,
                 automatically_declare_parameters_from_overrides=False) -> None:
        if not _graph.GRAPH.running:
            raise RuntimeError("rclpy.init() has not been called")
        namespace = namespace or "/"
        self._name = node_name
        self._namespace = namespace if namespace.startswith("/") else "/" + namespace
        self._subscriptions: list[Subscription] = []
        self._publishers: list[Publisher] = []
        self._clock = ROSClock()
        self._logger = logging.getLogger(f"ros.{node_name}")
        self._destroyed = False

    def get_name(self) -> str:
        return self._name

    def get_namespace(self) -> str:
        return self._namespace

    def resolve_topic_name(self, topic: str) -> str:
        """A relative name is in the node's namespace; an absolute one is as given."""
        if topic.startswith("/"):
            return topic
        return f"{self._namespace.rstrip('/')}/{topic}"

    def get_clock(self) -> ROSClock:
        return self._clock

    def get_logger(self):
        return self._logger

    def create_publisher(self, msg_type, topic: str, qos_profile, *, callback_group=None,
                         event_callbacks=None) -> Publisher:
        publisher = Publisher(self, msg_type, self.resolve_topic_name(topic), _profile(qos_profile))
        self._publishers.append(publisher)
        return publisher

    def create_subscription(self, msg_type, topic: str, callback, qos_profile, *,
                            callback_group=None, event_callbacks=None, raw=False) -> Subscription:
        sub = Subscription(self, msg_type, self.resolve_topic_name(topic), callback,
                           _profile(qos_profile))
        self._subscriptions.append(sub)
        _graph.GRAPH.subscribe(sub)
        return sub

    def destroy_subscription(self, subscription: Subscription) -> bool:
        if subscription in self._subscriptions:
            self._subscriptions.remove(subscription)
            _graph.GRAPH.subscriptions.remove(subscription)
            return True
        return False

    def destroy_publisher(self, publisher: Publisher) -> bool:
        if publisher in self._publishers:
            self._publishers.remove(publisher)
            return True
        return False

    def destroy_node(self) -> None:
        for sub in list(self._subscriptions):
            self.destroy_subscription(sub)
        self._publishers.clear()
        self._destroyed = True

    def _take_one(self) -> bool:
        """Runs the callback of the message that arrived first among this node's queues."""
        waiting = [s for s in self._subscriptions if s.queue]
        if not waiting:
            return False
        sub = min(waiting, key=lambda s: s.queue[0][0])
        _, msg = sub.queue.popleft()
        sub.callback(msg)
        return True
