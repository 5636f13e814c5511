"""The ROS node of ``mta follow`` (``mta_follow``): follower.Follower over topics. It subscribes
``hitch_poses`` (the A_k and headings th_k, from each pose's position and yaw) and answers each
pose with one ``steering_angle``. A simulator that halts ends the run (halt_watch.py): what was
measured is reported, with the reason, and the command exits 1."""
from __future__ import annotations


from geometry_msgs.msg import PoseArray
from rclpy.node import Node
from std_msgs.msg import Float64

from ...physics.terrain import heading_of
from ...node.ros_msgs import QOS
from ..halt_watch import HaltWatch
from .follower import Follower


class FollowNode(Node):
    def __init__(self, follower: Follower):
        super().__init__("mta_follow")
        self.follower = follower
        self.pub = self.create_publisher(Float64, "steering_angle", QOS)
        self.create_subscription(PoseArray, "hitch_poses", self._on_poses, QOS)
        self.halt = HaltWatch(self)
        self.figures: dict = {}
        self.exit_code = 0

    @property
    def done(self) -> bool:
        return self.follower.done or bool(self.halt.reason)

    def _on_poses(self, msg: PoseArray) -> None:
        if self.follower.done or len(msg.poses) != self.follower.train.n:
            return
        th = [heading_of(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w) for p in msg.poses]
        points = [(p.position.x, p.position.y) for p in msg.poses]
        self.pub.publish(Float64(data=self.follower.steering(points, th)))

    def finish(self) -> None:
        self.figures, self.exit_code = self.halt.report(self.get_logger(), self.follower.figures(), self.follower.summary())
