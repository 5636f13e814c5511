"""A coverage plan of a field for a train: headlands, swaths, their order, the turns and transits,
and the route of the implement's working point (types.Plan). The stages are modules of their own,
as Fields2Cover separates them: turning.py (the train's radius and reach), headlands.py,
swaths.py, order.py, turns.py, connect.py (transits), route.py (the arrays).

The turns are continuous-curvature turns the train follows (clothoid.py, turning.py: their radius
and sharpness chosen on the kinematic chain's inverse). The headland band is as many rings as the
field (or the options) asks, and at least what the plan's turns reach beyond a swath's end (every
cart's box along the inverted chain, turning.Shapes: first guessed from the U widths the order
will use, then measured on the turns made): when the rings are the field's own, more are added
(and said in the notes); when the options fix them, the notes say by how much the turns reach past
the band. A turn whose working point would come nearer an edge than half the implement (a curved
or slanted headland edge across it) goes round on the headland instead. The route starts at
the swath end nearest the field's entry (its first boundary vertex when it gives none), works
the swaths cell by cell, then, when the headlands are worked, each ring from the innermost out.
"""
from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np
import shapely
from shapely import geometry as sg

from ..validate import fail, is_finite, show
from .boundary import MAX_HEADLANDS, Field, FieldError
from .connect import Connection, inside, onto_ring, region_of, transit
from .headlands import Headlands, headlands
from .order import cells, choose_order, route_cells, swath_heading
from .route import SPACING, Move, Pose, assemble, moves_stretch, polyline_stretch, stretch_pose
from .swaths import Swaths, best_angle, swaths_at
from .clothoid import Curves
from .turning import TURN_SPEED, Reach, Shapes, Turning, min_straight, ring_curves, turn_reach, turning
from .turns import reach, turn_kind, turn_moves, turn_offset
from .types import ROUTES, TURNS, Plan, PlanOptions

#: route vertices a plan may have (1000 km at SPACING): a field past it is refused before any work
MAX_ROUTE_VERTICES = 2_000_000
#: m: how much nearer than half the implement's width to an edge a turn's working point may come
CLEARANCE_TOLERANCE = 0.05
#: times the plan is laid out again with more headland rings for the turns it found it needs
MAX_RELAYS = 3


@dataclass
class Layout:
    rings: int
    headlands: Headlands
    swaths: Swaths
    order: str
    notes: list


class Drive:
    """The route being built: its stretches and what was found on the way."""

    def __init__(self, polygon, shapes: Shapes, loops, spacing: float, measured: Reach, width: float):
        self.region = region_of(polygon)
        # where the working point keeps the implement's half width from the edges (ring 0 runs on it)
        self.clear = region_of(polygon.buffer(-(0.5 * width - CLEARANCE_TOLERANCE)))
        self.shapes, self.curves = shapes, shapes.turn.curves
        self.loops, self.spacing, self.measured = loops, spacing, measured
        self.stretches: list = []
        self.swaths: list = []
        self.kinds: Counter = Counter()
        self.outside: Counter = Counter()
        self.reach = measured.train  # m: the farthest the train's outline gets beyond a swath's end
        self.unfollowable = 0  # U-turns whose feedforward leaves the limits

    @property
    def pose(self) -> Pose:
        return stretch_pose(self.stretches[-1])

    def add(self, stretches, kind: str, ok: bool = True) -> None:
        self.stretches.extend(stretches)
        if not ok:
            self.outside[kind] += 1

    def swath(self, line, heading: float) -> None:
        start = Pose(*line.coords[0], heading)
        self.add(moves_stretch("swath", start, [Move(line.length)], True, len(self.swaths), self.spacing), "swath")
        self.swaths.append(line)

    def turn(self, goal: Pose, asked: str) -> None:
        end = self.pose
        offset = turn_offset(end, goal)
        kind = turn_kind(asked, offset, self.curves)
        middle = None
        if kind == "u":  # its shape chosen on the inverted chain, and its reach measured there
            middle, outline, ok = self.shapes.u(offset)
            self.unfollowable += not ok
        elif kind == "bulb":
            outline = self.shapes.bulb_reach(offset)
        else:  # the train's reach in a U, plus how much farther this turn takes the working point
            outline = self.measured.train + reach(kind, round(offset, 9), self.curves) - self.measured.point
        stretches = moves_stretch("turn", end, turn_moves(kind, end, goal, self.curves, middle), spacing=self.spacing)
        if not inside(self.clear, stretches):  # a headland edge slanted or curved across the turn
            found = transit(end, goal, self.curves, self.clear, self.loops, self.spacing)
            if found.inside:
                for st in found.stretches:
                    st.kind = "turn"
                self.kinds["via the headland"] += 1
                self.add(found.stretches, "turn")
                return
        self.reach = max(self.reach, outline)
        self.kinds[kind] += 1
        self.add(stretches, "turn", inside(self.region, stretches))

    def transit(self, goal: Pose) -> None:
        found: Connection = transit(self.pose, goal, self.curves, self.clear, self.loops, self.spacing)
        self.add(found.stretches, "transit", found.inside)

    def ring(self, loop, index: int) -> None:
        approach, line, ok = onto_ring(self.pose, loop, self.curves, self.clear, self.spacing)
        self.add(approach, "transit", ok)
        self.add([polyline_stretch("headland", line, True, index, self.spacing)], "headland")


def check_options(options: PlanOptions, field: Field) -> None:
    """One-line refusal of options no plan can be made with."""
    where, source = "plan options", field.source
    if not (is_finite(options.width) and 0 < options.width <= 100):
        fail("width", show(options.width), "in (0, 100] m", where, source, FieldError)
    if not (is_finite(options.overlap) and 0 <= options.overlap < 0.5):
        fail("overlap", show(options.overlap), "in [0, 0.5)", where, source, FieldError)
    if options.angle is not None and not is_finite(options.angle):
        fail("angle", show(options.angle), "a finite angle, or none (the angle that minimises turns)", where, source,
             FieldError)
    if options.headlands is not None and not (isinstance(options.headlands, int) and
                                              0 <= options.headlands <= MAX_HEADLANDS):
        fail("headlands", show(options.headlands), f"an integer in [0, {MAX_HEADLANDS}]", where, source, FieldError)
    if options.route not in ROUTES:
        fail("route", show(options.route), f"one of {', '.join(ROUTES)}", where, source, FieldError)
    if options.turn not in TURNS:
        fail("turn", show(options.turn), f"one of {', '.join(TURNS)}", where, source, FieldError)
    vertices = field.area / (options.width * (1.0 - options.overlap)) / SPACING
    if vertices > MAX_ROUTE_VERTICES:
        fail("boundary", f"{field.area / 1e4:.4g} ha for a {options.width:g} m implement",
             f"small enough for a route of at most {MAX_ROUTE_VERTICES} vertices {SPACING:g} m apart "
             f"(its swaths alone need ~{vertices:.3g})", "field", source, FieldError)


def lay_out(field: Field, options: PlanOptions, turn: Turning, rings: int, corners: Curves, follows=None) -> Layout:
    """Headlands (their corners CC turns of ``corners``), swaths and the order for ``rings`` rings."""
    width, notes = options.width, []
    band = headlands(field.polygon, rings, width, corners.radius, SPACING, corners, follows)
    if band.inner.is_empty or band.inner.area <= 0.0:
        fail("headlands", f"{rings} rings of {width:g} m, their corners turns of radius {corners.radius:.4g} m",
             "few and tight enough to leave ground inside them (the radius is the train's: its lock, hitches and "
             "implement.offset)", "field", field.source, FieldError)
    if options.angle is None:
        found, tried = best_angle(band.inner, field.polygon, width, options.overlap)
        notes.append(f"angle {math.degrees(found.angle):.1f} deg: the fewest swaths ({len(found.swaths)}) "
                     f"of {tried} angles tried")
    else:
        found = swaths_at(band.inner, options.angle, width, options.overlap)
    if not found.swaths:
        fail("boundary", f"no swath at {math.degrees(found.angle):.1f} deg",
             f"wide enough inside its headlands for a swath of at least one width ({width:g} m)", "field",
             field.source, FieldError)
    if found.dropped:
        notes.append(f"{found.dropped} pieces of swath shorter than the width dropped "
                     f"({found.dropped_length:.1f} m, ~{found.dropped_length * width:.0f} m^2)")
    order, why = choose_order(options.route, cells(found.swaths), turn.min_u, width * (1.0 - options.overlap))
    notes.append(f"route {order} ({why})")
    return Layout(rings, band, found, order, notes)


def drive(field: Field, layout: Layout, shapes: Shapes, options: PlanOptions, measured: Reach) -> Drive:
    """The route's stretches: the cells' swaths joined by turns and transits, then the rings."""
    band = layout.headlands
    innermost = [line for line, i in zip(band.rings, band.ring_index) if i == layout.rings - 1]
    run = Drive(field.polygon, shapes, innermost, SPACING, measured, options.width)
    entry = field.entry if field.entry is not None else field.polygon.exterior.coords[0]
    angle = layout.swaths.angle
    for c, passes in enumerate(route_cells(cells(layout.swaths.swaths), layout.order, entry)):
        for i, p in enumerate(passes):
            heading = swath_heading(angle, p.forward)
            line = p.swath.line if p.forward else p.swath.line.reverse()
            if run.stretches:
                goal = Pose(*line.coords[0], heading)
                run.turn(goal, options.turn) if i > 0 else run.transit(goal)
            run.swath(line, heading)
    if options.work_headlands:
        groups = ring_groups(field.polygon, band)
        while groups:
            here = _point(run.pose.xy)
            group = min(groups, key=lambda g: band.rings[g[0]].distance(here))
            groups.remove(group)
            for j in group:
                run.ring(band.rings[j], j)
    return run


def _point(xy) -> sg.Point:
    return sg.Point(float(xy[0]), float(xy[1]))


def ring_groups(polygon, band: Headlands) -> list[list[int]]:
    """The rings grouped by what they go round (the boundary, each obstacle: the outline nearest to
    a ring's first point), each group innermost first (nearest the swaths)."""
    outlines = [polygon.exterior, *polygon.interiors]
    groups: dict[int, list[int]] = {}
    for j, line in enumerate(band.rings):
        start = _point(line.coords[0])
        groups.setdefault(min(range(len(outlines)), key=lambda k: outlines[k].distance(start)), []).append(j)
    return [sorted(g, key=lambda j: -band.ring_index[j]) for _, g in sorted(groups.items())]


def expected_reach(shapes: Shapes, measured: Reach, options: PlanOptions) -> float:
    """m: what the U-turns of the order auto would choose reach (order.py: its turns span m to 2m
    spacings, m the fewest that hold the narrowest U), the band's first guess (the drive then
    measures the turns it made)."""
    spacing = options.width * (1.0 - options.overlap)
    m = max(1, math.ceil(shapes.turn.min_u / spacing * (1.0 - 1e-9)))
    return max([measured.train] + [shapes.u(k * spacing)[1] for k in range(m, 2 * m + 1)])


def rings_for(reach_m: float, width: float) -> int:
    """Rings of ``width`` a band needs to hold ``reach_m``."""
    return max(0, math.ceil(reach_m / width - 1e-9))


def plan_field(field: Field, train, options: PlanOptions) -> Plan:
    """The coverage plan of ``field`` for ``train`` with ``options`` (module docstring)."""
    check_options(options, field)
    turn = turning(train, options.width * (1.0 - options.overlap))
    measured = turn_reach(train, turn)
    speed = train.traction.set_speed if train.traction.set_speed > 0 else TURN_SPEED
    corners = ring_curves(train, turn, speed)
    follows = min_straight(train, turn, corners, speed)
    asked = options.headlands if options.headlands is not None else field.headlands
    own = options.headlands is None
    shapes = Shapes(train, turn)
    rings = max(asked, rings_for(expected_reach(shapes, measured, options), options.width)) if own else asked
    layout, run = None, None
    for _ in range(MAX_RELAYS):
        try:
            layout = lay_out(field, options, turn, rings, corners, follows)
        except FieldError:
            if rings == asked or layout is not None:
                raise
            rings = asked  # the field is too small for the band the turns want: the notes say so
            own = False
            continue
        run = drive(field, layout, shapes, options, measured)
        needed = rings_for(run.reach, options.width)
        if not (own and rings < needed <= MAX_HEADLANDS):
            break
        rings = needed
    notes = plan_notes(field, options, turn, measured, layout, run, asked)
    route, segments = assemble(run.stretches, SPACING)
    check_route(field, route, run.reach + 2.0 * turn.radius + options.width)
    band = layout.headlands
    target = field.polygon if options.work_headlands else band.inner
    return Plan(field=field, options=options, angle=layout.swaths.angle, headland_rings=band.rings,
                inner=band.inner, target=target, swaths=tuple(run.swaths), segments=segments, route=route,
                turn_radius=turn.radius, headland_width=band.width, notes=tuple(notes))


def check_route(field: Field, route, stray: float) -> None:
    """The planner's own failure (round-off its geometry did not survive) refused in one line, never
    written as a plan: a route past MAX_ROUTE_VERTICES, or one that leaves the field by more than
    ``stray`` m (what its turns may reach past a too narrow headland, with a turn's diameter and a width)."""
    xy = route.xy
    if len(xy) > MAX_ROUTE_VERTICES:
        fail("boundary", f"a route of {len(xy)} vertices", f"a field the planner fits in at most {MAX_ROUTE_VERTICES} "
             "vertices (its geometry failed on this one: simplify or round the boundary's coordinates)", "field",
             field.source, FieldError)
    outside = ~shapely.contains_xy(field.polygon.buffer(stray), xy[:, 0], xy[:, 1])
    if outside.any():
        x, y = xy[int(np.argmax(outside))]
        fail("boundary", f"a route that leaves the field at ({x:.1f}, {y:.1f}) m",
             f"a field the planner keeps its route in, to {stray:.1f} m (its geometry failed on this one: simplify or "
             "round the boundary's coordinates)", "field", field.source, FieldError)


def plan_notes(field, options, turn: Turning, measured: Reach, layout: Layout, run: Drive, asked: int) -> list:
    """The choices the plan made and what it found, in words."""
    width, band = options.width, layout.headlands.width
    notes = [f"turns of continuous curvature: radius {turn.radius:.2f} m, clothoids of {turn.clothoid:.1f} m "
             f"(sharpness {turn.sharpness:.4g} 1/m^2), the narrowest U {turn.min_u:.1f} m wide; their "
             f"feedforward asks at most {math.degrees(turn.steering):.1f} deg at {turn.rate:.2f} rad/s "
             f"(limits: {turn.bound})",
             f"the narrowest U-turn reaches {measured.train:.1f} m beyond the swath end (the train's outline on "
             f"the inverted chain; the working point {measured.point:.1f} m), the plan's turns {run.reach:.1f} m"]
    if layout.rings != asked:
        notes.append(f"headland rings {layout.rings} instead of {asked}: the turns need {run.reach:.1f} m")
    reach_needed = run.reach
    if reach_needed > band + 1e-9:
        notes.append(f"turns reach {reach_needed:.1f} m into a {band:.1f} m headland: the train leaves the field "
                     f"by up to {reach_needed - band:.1f} m")
    notes.extend(layout.notes)
    kinds = ", ".join(f"{n} {k}" for k, n in sorted(run.kinds.items()))
    notes.append(f"turns: {kinds or 'none'}" + (" (a U narrower than the narrowest the train follows: it cannot "
                                                "follow it)" if run.kinds["tight u"] else ""))
    if options.turn in ("bulb", "fishtail") and run.kinds["u"]:
        notes.append(f"turn {options.turn}: made only between swaths closer than the narrowest U, {turn.min_u:.1f} m "
                     f"(a U wherever one fits: {run.kinds['u']} of them)")
    if run.unfollowable:
        notes.append(f"{run.unfollowable} U-turns ask more of the steering than the limits (the least asking "
                     "shape taken)")
    for kind, n in sorted(run.outside.items()):
        notes.append(f"{n} {kind} paths of the working point leave the field")
    tight = ring_bends(field.polygon, layout.headlands, width, turn.radius)
    if tight:
        notes.append(f"{tight} headland rings bend tighter than the turn radius (concave corners, obstacles)")
    if not options.work_headlands:
        notes.append("headlands not worked")
    start = run.stretches[0].xy[0]
    notes.append(f"starts at ({start[0]:.1f}, {start[1]:.1f}) m, the swath end nearest the "
                 + ("entry" if field.entry is not None else "boundary's first vertex (no entry given)"))
    return notes


def ring_bends(polygon, band: Headlands, width: float, radius: float) -> int:
    """Rings that bend tighter than ``radius``: a ring's concave corners and its bends round an
    obstacle have its offset (i + 1/2) width as their radius (headlands.py), so those of an
    offset below the radius, where the field has such corners."""
    concave = len(polygon.interiors) > 0 or polygon.convex_hull.area > polygon.area * (1.0 + 1e-9)
    if not concave:
        return 0
    return sum((i + 0.5) * width < radius * (1.0 - 1e-9) for i in band.ring_index)


def turn_kinds(plan) -> Counter:
    """The plan's turns by kind, read off its route: a turn that reverses is a fishtail, one whose
    curvature changes sign a bulb, one tighter than the plan's turn radius a tight u, else a u."""
    kinds: Counter = Counter()
    route, segments = plan.route, plan.segments
    j = 0
    while j < len(segments):
        if segments[j].kind != "turn":
            j += 1
            continue
        first = j
        while j < len(segments) and segments[j].kind == "turn":
            j += 1
        parts = segments[first:j]
        k = route.curvature[parts[0].first:parts[-1].last]
        if any(p.reverse for p in parts):
            kinds["fishtail"] += 1
        elif k.size and k.max() > 0 and k.min() < 0:
            kinds["bulb"] += 1
        elif k.size and abs(k).max() > (1 + 1e-6) / plan.turn_radius:
            kinds["tight u"] += 1
        else:
            kinds["u"] += 1
    return kinds
