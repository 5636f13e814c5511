"""The ROS node of ``mta follow --plan/--field`` (``mta_field_follow``): live.Follow over topics.

Subscribes the node's ``hitch_poses`` (A_k, th_k), ``joint_states`` (psi_1: the steering joint's
position, the last) and ``odom`` (B_1's speed along the tractor's axis: V = v_B1 / cos psi_1), and
answers each tick, once the three messages of one stamp have come (and never one stamp twice: a
lockstep node re-publishes an unanswered tick), with ``steering_angle``, ``speed_setpoint``
(std_msgs/Float64) and ``implement_lowered`` (std_msgs/Bool): one lockstep answer of three topics
(the node's lockstep_answer). QoS ros_msgs.QOS.

Publishes, latched (ros_msgs.LATCHED_QOS: transient local, keep last 1), in the node's frame
(``--frame``, default map: the field's local frame, the frame of hitch_poses): ``plan``
(nav_msgs/Path, a pose a route vertex, field/plan_io.path_message) and ``field_boundary``
(visualization_msgs/MarkerArray: a LINE_STRIP for the outline, one per obstacle), and
``coverage`` (nav_msgs/OccupancyGrid, field/grid.py's values) every second of wall time and once
at the end. A simulator that halts (its /diagnostics at ERROR, halt_watch.py) stops the run at
once, with the node's reason; no pose for ``timeout`` wall seconds stops it too.
"""
from __future__ import annotations

import array
import math
import time

from geometry_msgs.msg import Point, PoseArray, PoseStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, ColorRGBA, Float64
from visualization_msgs.msg import Marker, MarkerArray

from ...physics.terrain import heading_of
from ...field.grid import outlines
from ...field.plan_io import path_message
from ...node.ros_msgs import LATCHED_QOS, QOS
from ..halt_watch import HaltWatch
from .live import DONE, Follow

#: wall s between two coverage grids
GRID_EVERY = 1.0
#: wall s spun after the end, so the last answer and grid reach their readers
LINGER = 1.0


def stamp_of(msg) -> tuple[int, int]:
    return msg.header.stamp.sec, msg.header.stamp.nanosec


class FieldFollowNode(Node):
    def __init__(self, follow: Follow, frame_id: str = "map", timeout: float = 60.0):
        super().__init__("mta_field_follow")
        self.follow, self.frame_id, self.timeout = follow, frame_id, timeout
        self.steer = self.create_publisher(Float64, "steering_angle", QOS)
        self.speed = self.create_publisher(Float64, "speed_setpoint", QOS)
        self.lower = self.create_publisher(Bool, "implement_lowered", QOS)
        self.plan_pub = self.create_publisher(Path, "plan", LATCHED_QOS)
        self.boundary_pub = self.create_publisher(MarkerArray, "field_boundary", LATCHED_QOS)
        self.grid_pub = self.create_publisher(OccupancyGrid, "coverage", LATCHED_QOS)
        self.waiting: dict[tuple, dict] = {}
        self.answered: tuple = (-1, -1)
        self.heard = time.monotonic()
        self.figures: dict = {}
        self.exit_code = 0
        self.linger = LINGER
        self.halt = HaltWatch(self)
        for msg_type, topic in ((PoseArray, "hitch_poses"), (JointState, "joint_states"), (Odometry, "odom")):
            self.create_subscription(msg_type, topic, lambda m, t=topic: self._on(t, m), QOS)
        self.plan_pub.publish(self._path())
        self.boundary_pub.publish(self._boundary())
        self.grid_pub.publish(self._grid())
        self.create_timer(GRID_EVERY, self._each_second, clock=Clock(clock_type=ClockType.STEADY_TIME))

    @property
    def done(self) -> bool:
        if self.halt.reason and not self.follow.done:  # the node halted: no pose will come
            self.follow.status, self.follow.reason = "stopped", self.halt.reason
        return self.follow.done

    def _on(self, topic: str, msg) -> None:
        stamp = stamp_of(msg)
        if self.follow.done or stamp <= self.answered:
            return
        self.heard = time.monotonic()
        parts = self.waiting.setdefault(stamp, {})
        parts[topic] = msg
        if len(parts) == 3:
            self._answer(stamp, parts)

    def _answer(self, stamp: tuple, parts: dict) -> None:
        poses = parts["hitch_poses"].poses
        if len(poses) != self.follow.train.n:
            return
        self.waiting = {s: p for s, p in self.waiting.items() if s > stamp}
        self.answered = stamp
        th = [heading_of(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w) for p in poses]
        points = [(p.position.x, p.position.y) for p in poses]
        psi = parts["joint_states"].position[-1]
        speed = parts["odom"].twist.twist.linear.x / math.cos(psi)
        steering, v_set, lowered = self.follow.answer(points, th, psi, speed)
        self.lower.publish(Bool(data=bool(lowered)))
        self.speed.publish(Float64(data=float(v_set)))
        self.steer.publish(Float64(data=float(steering)))
        if self.follow.done:
            self.grid_pub.publish(self._grid())

    def _each_second(self) -> None:
        self.grid_pub.publish(self._grid())
        if time.monotonic() - self.heard > self.timeout and not self.follow.done:
            self.follow.status, self.follow.reason = "stopped", (
                f"no pose from the node for {self.timeout:g} s (not running, halted, or not in lockstep)")

    def _path(self) -> Path:
        """The plan's route (field/plan_io.path_message's poses)."""
        msg = Path()
        msg.header.frame_id = self.frame_id
        for p in path_message(self.follow.plan, self.frame_id)["poses"]:
            ps = PoseStamped()
            ps.header.frame_id = self.frame_id
            position, orientation = p["pose"]["position"], p["pose"]["orientation"]
            ps.pose.position.x, ps.pose.position.y = position["x"], position["y"]
            ps.pose.orientation.z, ps.pose.orientation.w = orientation["z"], orientation["w"]
            msg.poses.append(ps)
        return msg

    def _boundary(self) -> MarkerArray:
        out = MarkerArray()
        for k, ring in enumerate(outlines(self.follow.plan)):
            m = Marker()
            m.header.frame_id = self.frame_id
            m.ns, m.id, m.type, m.action = ("boundary" if k == 0 else "obstacle"), k, Marker.LINE_STRIP, Marker.ADD
            m.pose.orientation.w = 1.0
            m.scale.x = 0.5
            m.color = ColorRGBA(r=0.1, g=0.6, b=0.1, a=1.0) if k == 0 else ColorRGBA(r=0.8, g=0.2, b=0.1, a=1.0)
            m.points = [Point(x=float(x), y=float(y), z=0.0) for x, y in ring]
            out.markers.append(m)
        return out

    def _grid(self) -> OccupancyGrid:
        grid = self.follow.grid
        msg = OccupancyGrid()
        msg.header.frame_id = self.frame_id
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.info.resolution = float(grid.resolution)
        msg.info.width, msg.info.height = grid.cols, grid.rows
        msg.info.origin.position.x, msg.info.origin.position.y = grid.origin
        msg.info.origin.orientation.w = 1.0
        msg.data = array.array("b", self.follow.grid_values().tobytes())
        return msg

    def finish(self) -> None:
        self.grid_pub.publish(self._grid())
        self.figures = self.follow.figures()
        self.exit_code = 0 if self.follow.status == DONE else 2 if self.follow.status == "refused" else 3
        log = self.get_logger().info if self.exit_code == 0 else self.get_logger().error
        log(self.follow.summary())
