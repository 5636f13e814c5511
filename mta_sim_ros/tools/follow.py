"""``mta follow``: an example closed-loop steering controller of the kind users write.

Pure pursuit of the tractor along a field path (``paths.field_path``: straight passes joined by
headland U-turns). It subscribes ``hitch_poses``, takes the tractor's rear axle B_1 = A_1 - l_1 e_1
as the reference point (its velocity is along e_1: the bicycle model pure pursuit assumes), and
steers towards the path point ``lookahead`` metres ahead:

    alpha = angle from e_1 to (look-ahead point - B_1),  kappa = 2 sin(alpha) / lookahead,
    psi_1 = atan(l_1 kappa)       (B_1 runs on radius l_1 / tan psi_1, MODEL.md)

What matters in the field is where the implement goes: the node measures the lateral error of the
last cart's axle B_n from the path on the straight passes, leaving out the first ``settle`` metres
of each pass (where the train is still straightening out of the turn) and the last train length
(where the tractor has begun the next turn and pulls the implement inwards: on a real headland
the implement is lifted there), and reports max and RMS when the path ends.
"""
from __future__ import annotations

import argparse
import math
import sys

import numpy as np
from geometry_msgs.msg import PoseArray
from rclpy.node import Node
from std_msgs.msg import Float64

from ..config import resolve_config_path
from ..controllers.pursuit.paths import field_path, lateral_error
from ..node.ros_msgs import QOS
from ..physics.loader import SpecError, load_scene
from ..validate import Range, Rule, number_arg, output_file, path_arg
from .maneuver import spin_and_report

#: largest length of the field's passes, their spacing and the look-ahead, m (the path is sampled every 0.25 m)
FIELD_SIZE = 5000.0
FIELD = Rule(f"in (0, {FIELD_SIZE:g}] m", lambda x: 0 < x <= FIELD_SIZE)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", default="scenes/headland_turn.yaml", help="scene giving the train (cart lengths)")
    p.add_argument("--passes", type=number_arg(Range.of(1, 100), int), default=3, help="straight passes (default 3)")
    p.add_argument("--length", type=number_arg(FIELD), default=80.0, help=f"length of a pass, m (default 80; {FIELD.text})")
    p.add_argument("--spacing", type=number_arg(FIELD), default=24.0,
                   help="distance between passes, m (default 24: every other 12 m pass, a 12 m turn radius)")
    p.add_argument("--lookahead", type=number_arg(FIELD), default=6.0,
                   help="pure-pursuit look-ahead distance, m (default 6)")
    p.add_argument("--settle", type=number_arg(Range.of(0.0, FIELD_SIZE, "m")),
                   help="m of each pass left out of the error (default 2 x train length)")
    p.add_argument("--report", type=path_arg(output_file), help="write the error figures to this JSON file")


def cart_axle(msg: PoseArray, k: int, length: float) -> tuple[np.ndarray, float]:
    """(B_k position, heading th_k) from the pose of A_k."""
    pose = msg.poses[k]
    th = 2.0 * math.atan2(pose.orientation.z, pose.orientation.w)
    a = np.array([pose.position.x, pose.position.y])
    return a - length * np.array([math.cos(th), math.sin(th)]), th


class PurePursuit(Node):
    def __init__(self, train, path, lookahead: float, settle: float, max_angle: float):
        super().__init__("mta_follow")
        self.train, self.path, self.lookahead, self.settle, self.max_angle = train, path, lookahead, settle, max_angle
        self.pub = self.create_publisher(Float64, "steering_angle", QOS)
        self.create_subscription(PoseArray, "hitch_poses", self._on_poses, QOS)
        self.tractor_index = 0
        self.implement_index = 0
        self.errors: list[float] = []
        self.done = False
        self.figures: dict = {}
        # arc length along the path, and where each pass starts
        seg = np.hypot(*np.diff(path.xy, axis=0).T)
        self.s = np.concatenate(([0.0], np.cumsum(seg)))
        self.pass_start, self.pass_end = {}, {}
        for i, p in enumerate(path.pass_index):
            self.pass_start.setdefault(int(p), self.s[i])
            self.pass_end[int(p)] = self.s[i]
        self.tail = train_length(train)

    def _on_poses(self, msg: PoseArray) -> None:
        if self.done or len(msg.poses) != self.train.n:
            return
        l1 = self.train.carts[0].length
        b1, th1 = cart_axle(msg, 0, l1)
        self.tractor_index = self.path.nearest(b1, self.tractor_index)
        target_s = self.s[self.tractor_index] + self.lookahead
        if target_s >= self.s[-1]:
            self.done = True
            self.pub.publish(Float64(data=0.0))
            return
        target = self.path.xy[int(np.searchsorted(self.s, target_s))]
        d = target - b1
        alpha = math.atan2(d[1], d[0]) - th1
        kappa = 2.0 * math.sin(alpha) / self.lookahead
        steer = math.atan(l1 * kappa)
        self.pub.publish(Float64(data=max(-self.max_angle, min(self.max_angle, steer))))
        self._measure(msg)

    def _measure(self, msg: PoseArray) -> None:
        last = self.train.n - 1
        bn, _ = cart_axle(msg, last, self.train.carts[last].length)
        self.implement_index = self.path.nearest(bn, self.implement_index)
        i = self.implement_index
        p = int(self.path.pass_index[i])
        if (self.path.straight[i] and self.s[i] - self.pass_start[p] > self.settle
                and self.pass_end[p] - self.s[i] > self.tail):
            self.errors.append(lateral_error(self.path, bn, i))

    def finish(self) -> None:
        e = np.abs(np.array(self.errors)) if self.errors else np.array([math.nan])
        self.figures = {"samples": len(self.errors), "max_m": float(np.max(e)),
                        "rms_m": float(np.sqrt(np.mean(e**2))), "settle_m": self.settle,
                        "lookahead_m": self.lookahead}
        self.get_logger().info(
            f"lateral error of '{self.train.carts[-1].name}' on the straight passes (after {self.settle:.0f} m, "
            f"before the last {self.tail:.0f} m): "
            f"max {self.figures['max_m']:.3f} m, RMS {self.figures['rms_m']:.3f} m over {len(self.errors)} samples")


def train_length(train) -> float:
    return sum(c.length + c.hitch_offset for c in train.carts[:-1]) + train.carts[-1].length


def main(args: argparse.Namespace) -> int:
    try:
        scene = load_scene(resolve_config_path(args.scene))
    except SpecError as err:
        print(f"mta follow: {err}", file=sys.stderr)
        return 2
    ini = scene.initial
    if ini.heading != 0.0:
        print("mta follow: the field path starts along +x: use a scene with initial heading 0", file=sys.stderr)
        return 2
    path = field_path(args.passes, args.length, args.spacing, x0=ini.x, y0=ini.y)
    settle = args.settle if args.settle is not None else 2.0 * train_length(scene.train)
    return spin_and_report(lambda: PurePursuit(scene.train, path, args.lookahead, settle, scene.train.actuator.max_angle),
                           args.ros_args, args.report)
