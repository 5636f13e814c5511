"""``mta field report``: the pictures and the table of a field run.

    mta field report DIR [--out DIR2]

Reads what ``mta field run`` wrote into DIR (trace.npz, coverage.json, metrics.json) and writes
into DIR2 (default DIR), each through a partial file renamed once complete:

- field.png: the field and its obstacles, the plan (swaths, headland rings, the route), every
  cart's path (its axle B_k), and the coverage map: worked ground light green, skipped red,
  double-worked blue, worked outside the field or in an obstacle black;
- tracking.png: the working point's lateral error from the route along the run (working passes
  dark, turns pale), its RMS and p95 on working passes;
- report.md: the figures' table (metrics.md's), the verdict, the excursions, the pictures.

Matplotlib draws without a display (Agg). Exit codes: 0 written; 2 DIR not a field run (a file
missing or unreadable, one line).
"""
from __future__ import annotations

import argparse
import json
import sys
import zipfile
from pathlib import Path

import numpy as np

from .. import validate
from ..validate import EXIT_INPUT, InputError, fail, output_folder, show

INPUTS = ("trace.npz", "coverage.json", "metrics.json")
OUTPUTS = ("field.png", "tracking.png", "report.md")
DPI = 120
#: fill colours of the coverage map
COLOURS = {"worked": "#b7e4a8", "skipped": "#d62728", "double": "#1f4fd6", "outside": "#000000"}


def add_parser(sub) -> None:
    q = sub.add_parser("report", help="a field run's pictures and table: field.png, tracking.png, report.md",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    q.add_argument("run", help="the folder mta field run wrote")
    q.add_argument("--out", help="folder to write into (default: the run's)")
    q.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    try:
        data = read_run(Path(args.run))
        folder = output_folder(args.out or args.run, "--out")
    except InputError as err:
        print(f"mta field report: {err}", file=sys.stderr)
        return EXIT_INPUT
    paths = {name: folder / name for name in OUTPUTS}
    write_report(paths, data)
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0


def read_run(folder: Path) -> dict:
    """The run's trace arrays, shapes and metrics; InputError when DIR is not a field run."""
    import shapely

    for name in INPUTS:
        if not (folder / name).is_file():
            fail("run", show(str(folder)), f"a folder of mta field run (it has no {name})")
    try:
        with np.load(folder / "trace.npz", allow_pickle=False) as npz:
            trace = {k: npz[k] for k in npz.files}
        doc = json.loads((folder / "coverage.json").read_text())
        shapes = {k: shapely.from_wkt(v) for k, v in doc["wkt"].items()}
        metrics = json.loads((folder / "metrics.json").read_text())
        problem = _run_problem(trace, shapes, metrics)
    except (OSError, ValueError, KeyError, TypeError, AttributeError, EOFError, zipfile.BadZipFile,
            shapely.errors.ShapelyError) as err:
        problem = f"{type(err).__name__}: {err}"
    if problem:
        fail("run", show(str(folder)), f"a readable field run ({validate.one_line(problem)[:300]})")
    return {"trace": trace, "shapes": shapes, "metrics": metrics, "markdown": (folder / "metrics.md").read_text()
            if (folder / "metrics.md").is_file() else ""}


def _fill(ax, geometry, colour: str, label: str, alpha: float = 1.0) -> None:
    """Every polygon of ``geometry`` filled (holes left open)."""
    import shapely
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MplPath

    first = True
    for polygon in shapely.get_parts(geometry):
        if polygon.geom_type != "Polygon" or polygon.is_empty:
            continue
        rings = [np.asarray(polygon.exterior.coords)] + [np.asarray(r.coords) for r in polygon.interiors]
        codes = np.concatenate([[MplPath.MOVETO] + [MplPath.LINETO] * (len(r) - 2) + [MplPath.CLOSEPOLY]
                                for r in rings])
        ax.add_patch(PathPatch(MplPath(np.concatenate(rings), codes), facecolor=colour, edgecolor="none",
                               alpha=alpha, label=label if first else None))
        first = False


def _lines(ax, geometry, **style) -> None:
    import shapely

    first = True
    for line in shapely.get_parts(geometry):
        if line.is_empty:
            continue
        xy = np.asarray(line.coords)
        ax.plot(xy[:, 0], xy[:, 1], label=style.pop("label", None) if first else None, **style)
        first = False


#: what the pictures read of a run: the trace's arrays, the coverage's shapes, the metrics' keys
TRACE_KEYS = ("t", "tracking_error", "lowered", "axle", "route_xy", "carts")
SHAPE_KEYS = ("field", "worked", "skipped", "double", "outside", "swaths", "headland_rings")
FIGURE_KEYS = ("tracking_rms_m", "tracking_p95_m", "tracking_max_m")
LINES = ("LineString", "LinearRing")


def _run_problem(trace: dict, shapes: dict, metrics) -> str:
    """'' where a run's files hold what the report reads, in consistent shapes; else what is wrong."""
    missing = [f"trace.npz {k}" for k in TRACE_KEYS if k not in trace] + \
        [f"coverage.json {k}" for k in SHAPE_KEYS if k not in shapes]
    if not isinstance(metrics, dict) or not isinstance(metrics.get("figures"), dict):
        return "metrics.json is not a field run's metrics (no figures)"
    missing += [f"metrics.json {k}" for k in ("field", "train", "verdict") if k not in metrics]
    missing += [f"metrics.json figures.{k}" for k in FIGURE_KEYS if not isinstance(metrics["figures"].get(k), (int, float))]
    if missing:
        return "missing " + ", ".join(missing)
    import shapely

    kinds = {"field": ("Polygon", "MultiPolygon"), "swaths": LINES, "headland_rings": LINES}
    wrong = [f"coverage.json {k} holds a {part.geom_type}" for k, ok in kinds.items()
             for part in shapely.get_parts(shapes[k])[:1] if part.geom_type not in ok]
    if wrong:
        return ", ".join(wrong)
    rows = {k: np.shape(trace[k])[:1] for k in ("t", "tracking_error", "lowered", "axle")}
    if len(set(rows.values())) != 1 or np.ndim(trace["axle"]) != 3 or np.shape(trace["axle"])[1:] != \
            (len(trace["carts"]), 2) or np.ndim(trace["route_xy"]) != 2 or np.shape(trace["route_xy"])[1] != 2:
        return "trace.npz's arrays of inconsistent shapes (" + ", ".join(
            f"{k} {np.shape(trace[k])}" for k in ("t", "tracking_error", "lowered", "axle", "route_xy", "carts")) + ")"
    return ""


def field_figure(data: dict):
    """field.png (module docstring)."""
    from matplotlib.figure import Figure

    shapes, trace = data["shapes"], data["trace"]
    minx, miny, maxx, maxy = shapes["field"].bounds
    width = 10.0
    fig = Figure(figsize=(width, max(4.0, min(14.0, width * (maxy - miny) / max(maxx - minx, 1.0) + 1.5))), dpi=DPI,
                 layout="constrained")
    ax = fig.add_subplot()
    _fill(ax, shapes["worked"], COLOURS["worked"], "worked")
    _fill(ax, shapes["skipped"], COLOURS["skipped"], "skipped")
    _fill(ax, shapes["double"], COLOURS["double"], "worked twice")
    _fill(ax, shapes["outside"], COLOURS["outside"], "worked outside the field")
    _lines(ax, shapes["field"].boundary, color="black", linewidth=1.2, label="boundary, obstacles")
    _lines(ax, shapes["swaths"], color="#555555", linewidth=0.4, linestyle=":", label="swaths (plan)")
    _lines(ax, shapes["headland_rings"], color="#8c564b", linewidth=0.4, linestyle=":", label="headland rings (plan)")
    route = trace["route_xy"]
    ax.plot(route[:, 0], route[:, 1], color="#999999", linewidth=0.3, label="route (working point)")
    for k, name in enumerate(trace["carts"]):
        axle = trace["axle"][:, k]
        ax.plot(axle[:, 0], axle[:, 1], linewidth=0.5, color=f"C{k % 10}", label=f"{name} axle")
    ax.set_aspect("equal")
    ax.set_xlabel("x east, m")
    ax.set_ylabel("y north, m")
    m = data["metrics"]
    ax.set_title(f"{m['field']} worked by {m['train']}: {m['verdict']}")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    return fig


def tracking_figure(data: dict):
    """tracking.png (module docstring)."""
    from matplotlib.figure import Figure

    trace, figures = data["trace"], data["metrics"]["figures"]
    fig = Figure(figsize=(10.0, 3.6), dpi=DPI, layout="constrained")
    ax = fig.add_subplot()
    t = trace["t"] / 60.0
    error = trace["tracking_error"]
    lowered = trace["lowered"].astype(bool)
    ax.plot(t, np.where(lowered, np.nan, error), color="#bbbbbb", linewidth=0.5, label="turns, transits (lifted)")
    ax.plot(t, np.where(lowered, error, np.nan), color="C0", linewidth=0.6, label="working passes")
    ax.set_xlabel("time, min")
    ax.set_ylabel("lateral error of the working point, m")
    ax.set_title(f"Tracking on working passes: RMS {figures['tracking_rms_m']:.3f} m, p95 "
                 f"{figures['tracking_p95_m']:.3f} m, max {figures['tracking_max_m']:.2f} m")
    ax.legend(loc="upper right", fontsize="small")
    ax.grid(alpha=0.3)
    return fig


def report_markdown(data: dict) -> str:
    table = data["markdown"] or json.dumps(data["metrics"]["figures"], indent=1)
    return table.rstrip("\n") + "\n\n## Pictures\n\n![the field, the plan, the paths and the coverage](field.png)\n\n" \
        "![the working point's tracking error](tracking.png)\n"


def write_report(paths: dict, data: dict) -> None:
    """The pictures and the report through their partial files, renamed once all are written."""
    from ..writing import write_together

    def write(temporary: dict) -> None:
        for name, figure in (("field.png", field_figure), ("tracking.png", tracking_figure)):
            with open(temporary[name], "wb") as stream:
                figure(data).savefig(stream, format="png", dpi=DPI)
        temporary["report.md"].write_text(report_markdown(data))

    write_together(paths, write)
