"""What working a field cost: the ground worked, skipped and worked twice, the train's footprint
outside the field, time, energy, fuel and tracking, read off a ``FieldTrace`` (no dynamics here).
Areas are shapely's, in the field's local metric frame.

Worked ground. While the implement is lowered (trace.lowered[i]: from row i to row i + 1) its
working bar, ``width`` wide and centred on the working point W, lies across the implement cart's
axis (trace.heading): the strip it sweeps between two rows is the quadrilateral of the bar's two
positions, and a lowered stretch's strip is the polygon of its left ends forward and its right
ends back. The bar's ends move on straight chords between rows: on a curve of radius R the strip
misses the sagitta ds^2 / (8 R) per chord on its outer edge (0.3 m chords at 3 m/s and 10 Hz, R =
10 m: 1 mm) and adds as much on the inner one. Unlike a buffer of W's path, the strip is as wide
as the bar across the cart's heading, not across the path: where the cart crabs (the working
point ahead of its axle in a turn) it is narrower across the path, as the real bar is. A stretch is
cut into pieces that turn at most 90 deg each (a piece then does not overlap itself where R >
width / 2); where the inner end still runs backwards (R < width / 2) its quadrilaterals are
joined one by one. Each piece is simplified to SIMPLIFY m (its area changes by at most that times
its perimeter).

    worked          union of the pieces, inside the field (field.polygon: obstacles are holes)
    skipped         plan.target minus worked, split by cause, one connected piece at a time:
                      boundary  a quarter or more of its outline lies on the field's boundary or an
                                obstacle's (within 1 cm): the passes did not reach the edge
                      turns     else, half or more of its area lies in the headland band (field
                                minus plan.inner) or in a swath's end zone (the first and last
                                ``width`` m of each plan.swaths line, ``width`` across): lowered
                                late, lifted early, or not yet back on the line after a turn
                      tracking  the rest: slivers between neighbouring passes along their length
    double-worked   ground inside the field under two or more pieces (pairs of pieces
                    intersected: a piece's own overlap where R < width / 2 is not counted)
    worked outside  worked ground beyond the boundary or in an obstacle

Footprints: each cart's box (physics/outline.box_of, the one RViz draws) at every row, against the
field grown by ON_BOUNDARY (a box's edge on the boundary, as a seeder's on the outer headland
pass, is inside): rows where a box is not inside the boundary, or reaches into an obstacle, are
grouped into excursions (cart, kind, from, to, where: the middle of the part outside at its
largest).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely import geometry as sg

from ..compat import trapezoid
from ..physics.outline import box_of
from .types import FieldTrace

#: m: the tolerance each strip piece is simplified to
SIMPLIFY = 1e-3
#: rad: a strip piece turns at most this much
PIECE_TURN = 0.5 * math.pi
#: m: a skipped piece's outline this close to the field's boundary lies on it
ON_BOUNDARY = 0.01
#: the share of its outline on the boundary that makes a skipped piece the boundary's
BOUNDARY_SHARE = 0.25
#: the share of its area in the headland band or the swaths' end zones that makes it the turns'
TURNS_SHARE = 0.5
#: kg per litre of diesel (EN 590: 0.820 - 0.845 at 15 C)
DIESEL_DENSITY = 0.835
CAUSES = ("boundary", "turns", "tracking")


@dataclass
class Coverage:
    """The ground of a field worked (module docstring); every value a shapely geometry."""

    pieces: list  # the strip pieces, Polygons
    worked: object
    skipped: object
    skipped_by: dict  # cause -> geometry
    double: object
    outside: object


@dataclass
class Excursion:
    """A cart's footprint outside the boundary or in an obstacle over rows first..last."""

    cart: str
    kind: str  # "outside the boundary" | "in an obstacle"
    first: float  # s
    last: float  # s
    where: tuple  # (x, y) m: the middle of the part outside, at its largest
    area: float  # m^2: the largest part outside

    def line(self) -> str:
        return (f"{self.cart} {self.kind} from t = {self.first:.1f} s to {self.last:.1f} s, at ({self.where[0]:.1f}, "
                f"{self.where[1]:.1f}) m, up to {self.area:.1f} m^2")


def implement_cart(train) -> int:
    return train.cart_index(train.implement.cart)


def lowered_stretches(lowered: np.ndarray) -> list[tuple[int, int]]:
    """(first row, last row) of each lowered stretch: rows a..b with lowered[a..b-1] true."""
    flags = np.concatenate(([False], np.asarray(lowered[:-1], dtype=bool), [False]))
    edges = np.flatnonzero(flags[1:] != flags[:-1])
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def bar_ends(trace: FieldTrace, cart: int, width: float) -> tuple[np.ndarray, np.ndarray]:
    """(left ends, right ends) of the working bar at every row, (r, 2) each."""
    th = trace.heading[:, cart]
    normal = np.column_stack((-np.sin(th), np.cos(th))) * (0.5 * width)
    return trace.implement + normal, trace.implement - normal


def strip_pieces(trace: FieldTrace, cart: int, width: float) -> list:
    """The lowered stretches' strips, cut where they turn PIECE_TURN (module docstring)."""
    left, right = bar_ends(trace, cart, width)
    turn = np.abs(np.diff(np.unwrap(trace.heading[:, cart])))
    pieces = []
    for a, b in lowered_stretches(trace.lowered):
        share = np.floor(np.cumsum(turn[a:b]) / PIECE_TURN)  # quadrilateral a + q turns it past q x PIECE_TURN
        cuts = [a, *(a + 1 + np.flatnonzero(np.diff(share) > 0)), b]
        pieces += [_strip(left[p:q + 1], right[p:q + 1]) for p, q in zip(cuts[:-1], cuts[1:]) if q > p]
    return [shapely.simplify(p, SIMPLIFY) for p in pieces if not p.is_empty]


def _strip(left: np.ndarray, right: np.ndarray):
    polygon = sg.Polygon(np.vstack((left, right[::-1])))
    if polygon.is_valid:
        return polygon
    quads = shapely.polygons(np.stack((left[:-1], left[1:], right[1:], right[:-1]), axis=1))
    return shapely.union_all(shapely.make_valid(quads))


def coverage(trace: FieldTrace, train) -> Coverage:
    """The ground the trace worked (module docstring), with the train's implement width."""
    plan = trace.plan
    land = plan.field.polygon
    width = train.implement.width
    pieces = strip_pieces(trace, implement_cart(train), width)
    swept = shapely.union_all(pieces) if pieces else sg.Polygon()
    worked = swept.intersection(land)
    skipped = plan.target.difference(worked)
    double = sg.Polygon()
    if len(pieces) > 1:
        tree = shapely.STRtree(pieces)
        i, j = tree.query(pieces, predicate="intersects")
        keep = i < j
        every = np.asarray(pieces, dtype=object)
        parts = shapely.intersection(every[i[keep]], every[j[keep]])
        double = shapely.union_all(parts).intersection(land) if parts.size else double
    return Coverage(pieces, worked, skipped, skip_causes(skipped, trace, width), _polygonal(double),
                    _polygonal(swept.difference(land)))


def _polygonal(geometry):
    """The polygons of a geometry (a line or point where pieces touch has no area)."""
    parts = [g for g in shapely.get_parts(geometry) if g.geom_type in ("Polygon", "MultiPolygon") and g.area > 0.0]
    return shapely.union_all(parts) if parts else sg.Polygon()


def end_zones(plan, width: float):
    """The first and last ``width`` m of every swath, ``width`` across (module docstring)."""
    zones = []
    for swath in plan.swaths:
        xy = np.asarray(swath.coords)
        for p, q in ((xy[0], xy[1]), (xy[-1], xy[-2])):
            t = (q - p) / max(float(np.hypot(*(q - p))), 1e-12)
            n = np.array([-t[1], t[0]]) * (0.5 * width)
            zones.append(sg.Polygon([p + n, p - n, p - n + width * t, p + n + width * t]))
    return shapely.union_all(zones) if zones else sg.Polygon()


def skip_causes(skipped, trace: FieldTrace, width: float) -> dict:
    """The skipped ground split by cause, piece by piece (module docstring's rule)."""
    plan = trace.plan
    edge = plan.field.polygon.boundary.buffer(ON_BOUNDARY)
    turning = plan.field.polygon.difference(plan.inner).union(end_zones(plan, width))
    shapely.prepare(edge)
    shapely.prepare(turning)
    found = {cause: [] for cause in CAUSES}
    for piece in shapely.get_parts(_polygonal(skipped)):
        outline = piece.boundary
        if outline.length > 0.0 and outline.intersection(edge).length >= BOUNDARY_SHARE * outline.length:
            found["boundary"].append(piece)
        elif piece.intersection(turning).area >= TURNS_SHARE * piece.area:
            found["turns"].append(piece)
        else:
            found["tracking"].append(piece)
    return {cause: shapely.union_all(parts) if parts else sg.Polygon() for cause, parts in found.items()}


# -- the footprints ---------------------------------------------------------------------------------


def boxes(trace: FieldTrace, train, k: int, rows: np.ndarray) -> np.ndarray:
    """Cart k's box at ``rows`` as shapely Polygons."""
    centre, length, width, _ = box_of(train, k)
    th = trace.heading[rows, k]
    e = np.column_stack((np.cos(th), np.sin(th)))
    n = np.column_stack((-e[:, 1], e[:, 0]))
    b = trace.axle[rows, k]
    corners = [b + (centre + sa * length / 2) * e + (sb * width / 2) * n
               for sa, sb in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
    return shapely.polygons(np.stack(corners, axis=1))


def excursions(trace: FieldTrace, train) -> list[Excursion]:
    """Every cart's footprint outside the boundary or in an obstacle, as runs of rows. A box whose
    centre lies farther inside than its half diagonal is inside: only the others are tested."""
    land = trace.plan.field.polygon.buffer(ON_BOUNDARY)  # a box's edge on the boundary is inside
    shell = sg.Polygon(land.exterior)
    shapely.prepare(land)
    shapely.prepare(shell)
    found = []
    for k, cart in enumerate(train.carts):
        centre, length, width, _ = box_of(train, k)
        core = land.buffer(-0.5 * math.hypot(length, width))
        shapely.prepare(core)
        th = trace.heading[:, k]
        middle = trace.axle[:, k] + centre * np.column_stack((np.cos(th), np.sin(th)))
        near = np.flatnonzero(~shapely.contains_xy(core, middle[:, 0], middle[:, 1]))
        box = boxes(trace, train, k, near)
        inside = shapely.covered_by(box, land)
        out_rows, box = near[~inside], box[~inside]
        if not out_rows.size:
            continue
        beyond = ~shapely.covered_by(box, shell)
        for kind, pick in (("outside the boundary", beyond), ("in an obstacle", ~beyond)):
            rows = out_rows[pick]
            outside = shapely.difference(box[pick], shell if kind.startswith("outside") else land)
            areas = shapely.area(outside)
            for run in np.split(np.arange(rows.size), np.flatnonzero(np.diff(rows) > 1) + 1):
                if not run.size:
                    continue
                worst = run[int(np.argmax(areas[run]))]
                spot = outside[worst].centroid if areas[worst] > 0.0 else box[pick][worst].centroid
                found.append(Excursion(cart.name, kind, float(trace.t[rows[run[0]]]), float(trace.t[rows[run[-1]]]),
                                       (spot.x, spot.y), float(areas[worst])))
    return sorted(found, key=lambda e: e.first)


# -- the figures --------------------------------------------------------------------------------------


@dataclass
class FieldMetrics:
    """The figures of a field worked (``metrics``) and what they were read from."""

    values: dict  # name (unit in its suffix) -> float
    coverage: Coverage
    excursions: list = field(default_factory=list)
    verdict: str = "ok"
    reason: str = ""


def metrics(trace: FieldTrace, train) -> FieldMetrics:
    """Every figure of the issue's list (``names``), from the trace alone."""
    plan = trace.plan
    cov = coverage(trace, train)
    ha = 1e-4
    t = trace.t
    dt = np.diff(t)
    kinds = np.array([s.kind for s in plan.segments] or ["swath"])
    turning = kinds[np.clip(trace.segment[:-1], 0, kinds.size - 1)] == "turn"
    lowered = np.asarray(trace.lowered[:-1], dtype=bool)
    energy = float(trapezoid(trace.power, t)) / 3.6e6 if t.size > 1 else 0.0  # kWh
    positive = float(trapezoid(np.maximum(trace.power, 0.0), t)) / 3.6e6 if t.size > 1 else 0.0
    worked = cov.worked.area * ha
    b1 = trace.axle[:, 0]
    working_rows = np.asarray(trace.lowered, dtype=bool)
    error = np.abs(trace.tracking_error[working_rows])
    total = float(t[-1] - t[0]) if t.size else 0.0
    values = {
        "field_area_ha": plan.field.area * ha,
        "target_area_ha": plan.target.area * ha,
        "worked_area_ha": worked,
        "skipped_area_ha": cov.skipped.area * ha,
        **{f"skipped_{c}_ha": cov.skipped_by[c].area * ha for c in CAUSES},
        "double_worked_ha": cov.double.area * ha,
        "worked_outside_ha": cov.outside.area * ha,
        "coverage_pct": 100.0 * plan.target.intersection(cov.worked).area / plan.target.area if plan.target.area else
        math.nan,
        "total_time_h": total / 3600.0,
        "working_time_h": float(dt[lowered].sum()) / 3600.0,
        "turn_time_h": float(dt[turning].sum()) / 3600.0,
        "field_efficiency_pct": 100.0 * float(dt[lowered].sum()) / total if total > 0 else math.nan,
        "distance_km": float(np.hypot(*np.diff(b1, axis=0).T).sum()) / 1e3,
        "working_distance_km": float(np.hypot(*np.diff(trace.implement, axis=0)[lowered].T).sum()) / 1e3,
        "energy_kWh": energy,
        "energy_per_ha_kWh": energy / worked if worked > 0 else math.nan,
        "fuel_kg": math.nan, "fuel_l": math.nan, "fuel_per_ha_l": math.nan,
        "max_hitch_angle_deg": math.degrees(float(np.max(np.abs(trace.hitch_angle)))) if trace.hitch_angle.size else
        math.nan,
        "min_jackknife_margin_deg": math.degrees(float(np.min(trace.margin))) if train.n > 1 else math.nan,
        "tracking_rms_m": float(np.sqrt(np.mean(error ** 2))) if error.size else math.nan,
        "tracking_p95_m": float(np.percentile(error, 95)) if error.size else math.nan,
        "tracking_max_m": float(np.max(error)) if error.size else math.nan,
    }
    if train.fuel is not None:
        kg = train.fuel.specific_consumption * positive / train.fuel.efficiency / 1e3
        values.update(fuel_kg=kg, fuel_l=kg / DIESEL_DENSITY,
                      fuel_per_ha_l=kg / DIESEL_DENSITY / worked if worked > 0 else math.nan)
    found = excursions(trace, train)
    values["excursions"] = float(len(found))
    return FieldMetrics(values, cov, found, trace.verdict, trace.reason)


#: each figure's words, for the Markdown table
LABELS = {
    "field_area_ha": "field (obstacles out), ha", "target_area_ha": "the plan's target, ha",
    "worked_area_ha": "worked, ha", "skipped_area_ha": "skipped, ha",
    "skipped_boundary_ha": "  skipped at the boundary, ha", "skipped_turns_ha": "  skipped in turns, ha",
    "skipped_tracking_ha": "  skipped by tracking error, ha", "double_worked_ha": "worked twice, ha",
    "worked_outside_ha": "worked outside the field, ha", "coverage_pct": "target worked, %",
    "total_time_h": "total time, h", "working_time_h": "working time, h", "turn_time_h": "time in turns, h",
    "field_efficiency_pct": "field efficiency (working / total time), %", "distance_km": "distance (tractor), km",
    "working_distance_km": "distance worked (implement), km", "energy_kWh": "traction energy, kWh",
    "energy_per_ha_kWh": "energy per worked ha, kWh/ha", "fuel_kg": "fuel, kg", "fuel_l": "fuel, l",
    "fuel_per_ha_l": "fuel per worked ha, l/ha", "max_hitch_angle_deg": "largest hitch angle, deg",
    "min_jackknife_margin_deg": "smallest jackknife margin, deg", "tracking_rms_m": "tracking error RMS, m",
    "tracking_p95_m": "tracking error p95, m", "tracking_max_m": "tracking error max, m",
    "excursions": "footprint outside the field or in an obstacle, times",
}


#: the figures ``metrics`` gives, in order (a sweep's columns of a field scene)
NAMES = tuple(LABELS)


def markdown(result: FieldMetrics) -> str:
    """The figures as a Markdown table, then the verdict and the excursions."""
    lines = ["| figure | value |", "|---|---:|"]
    lines += [f"| {LABELS.get(k, k).strip()} | {v:.4g} |" for k, v in result.values.items()]
    lines += ["", f"Verdict: {result.verdict}" + (f" ({result.reason})" if result.reason else "")]
    if result.excursions:
        lines += ["", "Footprint outside the field or in an obstacle:", ""]
        lines += [f"- {e.line()}" for e in result.excursions]
    return "\n".join(lines) + "\n"
