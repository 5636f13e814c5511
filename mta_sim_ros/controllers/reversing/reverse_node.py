"""The ROS node of ``mta reverse`` (``mta_reverse``): controller.Reverser over topics.

It subscribes ``hitch_poses`` (the A_k and headings th_k, from each pose's position and yaw) and
``applied_steering``, and answers each pose with one ``ackermann_cmd``: the steering command and
the speed in one message, one command a tick in lockstep. A simulator that halts (the train
folded: its /diagnostics at ERROR, halt_watch.py) ends the run: what was measured is reported, with
the reason, and the command exits 1.
"""
from __future__ import annotations


from ackermann_msgs.msg import AckermannDriveStamped
from geometry_msgs.msg import PoseArray
from rclpy.node import Node
from std_msgs.msg import Float64

from ...physics.terrain import heading_of
from ...node.ros_msgs import QOS
from ..halt_watch import HaltWatch
from .controller import Reverser


class ReverseNode(Node):
    def __init__(self, reverser: Reverser):
        super().__init__("mta_reverse")
        self.reverser = reverser
        self.pub = self.create_publisher(AckermannDriveStamped, "ackermann_cmd", QOS)
        self.create_subscription(Float64, "applied_steering", self._on_steering, QOS)
        self.create_subscription(PoseArray, "hitch_poses", self._on_poses, QOS)
        self.halt = HaltWatch(self)
        self.figures: dict = {}
        self.exit_code = 0

    @property
    def done(self) -> bool:
        return self.reverser.done or bool(self.halt.reason)

    def _on_steering(self, msg) -> None:
        self.reverser.psi = msg.data

    def _on_poses(self, msg) -> None:
        if self.reverser.done or len(msg.poses) != self.reverser.train.n:
            return
        th = [heading_of(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w) for p in msg.poses]
        points = [(p.position.x, p.position.y) for p in msg.poses]
        out = AckermannDriveStamped()
        out.drive.steering_angle, out.drive.speed = self.reverser.answer(points, th)
        self.pub.publish(out)

    def finish(self) -> None:
        self.figures, self.exit_code = self.halt.report(self.get_logger(), self.reverser.figures(), self.reverser.summary())
