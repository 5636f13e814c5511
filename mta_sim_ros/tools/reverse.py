"""``mta reverse``: an example controller node that backs the train up a straight line or a curve.

The gain is designed from the linear model (controllers/reversing/controller.py: LQR about straight motion at
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
``--report``, written as JSON. A train that folds stops the node's run (its jackknife guard): the
controller hears the halt on /diagnostics, reports what it measured until then with the node's
reason (``stopped``) and exits 1.

Before anything moves it refuses, in one line, exit 2: a train whose traction law ignores the speed;
along the line, a train and speed whose loop with the actuator's limits folds or does not settle
from the nominal start (controllers/reversing/envelope.py; with no weight given, gentler weights are
tried first: controller.held_design); along a circle, one whose steady turn bends a hitch past its
limit (the circle's own loop is not checked).
"""
from __future__ import annotations

import argparse
import sys

from ..validate import InputError, Range, fail, number_arg, output_file, path_arg, show

SPEED = Range.of(-20.0, -0.05, "m/s")
DISTANCE = Range.of(1.0, 10000.0, "m")
WEIGHT = Range.of(1e-6, 1e6)
#: the LQR weights' defaults (controller.design's)
WEIGHTS = {"q_offset": 1.0, "q_hitch": 10.0, "q_heading": 10.0, "r": 1.0}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", default="scenes/reversing.yaml", help="scene giving the train (default scenes/reversing.yaml)")
    p.add_argument("--speed", type=number_arg(SPEED), default=-1.0, help=f"reversing speed V, m/s ({SPEED.text}; default -1)")
    p.add_argument("--distance", type=number_arg(DISTANCE), default=60.0, help="m the last axle reverses (default 60)")
    p.add_argument("--settle", type=number_arg(Range.of(0.0, 10000.0, "m")), default=20.0,
                   help="m of reversing left out of the error (default 20)")
    for name, what in (("q_offset", "the last axle's lateral offset"), ("q_hitch", "each hitch angle"),
                       ("q_heading", "the last cart's heading"), ("r", "the steering command")):
        p.add_argument(f"--{name.replace('_', '-')}", type=number_arg(WEIGHT), help=f"LQR weight of {what} (default "
                       f"{WEIGHTS[name]:g}; with no weight given, the first weights that hold the train: "
                       "controller.held_design)")
    p.add_argument("--radius", type=number_arg(Range.of(5.0, 1e5, "m")),
                   help="back along a circle of this radius (the last axle's), m (default: a straight line)")
    p.add_argument("--side", choices=("left", "right"), default="left", help="the circle's side (default left)")
    p.add_argument("--report", type=path_arg(output_file), help="write the figures to this JSON file")


def main(args: argparse.Namespace) -> int:
    from ..config import resolve_config_path
    from ..controllers.reversing.controller import Reverser, design, design_curve, held_design
    from ..controllers.reversing.reverse_node import ReverseNode
    from ..physics.loader import load_scene
    from ..physics.spec import require_speed_law
    from .maneuver import spin_and_report

    if args.settle >= args.distance:  # it would measure nothing
        fail("--settle", show(args.settle), f"less than --distance {args.distance:g} m (the error is measured "
             "from --settle m of reversing to --distance m)")
    scene = load_scene(resolve_config_path(args.scene))  # a bad scene: cli.main says it in one line, exit 2
    train = scene.train
    require_speed_law(train, "mta reverse")
    given = {name: getattr(args, name) for name in WEIGHTS if getattr(args, name) is not None}
    weights = tuple((WEIGHTS | given).values())
    try:
        curve = None if args.radius is None else design_curve(
            train, args.speed, args.radius, 1.0 if args.side == "left" else -1.0, *weights)
    except ValueError as err:  # a circle tighter than the train can follow ("radius: ..."), or a train refused
        print(f"mta reverse: --{err}" if str(err).startswith("radius: ") else f"mta reverse: {err}", file=sys.stderr)
        return 2
    try:  # along a circle the curve's gain steers (its steady turn checked above); the line's, checked, else
        gains = (design(train, args.speed, *weights, check=False) if curve is not None else
                 design(train, args.speed, *weights) if given else held_design(train, args.speed))
    except InputError as err:  # the speed the loop cannot hold is --speed's
        print(f"mta reverse: --{err}" if str(err).startswith("speed: ") else f"mta reverse: {err}", file=sys.stderr)
        return 2
    reverser = Reverser(train, gains, curve, args.distance, args.settle, args.side)
    return spin_and_report(lambda: ReverseNode(reverser), args.ros_args, args.report)
