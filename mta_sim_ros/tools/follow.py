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
import sys

from ..config import resolve_config_path
from ..controllers.pursuit.follower import Follower, train_length
from ..controllers.pursuit.paths import field_path
from ..physics.loader import SpecError, load_scene
from ..validate import Range, Rule, number_arg, output_file, path_arg

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


def main(args: argparse.Namespace) -> int:
    from ..controllers.pursuit.follow_node import FollowNode
    from .maneuver import spin_and_report

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
    follower = Follower(scene.train, path, args.lookahead, settle, scene.train.actuator.max_angle)
    return spin_and_report(lambda: FollowNode(follower), args.ros_args, args.report)
