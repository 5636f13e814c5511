"""What the package's ROS nodes share: the one QoS profile, and the rclpy message classes of the
project's type names (for creating publishers and subscriptions).

The only part of the message layer that needs rclpy: every message the node publishes or records
is encoded ROS-free by :mod:`mta_sim_ros.messages` and handed to rclpy as CDR bytes.
"""
from __future__ import annotations

import importlib

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..bag.schemas import split_type_name

#: The QoS of every topic the simulator, its players and controllers use: reliable, volatile, keep
#: last 10 (rclpy's default publisher profile; the bag records it as offered_qos_profiles).
QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.VOLATILE)

#: The QoS of the latched topics (topics.LATCHED_TOPICS: /tf_static, robot_description): reliable,
#: transient-local, keep last 1, what tf2's static listener and robot_state_publisher's readers ask.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)


def message_class(type_name: str) -> type:
    """The rclpy message class of a type name of the topic table, e.g.
    ``message_class(topics.TOPICS["hitch_poses"])`` is ``geometry_msgs.msg.PoseArray``.

    Raises:
        ValueError: malformed type name.
        ImportError, AttributeError: the message package or type is not installed.
    """
    pkg, name = split_type_name(type_name)
    return getattr(importlib.import_module(f"{pkg}.msg"), name)
