"""``mta field run``: work a field offline, closed loop, and measure what it cost.

    mta field run FIELD [--train T] [--plan P] [--out DIR] [--work-speed V] [--turn-speed V]

The whole field is simulated without ROS (controllers/implement: the implement's working point
kept on the plan's route, lifted in turns, the dynamic level, compiled), then its coverage and
figures are read off the trace (field/coverage.py). The plan is ``mta field plan``'s for the
field and the train (default options), or the one in P: a folder ``mta field plan`` wrote, or its
plan.mcap or plan.csv. P's route is driven; the ground around it (inner field, target, swaths,
headland rings) is laid out again from the field, the train and, from a plan.mcap, the options it
was planned with (a plan.csv carries none: the defaults).

Writes into DIR (default runs/<field name>), each through a partial file renamed once complete:
trace.npz (numpy's uncompressed npz: the FieldTrace's arrays, one row a tick, and the
controller's station, steering, command and set speed), coverage.json (the field, the plan's
ground and the coverage map as WKT in the field's local frame, x east, y north, m), metrics.json
and metrics.md (the figures, the verdict, the footprint's excursions, where the time went; a
figure that cannot be had, as fuel without the train's fuel, is null). ``mta field report DIR``
draws them.

Exit codes: 0 worked to the route's end; 3 stopped by a guard (a jackknife, the working point off
the route, out of time): the files are written up to where it stopped; 2 an input refused (one
line: the field, the value and the rule), nothing written.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

from typing import TYPE_CHECKING

import numpy as np

from ..validate import EXIT_INPUT, InputError, Range, fail, number_arg, output_folder, show
from ..writing import finite_or_none

if TYPE_CHECKING:
    from ..controllers.implement.work import Work

EXIT_STOPPED = 3
OUTPUTS = ("trace.npz", "coverage.json", "metrics.json", "metrics.md")
SPEED = Range("in (0, 20] m/s", lambda v: 0.0 < v <= 20.0)


def add_parser(sub) -> None:
    q = sub.add_parser("run", help="work a field closed loop offline and measure it: trace, coverage, figures",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    q.add_argument("field", help="field file: GeoJSON (WGS84) or YAML (local metres), e.g. fields/kuban.geojson, "
                                 "or a field scene (fieldwork/*.yaml: a field, its plan's options, its speeds)")
    q.add_argument("--train", default="trains/default.yaml", help="train YAML with an implement "
                                                                 "(default trains/default.yaml)")
    q.add_argument("--plan", help="a plan folder of mta field plan, or its plan.mcap or plan.csv "
                                  "(default: the field planned now with default options)")
    q.add_argument("--out", help="folder to write into (default runs/<field name>)")
    q.add_argument("--work-speed", type=number_arg(SPEED), help="m/s on working passes (default: the train's "
                                                                 "set speed)")
    q.add_argument("--turn-speed", type=number_arg(SPEED), help="m/s in turns (default: the scene's, else 2)")
    q.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from ..controllers.implement.work import work_field

    t0 = time.perf_counter()
    try:
        scene, train, paths, plan_path = inputs(args)
        field = scene.field
        loaded = time.perf_counter() - t0
        t = time.perf_counter()
        plan = load_plan(plan_path, field, train) if plan_path else None
        read = time.perf_counter() - t
        work = work_field(field, train, scene.options(train), settings_of(args, scene), plan=plan)
    except InputError as err:
        print(f"mta field run: {err}", file=sys.stderr)
        return EXIT_INPUT
    if plan is not None:
        work.timings["plan"] = read
    work.timings = {"inputs": loaded, **work.timings}
    t = time.perf_counter()
    write_run(paths, work)
    work.timings["write"] = time.perf_counter() - t
    work.timings["total"] = time.perf_counter() - t0
    print(summary(work))
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    if work.run.trace.verdict != "ok":
        print(f"mta field run: stopped: {work.run.trace.reason}", file=sys.stderr)
        return EXIT_STOPPED
    return 0


def settings_of(args: argparse.Namespace, scene):
    """The drive's settings: the scene's, each flag given in place of its own."""
    from ..controllers.implement.design import Settings

    given = {"work_speed": args.work_speed, "turn_speed": args.turn_speed}
    return Settings(**{**scene.drive, **{k: v for k, v in given.items() if v is not None}})


def inputs(args: argparse.Namespace):
    """(field scene, train, output paths, plan path or None), every one checked before any work."""
    from ..config import resolve_config_path
    from ..field.boundary import default_folder
    from ..field.scene import load_field_or_scene
    from ..field.turning import implement_of
    from ..physics.loader import load_train
    from ..physics.spec import require_speed_law

    scene = load_field_or_scene(resolve_config_path(args.field))
    field = scene.field
    train = load_train(resolve_config_path(args.train))
    implement_of(train)
    require_speed_law(train, "mta field run")
    settings_of(args, scene).speeds(train)  # the drive's speeds, before any folder is made
    plan_path = plan_file(args.plan) if args.plan else None
    folder = output_folder(args.out or default_folder("runs", field), "--out")
    paths = {name: folder / name for name in OUTPUTS}
    for path in paths.values():
        for source in (field.source, train.source, plan_path):
            if source and Path(source).exists() and path.resolve() == Path(source).resolve():
                fail("--out", show(str(folder)), f"a folder whose {path.name} is not the input {source}")
    return scene, train, paths, plan_path


def plan_file(path: str) -> Path:
    """The route file of --plan: the path, or the plan.mcap (else plan.csv) of a plan folder."""
    p = Path(path)
    if p.is_dir():
        for name in ("plan.mcap", "plan.csv"):
            if (p / name).is_file():
                return p / name
        fail("--plan", show(path), "a plan folder holding plan.mcap or plan.csv (mta field plan --out)")
    if not p.is_file():
        fail("--plan", show(path), "an existing plan folder, plan.mcap or plan.csv")
    return p


def planned_options(path: Path, train):
    """The PlanOptions a plan.mcap was made with (its metadata), else the defaults for ``train``."""
    from ..field.plan_io import PLAN_METADATA
    from ..field.types import PlanOptions

    width = train.implement.width
    if path.suffix.lower() != ".mcap":
        return PlanOptions(width=width)
    from ..bag import BagError, read_metadata

    try:
        stored = json.loads(read_metadata(path).get(PLAN_METADATA, {}).get("options", "{}"))
    except (BagError, ValueError) as err:
        fail("--plan", show(str(path)), f"a plan bag whose {PLAN_METADATA} options are readable ({err})")
    known = {k: v for k, v in stored.items() if k in PlanOptions.__dataclass_fields__}
    options = PlanOptions(**{**known, "width": known.get("width", width)})
    if not math.isclose(options.width, width, rel_tol=1e-9):
        fail("--plan", show(str(path)), f"a plan for this train's {width:g} m implement (it is for "
                                        f"{options.width:g} m)")
    return options


def load_plan(path: Path, field, train):
    """The plan of ``path`` (module docstring): its route, on the ground laid out again."""
    from ..field.plan import plan_field
    from ..field.route_io import read_route

    read = read_route(path, field)
    ground = plan_field(field, train, planned_options(path, train))
    same = read.route.xy.shape == ground.route.xy.shape and np.allclose(read.route.xy, ground.route.xy, atol=1e-6)
    notes = ground.notes + read.notes + ((f"route read from {path}"
                                          + ("" if same else "; it differs from the route laid out again here: "
                                             "the ground (inner, target, swaths) is the one laid out")),)
    return dataclasses.replace(ground, route=read.route, segments=read.segments, notes=notes)


# -- what is written -----------------------------------------------------------------------------------


def trace_arrays(work: Work) -> dict:
    """The arrays of trace.npz: the FieldTrace's, the controller's extra columns, the carts' names."""
    from ..controllers.implement.drive import EXTRA

    trace = work.run.trace
    arrays = {name: getattr(trace, name) for name in ("t", "implement", "lowered", "segment", "tracking_error",
                                                     "axle", "heading", "hitch_angle", "margin", "speed", "power")}
    arrays.update({name: work.run.rows[:, column] for name, column in EXTRA.items()})
    arrays.update(tick=np.array(trace.tick), carts=np.array([c.name for c in work.train.carts]),
                  segment_kind=np.array([s.kind for s in work.plan.segments] or ["swath"]),
                  route_xy=work.plan.route.xy, route_working=work.plan.route.working,
                  route_reverse=work.plan.route.reverse)
    return arrays


def coverage_document(work: Work) -> dict:
    """coverage.json: the field, the plan's ground and the coverage map as WKT (local frame)."""
    from shapely import geometry as sg

    plan, cov = work.plan, work.result.coverage
    shapes = {"field": plan.field.polygon, "inner": plan.inner, "target": plan.target,
              "swaths": sg.MultiLineString(list(plan.swaths)), "headland_rings": sg.MultiLineString(
                  list(plan.headland_rings)), "worked": cov.worked, "skipped": cov.skipped, "double": cov.double,
              "outside": cov.outside, **{f"skipped_{c}": g for c, g in cov.skipped_by.items()}}
    return {"frame": "the field's local metric frame: x east, y north, m (field.crs shifted by field.origin)",
            "crs": plan.field.crs, "origin": list(plan.field.origin), "field_name": plan.field.name,
            "wkt": {name: g.wkt for name, g in shapes.items()}}


def metrics_document(work: Work) -> dict:
    result, run, plan = work.result, work.run, work.plan
    return {"field": plan.field.name, "field_file": plan.field.source, "train": work.train.name,
            "train_file": work.train.source, "verdict": result.verdict, "reason": result.reason,
            "figures": {k: v if math.isfinite(v) else None for k, v in result.values.items()},
            "excursions": [dataclasses.asdict(e) for e in result.excursions],
            "timings_s": work.timings, "plan_notes": list(plan.notes),
            "accuracy": {"position_error_m": finite_or_none(work.accuracy.error), "tolerance_m": work.accuracy.tolerance,
                         "meets": work.accuracy.meets, "estimate": work.accuracy.how, "line": work.accuracy.line()},
            "controller": {"speeds_m_s": list(run.controller.speeds), "lead_s": run.controller.lead,
                           "forward_angle_deg": math.degrees(run.controller.forward_angle),
                           "gains": [g.K.tolist() for g in run.controller.gains],
                           "settings": dataclasses.asdict(run.controller.settings), "rk4_step_s": run.step,
                           "compiled": run.compiled, "right_hand_sides": run.nfev}}


def metrics_markdown(work: Work) -> str:
    from ..field.coverage import markdown

    plan = work.plan
    head = [f"# Field run: {plan.field.name} with {work.train.name}", "",
            f"Field {plan.field.source}, train {work.train.source}; {len(plan.swaths)} swaths, route "
            f"{plan.route.s[-1] / 1e3:.2f} km.", ""]
    times = ", ".join(f"{k} {v:.2f} s" for k, v in work.timings.items())
    return ("\n".join(head) + markdown(work.result) + f"\nAccuracy: {work.accuracy.line()} (docs/accuracy.md).\n"
            f"\nWhere the time went: {times}.\n")


def write_run(paths: dict, work: Work) -> None:
    """Every output through its partial file, renamed once all are written."""
    from ..writing import write_together

    def write(temporary: dict) -> None:
        with open(temporary["trace.npz"], "wb") as stream:
            np.savez(stream, **trace_arrays(work))  # uncompressed: 15 MB for 2 h in 0.03 s, zlib 10 MB in 0.6 s
        temporary["coverage.json"].write_text(json.dumps(coverage_document(work)) + "\n")
        temporary["metrics.json"].write_text(json.dumps(metrics_document(work), indent=1, default=float,
                                                        allow_nan=False) + "\n")
        temporary["metrics.md"].write_text(metrics_markdown(work))

    write_together(paths, write)


def summary(work: Work) -> str:
    v = work.result.values
    verdict = work.result.verdict + (f" ({work.result.reason})" if work.result.reason else "")
    return "\n".join([
        f"field {work.plan.field.name}: {v['field_area_ha']:.2f} ha, worked {v['worked_area_ha']:.2f} ha "
        f"({v['coverage_pct']:.1f} % of the target), skipped {v['skipped_area_ha']:.3f} ha, twice "
        f"{v['double_worked_ha']:.3f} ha",
        f"time {v['total_time_h']:.2f} h (turns {v['turn_time_h']:.2f} h, efficiency "
        f"{v['field_efficiency_pct']:.1f} %), energy {v['energy_kWh']:.0f} kWh, fuel {v['fuel_l']:.1f} l",
        f"tracking error on working passes: RMS {v['tracking_rms_m']:.3f} m, p95 {v['tracking_p95_m']:.3f} m, "
        f"max {v['tracking_max_m']:.2f} m; footprint outside {v['excursions']:.0f} times",
        f"verdict {verdict}; {work.accuracy.line()}",
        "time: " + ", ".join(f"{k} {s:.2f} s" for k, s in work.timings.items())])
