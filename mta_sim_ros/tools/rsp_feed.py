"""``mta rsp_feed``: a node that hands the simulator's robot_description to robot_state_publisher.

robot_state_publisher of ROS 2 Jazzy (3.3.x) reads the robot's URDF from its ``robot_description``
parameter only: it must be set, and not empty, when the node starts, and it is parsed again each
time the parameter is set (reading it from a topic came with 3.5.3, after Jazzy). The simulator
publishes its train's URDF on the topic ``robot_description`` (std_msgs/String, transient local).
This node subscribes that topic and sets each new description on the ``robot_description``
parameter of ``--target`` (default ``robot_state_publisher``, resolved in this node's namespace),
so a launch file can start robot_state_publisher with a one-link placeholder and the train's model
replaces it as soon as the simulator is up (``launch/sim.launch.py``).

A description the target refuses (robot_state_publisher parses it first) is logged with the
target's reason and not sent again; the next different description is. The node runs until
SIGINT or SIGTERM.
"""
from __future__ import annotations

import argparse
import re
import time

from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from ..validate import Rule, show
from .maneuver import spin_until_done

#: the topic the simulator publishes its URDF on, and the parameter robot_state_publisher reads it from
DESCRIPTION = "robot_description"
#: the QoS of a latched description (robot_state_publisher's own: depth 1, reliable, transient local)
DESCRIPTION_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: s between tries while the target's parameter services are not up, and before a call that got no
#: answer is made again
RETRY_S = 0.5
ANSWER_TIMEOUT_S = 5.0


#: the longest target: '/<namespace>/<target>/describe_parameters' must stay within rcl's 247 characters
MAX_TARGET = 160
#: a ROS node name, relative or absolute (rcl's rule for names: tokens of letters, digits and _,
#: not starting with a digit, joined by '/')
NODE_NAME = Rule("a node name: letters, digits and _ (not starting with a digit), parts joined by '/', "
                 f"a leading '/' for an absolute name, at most {MAX_TARGET} characters (its parameter services' "
                 "names must fit rcl's 247)",
                 lambda v: len(v) <= MAX_TARGET
                 and re.fullmatch(r"/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*", v) is not None)


def node_name(text: str) -> str:
    """An argparse ``type``: ``text`` if it is a node name (NODE_NAME), else the one-line reason."""
    if not NODE_NAME.test(text):
        raise argparse.ArgumentTypeError(f"{show(text)} must be {NODE_NAME.text}")
    return text


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--target", default="robot_state_publisher", type=node_name,
                   help="the node whose robot_description parameter to set (default robot_state_publisher; "
                        "a relative name is in this node's namespace)")


class DescriptionFeed(Node):
    """Sets every new robot_description message on the target's robot_description parameter."""

    def __init__(self, target: str):
        super().__init__("mta_rsp_feed")
        self.target = target
        self.client = AsyncParameterClient(self, target)
        self.create_subscription(String, DESCRIPTION, self._on_description, DESCRIPTION_QOS)
        self.pending: str | None = None  # the newest description the target has not yet taken
        self.taken: str | None = None  # the last one it took
        self.asked_at: float | None = None  # steady time of the call awaiting an answer
        self.done = False  # never: it runs until SIGINT/SIGTERM (spin_until_done)
        self.create_timer(RETRY_S, self._send)

    def _on_description(self, msg: String) -> None:
        if msg.data != self.taken:
            self.pending = msg.data
            self._send()

    def _send(self) -> None:
        """Ask the target to take the pending description, once its services answer and no call
        is awaiting its answer (a call unanswered after ANSWER_TIMEOUT_S is made again)."""
        if self.pending is None:
            return
        if self.asked_at is not None and time.monotonic() - self.asked_at < ANSWER_TIMEOUT_S:
            return
        if not self.client.services_are_ready():
            return
        text = self.pending
        self.asked_at = time.monotonic()
        future = self.client.set_parameters([Parameter(DESCRIPTION, Parameter.Type.STRING, text)])
        future.add_done_callback(lambda done: self._answered(done.result(), text))

    def _answered(self, response, text: str) -> None:
        self.asked_at = None
        result = response.results[0]
        if self.pending == text:
            self.pending = None  # taken or refused: a refused one is not sent again
        if result.successful:
            self.taken = text
            self.get_logger().info(f"{self.target} took the robot_description ({len(text)} characters)")
        else:
            self.get_logger().error(f"{self.target} refused the robot_description: {result.reason}")


def main(args: argparse.Namespace) -> int:
    return spin_until_done(lambda: DescriptionFeed(args.target), args.ros_args)
