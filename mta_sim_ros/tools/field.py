"""``mta field``: field operations.

    mta field plan FIELD [--train T] [--angle DEG] [--overlap F] [--headlands N]
                   [--route auto|boustrophedon|skip] [--turn auto|u|bulb|fishtail] [--out DIR]
    mta field run FIELD [--train T] [--plan P] [--out DIR]      (field_run.py: work it, measure it)
    mta field report DIR [--out DIR2]                           (field_report.py: its pictures)

``plan`` makes the coverage plan of a field (GeoJSON or YAML, config/fields/) for a train's
implement (its working width, the working point the route is for) and writes it into DIR (default
plans/<field name>): plan.geojson (field, headland rings, swaths, route), plan.csv (the route's
arrays) and plan.mcap (one nav_msgs/Path, frame map); then prints a summary: swaths, angle, turns
by kind, headland width, turn radius, route length, target area, and the plan's notes. A bad
field, train or option is refused in one line, exit code 2, before anything is written; the files
are written beside their place and renamed onto it once all three are complete, and none may be
an input.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from pathlib import Path

import numpy as np

from ..validate import EXIT_INPUT, InputError, Range, fail, number_arg, output_folder, show
from ..writing import write_together

OVERLAP = Range("in [0, 0.5)", lambda x: 0.0 <= x < 0.5)
ANGLE = Range.of(-360.0, 360.0, "deg")
OUTPUTS = ("plan.geojson", "plan.csv", "plan.mcap")


def add_arguments(p: argparse.ArgumentParser) -> None:
    from ..field.boundary import MAX_HEADLANDS
    from ..field.types import ROUTES, TURNS

    sub = p.add_subparsers(dest="field_command", required=True, metavar="ACTION")
    q = sub.add_parser("plan", help="the coverage plan of a field for a train: GeoJSON, CSV, nav_msgs/Path",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    q.add_argument("field", help="field file: GeoJSON (WGS84) or YAML (local metres), e.g. fields/rectangle.yaml, "
                                 "or a field scene (fieldwork/*.yaml: a field and its plan's options)")
    q.add_argument("--train", default="trains/default.yaml",
                   help="train YAML with an implement (default trains/default.yaml)")
    q.add_argument("--angle", type=number_arg(ANGLE), help="swath direction, deg from east counterclockwise "
                                                           "(default: the angle with the fewest swaths)")
    q.add_argument("--overlap", type=number_arg(OVERLAP),
                   help="share of the width neighbouring swaths overlap (default: the scene's, else 0)")
    q.add_argument("--headlands", type=number_arg(Range.of(0, MAX_HEADLANDS), int),
                   help="headland rings (default: the field's, more if the train's turns need them)")
    q.add_argument("--route", choices=ROUTES, help="swath order (default: the scene's, else auto)")
    q.add_argument("--turn", choices=TURNS, help="headland turn kind (default: the scene's, else auto)")
    q.add_argument("--out", help="folder to write into (default plans/<field name>)")
    q.set_defaults(func=main)
    from . import field_report, field_run

    field_run.add_parser(sub)
    field_report.add_parser(sub)


def main(args: argparse.Namespace) -> int:
    try:
        return plan_main(args)
    except InputError as err:
        print(f"mta field {args.field_command}: {err}", file=sys.stderr)
        return EXIT_INPUT


def plan_main(args: argparse.Namespace) -> int:
    from ..config import resolve_config_path
    from ..field.plan import plan_field
    from ..field.scene import load_field_or_scene
    from ..field.turning import implement_of
    from ..physics.loader import load_train

    scene = load_field_or_scene(resolve_config_path(args.field))
    field = scene.field
    train = load_train(resolve_config_path(args.train))
    implement_of(train)
    paths = output_paths(args, field, train)
    given = {"overlap": args.overlap, "angle": None if args.angle is None else math.radians(args.angle),
             "headlands": args.headlands, "route": args.route, "turn": args.turn}
    options = dataclasses.replace(scene.options(train), **{k: v for k, v in given.items() if v is not None})
    plan = plan_field(field, train, options)
    write_plan(plan, paths)
    print(summary(plan, train))
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0


def output_paths(args: argparse.Namespace, field, train) -> dict[str, Path]:
    """The three files in the output folder, checked before any work: none of them an input."""
    from ..field.boundary import default_folder

    folder = output_folder(args.out or default_folder("plans", field), "--out")
    paths = {name: folder / name for name in OUTPUTS}
    for path in paths.values():
        for source in (field.source, train.source):
            if source and Path(source).exists() and path.resolve() == Path(source).resolve():
                fail("--out", show(str(folder)), f"a folder whose {path.name} is not the input {source}")
    return paths


def write_plan(plan, paths: dict[str, Path]) -> None:
    """All three files through partial ones, renamed onto their places once all are written."""
    from ..field.plan_io import geojson_text, route_csv, write_bag

    def write(temporary: dict[str, Path]) -> None:
        temporary["plan.geojson"].write_text(geojson_text(plan))
        temporary["plan.csv"].write_text(route_csv(plan))
        write_bag(plan, temporary["plan.mcap"])

    write_together(paths, write)


def summary(plan, train) -> str:
    """What ``mta field plan`` prints."""
    from ..field.plan import turn_kinds

    kinds = turn_kinds(plan)
    field = plan.field
    working = float(np.diff(plan.route.s)[plan.route.working[:-1]].sum())
    lines = [f"field {field.name} ({field.source}), {field.area / 1e4:.2f} ha; train {train.name}, implement "
             f"{plan.options.width:g} m",
             f"swaths {len(plan.swaths)} at {math.degrees(plan.angle):.1f} deg, spacing "
             f"{plan.options.width * (1 - plan.options.overlap):.2f} m",
             "turns " + (", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) or "none"),
             f"headland {plan.headland_width:.1f} m, turn radius {plan.turn_radius:.2f} m",
             f"route {plan.route.s[-1] / 1e3:.2f} km ({working / 1e3:.2f} km working, {plan.route.s.size} vertices), "
             f"target {plan.target.area / 1e4:.2f} ha"]
    lines += [f"  - {note}" for note in plan.notes]
    return "\n".join(lines)
