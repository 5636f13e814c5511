"""``mta follow``: an example closed-loop steering controller of the kind users write, or a field
plan worked live (``--plan P`` or ``--field SCENE``, below).

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

With ``--plan P`` (a plan folder of ``mta field plan``, its plan.mcap or plan.csv; the field from
the plan's own record unless ``--field`` names it) or ``--field SCENE`` (a field scene,
config/fieldwork/*.yaml, or a field file: planned now) and ``--train T``, it runs the
implement-tracking controller of ``mta field run`` instead (controllers/implement/live.py and
field_node.py): each tick answered with steering_angle, speed_setpoint and implement_lowered, the
plan (nav_msgs/Path), the field's boundary (visualization_msgs/MarkerArray) and the coverage
(nav_msgs/OccupancyGrid) published for RViz and Foxglove. ``--write-scene DIR`` writes the node's
scene (the train at the route's start) and parameters (lockstep, one answer of three topics) into
DIR and exits: start the node with ``mta node --params-file DIR/sim.yaml``. Exit codes: 0 the
route's end reached, 3 stopped (off the route, no pose from the node), 2 an input refused (one line;
also a node whose train is not at the route's start).
"""
from __future__ import annotations

import argparse
import os
import re
import sys

from ..config import resolve_config_path
from ..controllers.pursuit.follower import Follower, train_length
from ..controllers.pursuit.paths import field_path
from ..physics.loader import SpecError, load_scene
from ..validate import InputError, Range, Rule, fail, number_arg, output_file, path_arg, show

GRID = Range.of(0.05, 10.0, "m")
SPEED = Range("in (0, 20] m/s", lambda v: 0.0 < v <= 20.0)

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
    f = p.add_argument_group("a field plan worked live (instead of the pure-pursuit path)")
    f.add_argument("--plan", help="a plan folder of mta field plan, or its plan.mcap or plan.csv")
    f.add_argument("--field", help="a field scene (fieldwork/*.yaml) or field file: with --plan, the plan's field "
                                   "(default: the one the plan names); alone, planned now")
    f.add_argument("--train", default="trains/default.yaml", help="train YAML with an implement (default "
                                                                  "trains/default.yaml)")
    f.add_argument("--write-scene", metavar="DIR", help="write DIR/scene.yaml (the train at the route's start) and "
                                                        "DIR/sim.yaml (the node's parameters) and exit")
    f.add_argument("--grid", type=number_arg(GRID), default=0.5, help=f"coverage cell size, m ({GRID.text}; "
                                                                       "default 0.5)")
    f.add_argument("--frame", default="map", help="frame of the plan, boundary and coverage (default map: the "
                                                  "node's frame_id)")
    f.add_argument("--timeout", type=number_arg(Range.of(1.0, 3600.0, "s")), default=60.0,
                   help="wall s without a pose from the node before stopping (default 60)")
    f.add_argument("--work-speed", type=number_arg(SPEED), help="m/s on working passes (default: the train's)")
    f.add_argument("--turn-speed", type=number_arg(SPEED), help="m/s in turns (default: the scene's, else 2)")


def main(args: argparse.Namespace) -> int:
    if args.plan or args.field:
        return field_main(args)
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
    if settle >= args.length:  # every straight pass would be left out: it would measure nothing
        fail("--settle", show(settle), f"less than a pass's --length {args.length:g} m (each pass is measured "
             "after its first --settle m; the default is twice the train's length)")
    follower = Follower(scene.train, path, args.lookahead, settle, scene.train.actuator.max_angle)
    return spin_and_report(lambda: FollowNode(follower), args.ros_args, args.report)


# -- a field plan worked live --------------------------------------------------------------------------


def field_inputs(args: argparse.Namespace):
    """(plan, train, settings) of --plan / --field and --train, each checked (InputError)."""
    from ..field.scene import load_field_or_scene
    from ..physics.loader import load_train
    from ..physics.spec import require_speed_law
    from .field_run import load_plan, plan_file, settings_of

    train = load_train(resolve_config_path(args.train))
    from ..field.turning import implement_of

    implement_of(train)
    require_speed_law(train, "mta follow")
    path = plan_file(args.plan) if args.plan else None
    field_path = args.field or (planned_field(path) if path else None)
    scene = load_field_or_scene(resolve_config_path(field_path))
    settings_of(args, scene).speeds(train)  # the drive's speeds, checked before planning
    if path is None:
        from ..field.plan import plan_field

        plan = plan_field(scene.field, train, scene.options(train))
    else:
        planned_for = plan_field_name(path)
        if planned_for is not None and planned_for != scene.field.name:
            fail("--plan", show(str(path)), f"a plan of field {scene.field.name!r} (it is of {planned_for!r})")
        plan = load_plan(path, scene.field, train)
    return plan, train, settings_of(args, scene)


def planned_field(path) -> str:
    """The field file a plan names (its plan.mcap's record, or its plan.csv's first line)."""
    from ..field.plan_io import PLAN_METADATA

    source = ""
    if path.suffix.lower() == ".mcap":
        from ..bag import BagError, read_metadata

        try:
            source = read_metadata(path).get(PLAN_METADATA, {}).get("field_file", "")
        except BagError as err:
            fail("--plan", show(str(path)), f"a readable plan bag ({err})")
    else:
        match = re.match(r"# mta_sim_ros coverage plan of field .* \((.*)\); frame", _first_line(path))
        source = match.group(1) if match else ""
    if not source or not os.path.isfile(source):
        fail("--plan", show(str(path)), f"a plan naming its field file (it names {source!r}): give --field")
    return source


def plan_field_name(path):
    """The field's name a plan was made for (None: it does not say)."""
    from ..field.plan_io import PLAN_METADATA

    if path.suffix.lower() == ".mcap":
        from ..bag import BagError, read_metadata

        try:
            return read_metadata(path).get(PLAN_METADATA, {}).get("field")
        except BagError:
            return None
    match = re.match(r"# mta_sim_ros coverage plan of field (.*) \(", _first_line(path))
    return match.group(1) if match else None


def _first_line(path) -> str:
    with open(path, encoding="utf-8", errors="replace") as f:
        return f.readline(4096)


def field_main(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..controllers.implement.live import Follow, start_files

    try:
        plan, train, settings = field_inputs(args)
        follow = Follow(plan, train, settings, args.grid)
    except (InputError, ValueError) as err:
        print(f"mta follow: {validate_line(err)}", file=sys.stderr)
        return 2
    if args.write_scene:
        scene, params = start_files(Path(args.write_scene), plan, train, settings)
        print(f"wrote {scene} and {params}: start the node with mta node --params-file {params}")
        return 0
    from ..controllers.implement.field_node import FieldFollowNode
    from .maneuver import spin_and_report

    code = spin_and_report(lambda: FieldFollowNode(follow, args.frame, args.timeout), args.ros_args, args.report)
    if follow.status and code:
        print(f"mta follow: {follow.reason}", file=sys.stderr)
    return code


def validate_line(err: Exception) -> str:
    return " ".join(str(err).split())
