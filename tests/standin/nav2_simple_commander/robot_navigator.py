"""``nav2_simple_commander.robot_navigator`` of the stand-in: ``BasicNavigator`` (an rclpy
node) and ``TaskResult``, the parts the ROS 2 adapter uses, with the simple commander's
behaviour:

- ``goToPose(pose, behavior_tree='')`` waits for the ``navigate_to_pose`` action server, sends
  the goal and returns whether it was accepted;
- ``isTaskComplete()`` spins the node for up to 0.1 s and says whether the goal has ended;
- ``getResult()`` maps the goal's status to ``TaskResult``; ``cancelTask()`` cancels it;
- ``waitUntilNav2Active(navigator, localizer)`` waits for the lifecycle nodes to be active and,
  with ``localizer='amcl'``, publishes ``initialpose`` (the pose given to ``setInitialPose``, by
  default the map's origin) until ``amcl_pose`` comes, as the real one does.

The action server is a simulated robot on the stand-in graph (``tests/standin/sim_robot.py``):
``send_goal(pose)`` gives a handle with ``accepted``, ``status`` (``action_msgs``' codes),
``done()`` and ``cancel()``.
"""

from __future__ import annotations

import enum
import time

import rclpy
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from rclpy import _graph
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


class TaskResult(enum.Enum):
    UNKNOWN = 0
    SUCCEEDED = 1
    CANCELED = 2
    FAILED = 3


class BasicNavigator(Node):
    def __init__(self, node_name: str = "basic_navigator", namespace: str = "") -> None:
        super().__init__(node_name=node_name, namespace=namespace)
        self.initial_pose = PoseStamped()
        self.initial_pose.header.frame_id = "map"
        self.goal_handle = None
        self.status = None
        self.initial_pose_received = False
        amcl_pose_qos = QoSProfile(durability=DurabilityPolicy.TRANSIENT_LOCAL,
                                   reliability=ReliabilityPolicy.RELIABLE,
                                   history=HistoryPolicy.KEEP_LAST, depth=1)
        self.localization_pose_sub = self.create_subscription(
            PoseWithCovarianceStamped, "amcl_pose", self._amclPoseCallback, amcl_pose_qos)
        self.initial_pose_pub = self.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)

    def _server(self):
        return _graph.GRAPH.action_servers.get(self.resolve_topic_name("navigate_to_pose"))

    def goToPose(self, pose: PoseStamped, behavior_tree: str = "") -> bool:
        while self._server() is None:  # as the real one: waits, saying so, for ever
            self.get_logger().info("'NavigateToPose' action server not available, waiting...")
            rclpy.spin_once(self, timeout_sec=1.0)
        self.goal_handle = self._server().send_goal(pose)
        if not self.goal_handle.accepted:
            self.get_logger().error(f"Goal to {pose.pose.position.x} {pose.pose.position.y} "
                                    "was rejected!")
            return False
        return True

    def cancelTask(self) -> None:
        if self.goal_handle is not None and self.goal_handle.accepted:
            self.goal_handle.cancel()

    def isTaskComplete(self) -> bool:
        if self.goal_handle is None or not self.goal_handle.accepted:
            return True
        deadline = time.monotonic() + 0.10
        while not self.goal_handle.done() and time.monotonic() < deadline:
            rclpy.spin_once(self, timeout_sec=0.005)
        if not self.goal_handle.done():
            return False
        self.status = self.goal_handle.status
        return True

    def getResult(self) -> TaskResult:
        if self.status == GoalStatus.STATUS_SUCCEEDED:
            return TaskResult.SUCCEEDED
        if self.status == GoalStatus.STATUS_ABORTED:
            return TaskResult.FAILED
        if self.status == GoalStatus.STATUS_CANCELED:
            return TaskResult.CANCELED
        return TaskResult.UNKNOWN

    def setInitialPose(self, initial_pose: PoseStamped) -> None:
        self.initial_pose_received = False
        self.initial_pose = initial_pose
        self._setInitialPose()

    def waitUntilNav2Active(self, navigator: str = "bt_navigator", localizer: str = "amcl") -> None:
        if localizer != "robot_localization":
            self._waitForNodeToActivate(localizer)
        if localizer == "amcl":
            self._waitForInitialPose()
        self._waitForNodeToActivate(navigator)

    def _waitForNodeToActivate(self, node_name: str) -> None:
        name = self.resolve_topic_name(node_name)
        while _graph.GRAPH.lifecycle.get(name) != "active":
            self.get_logger().info(f"{node_name}/get_state service not available, waiting...")
            rclpy.spin_once(self, timeout_sec=1.0)

    def _waitForInitialPose(self) -> None:
        while not self.initial_pose_received:
            self._setInitialPose()
            rclpy.spin_once(self, timeout_sec=1.0)

    def _amclPoseCallback(self, msg) -> None:
        self.initial_pose_received = True

    def _setInitialPose(self) -> None:
        msg = PoseWithCovarianceStamped()
        msg.pose.pose = self.initial_pose.pose
        msg.header.frame_id = self.initial_pose.header.frame_id
        msg.header.stamp = self.initial_pose.header.stamp
        self.initial_pose_pub.publish(msg)

    def destroyNode(self) -> None:
        self.destroy_node()
