"""The rclpy message classes of the project's type names, for creating publishers and subscriptions.

The only part of the message layer that needs rclpy: every message the node publishes or records
is encoded ROS-free by :mod:`mta_sim_ros.messages` and handed to rclpy as CDR bytes.
"""
from __future__ import annotations

import importlib

from .bag.schemas import split_type_name


def message_class(type_name: str) -> type:
    """The rclpy message class of a type name of the topic table, e.g.
    ``message_class(topics.TOPICS["hitch_poses"])`` is ``geometry_msgs.msg.PoseArray``.

    Raises:
        ValueError: malformed type name.
        ImportError, AttributeError: the message package or type is not installed.
    """
    pkg, name = split_type_name(type_name)
    return getattr(importlib.import_module(f"{pkg}.msg"), name)
