"""Routes read back: a plan's own CSV and bag (plan_io.py), and plans exported by others
(Fields2Cover, opennav_coverage): a nav_msgs/Path in an MCAP bag, or a CSV of x, y with or without
a header. Every value is checked; a fault is one line (FieldError, exit code 2).

A plan's own files give the route as written (the bag: its Path and the CSV in its metadata, held
to agree). A foreign route has only points (a Path also the way each pose points). Its flags are
inferred from its geometry: repeated points dropped; heading from each chord, curvature from the
turn at each vertex (route.polyline_arrays); a pose pointing against its motion is driven
backwards; a straight run (no chord turning more than STRAIGHT_TOLERANCE from the run's first) at
least MIN_SWATH_RUN long and driven forwards is a swath (working), everything between swaths a
turn (raised). A transit along a straight line is thus taken for a swath and a curved swath for a
turn: the geometry cannot tell them apart.

Checks: at least 2 distinct points, at most MAX_ROUTE_VERTICES, finite numbers within +-MAX_LOCAL
m, no more than MAX_EXTENT m across, and, given a field, every point within the field's own extent
of its boundary (a route in the absolute coordinates of the field's UTM zone is shifted into its
local frame first, and the notes say so).
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field as dataclass_field
from pathlib import Path

import numpy as np
import shapely

from .. import validate
from ..validate import fail, show
from .boundary import LOCAL, MAX_EXTENT, MAX_LOCAL, FieldError
from .plan import MAX_ROUTE_VERTICES
from .plan_io import CSV_COLUMNS, PLAN_LINE, PLAN_METADATA, PLAN_TOPIC, PLAN_TYPE, SPACING_LINE
from .route import Stretch, assemble, polyline_arrays, wrap
from .types import SEGMENT_KINDS, Route, Segment

#: bytes of a route file read at most
MAX_ROUTE_BYTES = 1 << 28
#: rad: a swath's chords turn at most this far from its first
STRAIGHT_TOLERANCE = math.radians(1.0)
#: m: the shortest straight run taken for a swath
MIN_SWATH_RUN = 10.0


@dataclass(frozen=True)
class ReadRoute:
    route: Route
    segments: tuple
    source: str
    inferred: bool  # flags inferred from the geometry (a foreign route)
    notes: tuple = dataclass_field(default_factory=tuple)


def _fail(what: str, value: str, rule: str, source: str, where: str = "route"):
    fail(what, value, rule, where, source, FieldError)


def read_route(path, field=None) -> ReadRoute:
    """The route of a plan's CSV (.csv) or MCAP bag (.mcap), checked (module docstring)."""
    source = str(path)
    suffix = Path(source).suffix.lower()
    if suffix == ".csv":
        return csv_route(_read_text(path), source, field)
    if suffix == ".mcap":
        return bag_route(path, field)
    _fail("file", show(Path(source).name), "a .csv or .mcap route", source, "document")


def _read_text(path) -> str:
    source = str(path)
    data = validate.read_limited(path, MAX_ROUTE_BYTES, "route file", FieldError)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        _fail("file", f"not UTF-8 ({err.reason})", "a UTF-8 CSV file", source, "document")


# --------------------------------------------------------------------------- CSV


def _number(text: str, what: str, line: int, source: str) -> float:
    try:
        value = float(text)
    except ValueError:
        _fail(what, show(text), "a number", source, f"line {line}")
    if not math.isfinite(value):
        _fail(what, show(text), "finite", source, f"line {line}")
    return value


def _rows(text: str, source: str) -> tuple[list, list, str, str]:
    """(header or [], [(line number, cells)], the spacing comment's value or '', what a plan's own CSV
    says it is of ("NAME (FILE)", its first line past PLAN_LINE up to the frame), or '')."""
    rows, spacing, of = [], "", ""
    for number, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if line.startswith(SPACING_LINE.strip()):
            spacing = line[len(SPACING_LINE.strip()):].strip()
        if line.startswith(PLAN_LINE) and not of:  # "... of field NAME (FILE); frame: ..."
            of = line[len(PLAN_LINE):].rsplit("; frame:", 1)[0]
        if not line or line.startswith("#"):
            continue
        rows.append((number, [c.strip() for c in next(csv.reader(io.StringIO(line)))]))
        if len(rows) > MAX_ROUTE_VERTICES + 1:
            _fail("rows", f"more than {MAX_ROUTE_VERTICES}", f"at most {MAX_ROUTE_VERTICES} route vertices", source)
    if not rows:
        _fail("rows", "none", "at least 2 points x, y", source)
    first = rows[0][1]
    try:
        [float(c) for c in first[:2]]
        return [], rows, spacing, of
    except ValueError:
        return [c.lower() for c in first], rows[1:], spacing, of


def csv_route(text: str, source: str, field=None) -> ReadRoute:
    """A route from CSV text: a plan's own (every column of plan_io.CSV_COLUMNS) or x, y. A plan's own
    made for another field than ``field`` is refused (its swaths and turns are that field's)."""
    header, rows, spacing, of = _rows(text, source)
    if header and not {"x", "y"} <= set(header):
        _fail("header", show(",".join(header)), "columns x and y (or no header: x, y first)", source)
    if header and set(CSV_COLUMNS) <= set(header):
        if field is not None and of and not of.startswith(f"{field.name} ("):  # a name or file may hold " ("
            _fail("field", show(of), f"the field it is run on, {field.name}: a plan is made for one field (mta field "
                  "plan)", source, "plan")
        return _own_route(header, rows, spacing, source, field)
    ix, iy = (header.index("x"), header.index("y")) if header else (0, 1)
    xy = np.empty((len(rows), 2))
    for k, (line, cells) in enumerate(rows):
        if len(cells) <= max(ix, iy):
            _fail("row", show(",".join(cells)), "a point x, y", source, f"line {line}")
        xy[k] = _number(cells[ix], "x", line, source), _number(cells[iy], "y", line, source)
    return points_route(xy, None, source, field)


def _own_route(header: list, rows: list, spacing: str, source: str, field) -> ReadRoute:
    col = {name: header.index(name) for name in CSV_COLUMNS}
    m = len(rows)
    numbers = {name: np.empty(m) for name in ("x", "y", "s", "heading", "curvature")}
    flags = {name: np.empty(m, dtype=int) for name in ("working", "reverse", "segment", "index")}
    kinds = []
    for k, (line, cells) in enumerate(rows):
        if len(cells) < len(header):
            _fail("row", show(",".join(cells)), f"{len(header)} columns", source, f"line {line}")
        for name in numbers:
            numbers[name][k] = _number(cells[col[name]], name, line, source)
        for name in flags:
            value = cells[col[name]]
            if not (value.lstrip("-").isdigit() and len(value) < 10):
                _fail(name, show(value), "an integer", source, f"line {line}")
            flags[name][k] = int(value)
        kinds.append(cells[col["kind"]])
    xy = np.column_stack([numbers["x"], numbers["y"]])
    _check_points(xy, source)
    xy, notes = _in_field(xy, field, source)
    segments = _segments_of(flags, kinds, source)
    s = numbers["s"]
    if m < 2 or not np.all(np.diff(s) > 0.0):
        _fail("s", "not increasing", "increasing from vertex to vertex (at least 2 vertices)", source)
    chord = float(np.max(np.hypot(*np.diff(xy, axis=0).T)))
    step = _number(spacing, "spacing_m", 0, source) if spacing else chord
    route = Route(xy=xy, s=s, heading=numbers["heading"], curvature=numbers["curvature"],
                  working=flags["working"].astype(bool), reverse=flags["reverse"].astype(bool),
                  segment=flags["segment"], spacing=step)
    return ReadRoute(route, segments, source, False, notes)


def _segments_of(flags: dict, kinds: list, source: str) -> tuple:
    """The Segments of a plan's own CSV, each vertex's segment, kind, index and reverse agreeing."""
    for name in ("working", "reverse"):
        if not set(np.unique(flags[name])) <= {0, 1}:
            _fail(name, "not 0 or 1", "0 or 1", source)
    seg = flags["segment"]
    if seg[0] != 0 or not np.all(np.isin(np.diff(seg), (0, 1))):
        _fail("segment", "out of order", "0 at the first vertex, then the same or one more at each next", source)
    starts = np.flatnonzero(np.concatenate([[True], np.diff(seg) != 0]))
    segments = []
    for j, first in enumerate(starts):
        end = starts[j + 1] if j + 1 < len(starts) else len(seg) - 1
        inside = slice(first, max(end, first + 1))
        kind = kinds[first]
        if kind not in SEGMENT_KINDS or any(k != kind for k in kinds[inside]):
            _fail("kind", show(kind), f"one of {', '.join(SEGMENT_KINDS)}, the same along a segment", source)
        for name in ("reverse", "index", "working"):
            if np.any(flags[name][inside] != flags[name][first]):
                _fail(name, f"changes inside segment {j}", "the same along a segment", source)
        segments.append(Segment(kind, int(first), int(end), bool(flags["reverse"][first]), int(flags["index"][first])))
    return tuple(segments)


# --------------------------------------------------------------------------- foreign points


def _check_points(xy: np.ndarray, source: str) -> None:
    if len(xy) > MAX_ROUTE_VERTICES:
        _fail("points", f"{len(xy)}", f"at most {MAX_ROUTE_VERTICES}", source)
    if not np.all(np.isfinite(xy)):
        _fail("points", "not finite", "finite", source)
    if np.max(np.abs(xy), initial=0.0) > MAX_LOCAL:
        _fail("points", f"up to {np.max(np.abs(xy)):.4g} m", f"within +-{MAX_LOCAL:g} m", source)
    extent = float(np.max(np.ptp(xy, axis=0))) if len(xy) else 0.0
    if extent > MAX_EXTENT:
        _fail("points", f"{extent:.6g} m across", f"at most {MAX_EXTENT:g} m across (one field)", source)


def _in_field(xy: np.ndarray, field, source: str) -> tuple[np.ndarray, tuple]:
    """The points in the field's local frame (shifted from its UTM zone's absolute coordinates
    when that is where they lie), each within the field's extent of it."""
    if field is None:
        return xy, ()
    x0, y0, x1, y1 = field.polygon.bounds
    size = max(x1 - x0, y1 - y0)
    notes = ()
    far = shapely.distance(field.polygon, shapely.points(xy))
    if field.crs != LOCAL and np.max(far) > size:
        shifted = xy - np.asarray(field.origin)
        if np.max(shapely.distance(field.polygon, shapely.points(shifted))) <= size:
            xy, far = shifted, shapely.distance(field.polygon, shapely.points(shifted))
            notes = (f"points taken as {field.crs} easting, northing and shifted into the field's local frame",)
    if np.max(far) > size:
        k = int(np.argmax(far))
        _fail(f"point {k}", f"({xy[k, 0]:.6g}, {xy[k, 1]:.6g}), {far[k]:.4g} m from the field",
              f"within the field's extent ({size:.4g} m) of field {field.name}", source)
    return xy, notes


def points_route(xy: np.ndarray, yaw, source: str, field=None) -> ReadRoute:
    """A foreign route from its points (and the way each pose points, if known): module docstring."""
    _check_points(xy, source)
    step = np.hypot(*np.diff(xy, axis=0).T) if len(xy) > 1 else np.zeros(0)
    keep = np.concatenate([[True], step > 1e-9])
    xy = xy[keep]
    if len(xy) < 2:
        _fail("points", f"{len(xy)} distinct", "at least 2 distinct points", source)
    xy, notes = _in_field(xy, field, source)
    heading, curvature = polyline_arrays(xy)
    reverse = np.zeros(len(xy), dtype=bool)
    if yaw is not None:
        reverse = np.abs(wrap(np.asarray(yaw)[keep] - heading)) > 0.5 * math.pi
    stretches = _stretches(xy, heading, curvature, reverse)
    route, segments = assemble(stretches, float(np.max(np.hypot(*np.diff(xy, axis=0).T))))
    return ReadRoute(route, segments, source, True, notes + ("segments inferred from the geometry",))


def _runs(heading: np.ndarray, reverse: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) vertices of the straight runs of one direction, joints shared."""
    runs, first = [], 0
    for i in range(1, len(heading) - 1):
        if reverse[i] != reverse[first] or abs(wrap(heading[i] - heading[first])) > STRAIGHT_TOLERANCE:
            runs.append((first, i))
            first = i
    runs.append((first, len(heading) - 1))
    return runs


def _stretches(xy, heading, curvature, reverse) -> list:
    """Swaths (long forward straight runs) and turns between them (module docstring)."""
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    out: list[Stretch] = []
    swaths = 0
    for first, last in _runs(heading, reverse):
        swath = not reverse[first] and s[last] - s[first] >= MIN_SWATH_RUN
        kind = "swath" if swath else "turn"
        if out and not swath and out[-1].kind == "turn" and out[-1].reverse == bool(reverse[first]):
            prev = out[-1]
            prev.xy = np.vstack([prev.xy[:-1], xy[first:last + 1]])
            prev.heading = np.concatenate([prev.heading[:-1], heading[first:last + 1]])
            prev.curvature = np.concatenate([prev.curvature[:-1], curvature[first:last + 1]])
            continue
        out.append(Stretch(kind, xy[first:last + 1], heading[first:last + 1], curvature[first:last + 1], swath,
                           bool(reverse[first]), swaths if swath else -1))
        swaths += swath
    return out


# --------------------------------------------------------------------------- MCAP


def bag_route(path, field=None) -> ReadRoute:
    """The route of a bag: its plan's own (PLAN_METADATA and PLAN_TOPIC), or the last
    nav_msgs/Path on its one Path topic."""
    from ..bag import BagError, read_messages, read_metadata, summary

    source = str(path)
    try:
        topics = summary(path)
        paths = sorted(t for t, info in topics.items() if info["type"] == PLAN_TYPE)
        if not paths:
            _fail("topics", show(sorted(topics)), f"a topic of {PLAN_TYPE}", source, "bag")
        if len(paths) > 1 and PLAN_TOPIC not in paths:
            _fail("topics", show(paths), f"one topic of {PLAN_TYPE} (or {PLAN_TOPIC})", source, "bag")
        topic = PLAN_TOPIC if PLAN_TOPIC in paths else paths[0]
        message = None
        for _, _, message in read_messages(path, [topic]):
            pass
        metadata = read_metadata(path).get(PLAN_METADATA)
    except BagError as err:
        _fail("file", f"unreadable ({err})", "an MCAP bag", source, "document")
    if message is None or len(message.poses) > MAX_ROUTE_VERTICES:
        _fail(topic, "no message" if message is None else f"{len(message.poses)} poses",
              f"a Path of 2 to {MAX_ROUTE_VERTICES} poses", source, "bag")
    xy = np.array([[p.pose.position.x, p.pose.position.y] for p in message.poses], dtype=float).reshape(-1, 2)
    q = [p.pose.orientation for p in message.poses]
    yaw = np.array([2.0 * math.atan2(o.z, o.w) for o in q])
    if metadata is None or "route_csv" not in metadata:
        return points_route(xy, yaw, source, field)
    own = csv_route(metadata["route_csv"], f"{source} ({PLAN_METADATA})", field)
    if own.route.xy.shape != xy.shape or not np.array_equal(own.route.xy, xy):
        _fail(topic, f"{len(xy)} poses", f"the route of the bag's {PLAN_METADATA} record ({len(own.route.xy)} "
              "vertices, the same points)", source, "bag")
    return ReadRoute(own.route, own.segments, source, False, own.notes)
