"""``mta reverse``: an example controller node that backs the train up a straight line or a curve.

The gain is designed from the linear model (mta_sim_ros/reversing.py: LQR about straight motion at
the reversing speed, on the last axle's lateral offset, the hitch angles and the last cart's
heading). The node subscribes ``hitch_poses`` and ``applied_steering`` (the state: A_1's lateral
offset from the line y = 0 of the node's frame, the headings, hitch angles and the steering
angle), and answers each pose with one ``ackermann_cmd``. With ``--radius R`` it backs the last
axle along a circle of radius R instead (``--side`` left or right of the tractor's course): the gain
is designed about that steady turn (reversing.design_curve), the circle placed at the first pose
heard (the train is taken to start on its steady circle), the error the last axle's radial offset (the steering command and the speed, in
one message: one command a tick in lockstep). It measures the lateral error of the last cart's
axle B_n from the line after ``--settle`` m, and stops the train (speed 0) once B_n has reversed
``--distance`` m; max and RMS error, the largest hitch angle and the steering are logged and, with
``--report``, written as JSON. A train that folds stops the node's run (its jackknife guard):
the controller then reports what it saw.
"""
from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from ..validate import Range, number_arg, output_file, path_arg

SPEED = Range.of(-20.0, -0.05, "m/s")
DISTANCE = Range.of(1.0, 10000.0, "m")
WEIGHT = Range.of(1e-6, 1e6)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", default="scenes/reversing.yaml", help="scene giving the train (default scenes/reversing.yaml)")
    p.add_argument("--speed", type=number_arg(SPEED), default=-1.0, help=f"reversing speed V, m/s ({SPEED.text}; default -1)")
    p.add_argument("--distance", type=number_arg(DISTANCE), default=60.0, help="m the last axle reverses (default 60)")
    p.add_argument("--settle", type=number_arg(Range.of(0.0, 10000.0, "m")), default=20.0,
                   help="m of reversing left out of the error (default 20)")
    for name, default, what in (("q-offset", 1.0, "the last axle's lateral offset"), ("q-hitch", 10.0, "each hitch angle"),
                                ("q-heading", 10.0, "the last cart's heading"), ("r", 1.0, "the steering command")):
        p.add_argument(f"--{name}", type=number_arg(WEIGHT), default=default, help=f"LQR weight of {what} (default {default:g})")
    p.add_argument("--radius", type=number_arg(Range.of(5.0, 1e5, "m")),
                   help="back along a circle of this radius (the last axle's), m (default: a straight line)")
    p.add_argument("--side", choices=("left", "right"), default="left", help="the circle's side (default left)")
    p.add_argument("--report", type=path_arg(output_file), help="write the figures to this JSON file")


def main(args: argparse.Namespace) -> int:
    from ackermann_msgs.msg import AckermannDriveStamped
    from geometry_msgs.msg import PoseArray
    from rclpy.node import Node
    from std_msgs.msg import Float64

    from ..config import resolve_config_path
    from ..controllers.reversing.controller import design, design_curve
    from ..node.ros_msgs import QOS
    from ..physics.loader import load_scene
    from .maneuver import spin_and_report

    scene = load_scene(resolve_config_path(args.scene))  # a bad scene: cli.main says it in one line, exit 2
    train = scene.train
    weights = (args.q_offset, args.q_hitch, args.q_heading, args.r)
    try:
        curve = None if args.radius is None else design_curve(
            train, args.speed, args.radius, 1.0 if args.side == "left" else -1.0, *weights)
    except ValueError as err:  # a circle tighter than the train can follow
        print(f"mta reverse: --radius: {err}", file=sys.stderr)
        return 2
    gains = design(train, args.speed, *weights)
    max_angle = train.actuator.max_angle

    class Reverse(Node):
        def __init__(self):
            super().__init__("mta_reverse")
            self.pub = self.create_publisher(AckermannDriveStamped, "ackermann_cmd", QOS)
            self.create_subscription(Float64, "applied_steering", self._on_steering, QOS)
            self.create_subscription(PoseArray, "hitch_poses", self._on_poses, QOS)
            self.psi = 0.0
            self.start_x = None
            self.errors: list[float] = []
            self.centre = self.last_bn = None
            self.hitch, self.steer, self.reversed = 0.0, 0.0, 0.0
            self.done = False
            self.figures: dict = {}

        def _on_steering(self, msg) -> None:
            self.psi = msg.data

        def _on_poses(self, msg) -> None:
            if self.done or len(msg.poses) != train.n:
                return
            th = [2.0 * math.atan2(p.orientation.z, p.orientation.w) for p in msg.poses]
            phis = [math.atan2(math.sin(th[k - 1] - th[k]), math.cos(th[k - 1] - th[k])) for k in range(1, train.n)]
            last = msg.poses[-1].position
            bn = np.array([last.x, last.y]) - train.carts[-1].length * np.array([math.cos(th[-1]), math.sin(th[-1])])
            a1 = np.array([msg.poses[0].position.x, msg.poses[0].position.y])
            if self.start_x is None:
                self.start_x, self.last_bn = bn[0], bn
                if curve is not None:  # the steady circle through the first pose: alpha = th_1 - eta_0
                    alpha = th[0] - curve.point[1]
                    self.centre = a1 - curve.R_A1 * np.array([math.cos(alpha), math.sin(alpha)])
            if curve is None:
                self.reversed = self.start_x - bn[0]
                x = np.array([a1[1], th[0], *phis, self.psi])
                command = gains.command(x, max_angle)
                error = float(bn[1])
            else:
                self.reversed += float(np.hypot(*(bn - self.last_bn)))
                self.last_bn = bn
                r = a1 - self.centre
                alpha = math.atan2(r[1], r[0])
                eta = curve.point[1] + math.remainder(th[0] - alpha - curve.point[1], 2 * math.pi)
                x = np.array([math.hypot(*r) - curve.R_A1, eta, *phis, self.psi])
                command = curve.command(x, max_angle)
                error = float(np.hypot(*(bn - self.centre)) - curve.radius)
            self.hitch = max([self.hitch, *map(abs, phis)])
            self.steer = max(self.steer, abs(self.psi))
            if self.reversed >= args.settle:
                self.errors.append(error)
            stop = self.reversed >= args.distance
            out = AckermannDriveStamped()
            out.drive.steering_angle = command
            out.drive.speed = 0.0 if stop else args.speed * math.cos(command)  # the rear axle's speed
            self.pub.publish(out)
            self.done = stop

        def finish(self) -> None:
            e = np.abs(np.array(self.errors)) if self.errors else np.array([math.nan])
            self.figures = {"path": "straight" if curve is None else f"circle of {curve.radius:g} m, {args.side}",
                            "centre": None if self.centre is None else self.centre.tolist(),
                            "reversed_m": self.reversed, "samples": len(self.errors), "max_m": float(e.max()),
                            "rms_m": float(np.sqrt(np.mean(e ** 2))), "max_hitch_deg": math.degrees(self.hitch),
                            "max_steering_deg": math.degrees(self.steer), "speed_m_s": gains.speed,
                            "gain": (curve or gains).K.ravel().tolist(),
                            "closed_loop": [str(complex(v)) for v in (curve or gains).closed_loop]}
            self.get_logger().info(
                f"reversed {self.reversed:.1f} m at {gains.speed:g} m/s: lateral error of '{train.carts[-1].name}' "
                f"after {args.settle:g} m: max {self.figures['max_m']:.3f} m, RMS {self.figures['rms_m']:.3f} m; "
                f"largest hitch angle {self.figures['max_hitch_deg']:.1f} deg")

    return spin_and_report(Reverse, args.ros_args, args.report)
