"""A stand-in for ``rclpy`` (ROS 2's Python client library), for tests on machines without ROS 2.

Only what the ROS 2 adapter (``efficienteqa.envs.ros2``), the stand-in ``tf2_ros`` and the
stand-in ``nav2_simple_commander`` use, with rclpy's signatures: ``init``, ``ok``, ``shutdown``,
``spin_once``, ``spin_until_future_complete``, ``node.Node`` (subscriptions, publishers, the
clock), ``qos`` (profiles and their policies), ``time.Time``, ``duration.Duration``.

Behind it one in-process graph (``rclpy._graph``): publishers deliver to the subscriptions of
their topic whose type and QoS match (a reliable subscription gets nothing from a best-effort
publisher; a transient-local one gets what a transient-local publisher kept, even when it
subscribes later), each subscription keeps its queue's depth of the newest messages, and
``spin_once`` runs one callback of the node it spins. The graph's other processes (a simulated
robot, ``tests/standin/sim_robot.py``) run whenever any node is spun: the time they get is the
time the adapter spends spinning, as on a real robot. Time is the system clock, as rclpy's
without ``use_sim_time``.
"""

from __future__ import annotations

import time as _time

from rclpy import _graph

STANDIN = True  # lets tests tell this module from the real one

__all__ = ["init", "ok", "shutdown", "spin_once", "spin_until_future_complete"]


def init(*, args=None, context=None, domain_id=None, signal_handler_options=None) -> None:
    if _graph.GRAPH.running:
        raise RuntimeError("Context.init() must only be called once")
    _graph.GRAPH.start()


def ok(*, context=None) -> bool:
    return _graph.GRAPH.running


def shutdown(*, context=None, uncaught_exception=True) -> None:
    if not _graph.GRAPH.running:
        raise RuntimeError("Context must be initialized before it can be shutdown")
    _graph.GRAPH.stop()


def spin_once(node, *, executor=None, timeout_sec=None) -> None:
    """Runs one ready callback of ``node``, waiting up to ``timeout_sec`` for one (None: until
    there is one)."""
    deadline = None if timeout_sec is None else _time.monotonic() + max(timeout_sec, 0.0)
    while True:
        _graph.GRAPH.run_processes()
        if node._take_one():
            return
        now = _time.monotonic()
        if deadline is not None and now >= deadline:
            return
        _time.sleep(0.002 if deadline is None else min(0.002, deadline - now))


def spin_until_future_complete(node, future, executor=None, timeout_sec=None) -> None:
    """Spins ``node`` until ``future.done()`` or ``timeout_sec`` has passed."""
    deadline = None if timeout_sec is None else _time.monotonic() + timeout_sec
    while not future.done():
        left = None if deadline is None else deadline - _time.monotonic()
        if left is not None and left <= 0:
            return
        spin_once(node, timeout_sec=0.005 if left is None else min(0.005, left))
