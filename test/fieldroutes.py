"""Fields, routes and plans built in code for the field tests: a rectangle worked in straight swaths
joined by circular turns, every number known in closed form (the planner, field/plan.py, is tested
on its own). A route is a list of pieces, each a straight line or a circular arc, sampled every
``spacing`` m at most."""
from __future__ import annotations

import math

import numpy as np
from shapely import geometry as sg

from mta_sim_ros.field.boundary import field_from_yaml
from mta_sim_ros.field.types import Plan, PlanOptions, Route, Segment


def rectangle(width: float, height: float, headlands: int = 1, holes=()):
    """A width x height m field, its south-west corner at the origin."""
    data = {"name": "rectangle", "boundary": [[0, 0], [width, 0], [width, height], [0, height]],
            "headlands": headlands}
    if holes:
        data["holes"] = [list(h) for h in holes]
    return field_from_yaml(data, "test rectangle")


def line(length: float, kind: str = "swath", working: bool = True, reverse: bool = False, index: int = -1):
    return ("line", length, 0.0, kind, working, reverse, index)


def arc(radius: float, angle: float, kind: str = "turn", working: bool = False, reverse: bool = False):
    """A circular arc of ``radius`` turning ``angle`` rad (> 0 left of travel, < 0 right)."""
    return ("arc", radius * abs(angle), math.copysign(1.0 / radius, angle), kind, working, reverse, -1)


def route_of(pieces, start=(0.0, 0.0), heading: float = 0.0, spacing: float = 0.5):
    """(Route, segments) of pieces driven one after the other from ``start`` along ``heading``
    (the direction of travel). Where a piece's direction (reverse) differs from the one before, the
    travel turns back on itself (a cusp: the carts stop and drive the other way), its heading + pi;
    an arc's angle is the turn of the direction of travel (> 0 left of it)."""
    xy, s, hs, ks, work, rev, seg = [np.array(start, dtype=float)], [0.0], [heading], [], [], [], []
    segments = []
    x, y, h, station = float(start[0]), float(start[1]), heading, 0.0
    for i, (_, length, kappa, kind, working, reverse, index) in enumerate(pieces):
        if i and reverse != pieces[i - 1][5]:
            h += math.pi
            hs[-1] = h
        count = max(1, int(math.ceil(length / spacing - 1e-9)))
        first = len(xy) - 1
        for j in range(1, count + 1):
            d = length * j / count
            if kappa == 0.0:
                px, py, ph = x + d * math.cos(h), y + d * math.sin(h), h
            else:
                ph = h + kappa * d
                px = x + (math.sin(ph) - math.sin(h)) / kappa
                py = y - (math.cos(ph) - math.cos(h)) / kappa
            xy.append(np.array([px, py]))
            s.append(station + d)
            hs.append(ph)
        ks += [kappa] * count
        work += [working] * count
        rev += [reverse] * count
        seg += [i] * count
        x, y, h, station = float(xy[-1][0]), float(xy[-1][1]), hs[-1], s[-1]
        segments.append(Segment(kind, first, len(xy) - 1, reverse, index))
    ks.append(ks[-1])
    work.append(work[-1])
    rev.append(rev[-1])
    seg.append(seg[-1])
    route = Route(np.array(xy), np.array(s), np.array(hs), np.array(ks), np.array(work, dtype=bool),
                  np.array(rev, dtype=bool), np.array(seg, dtype=np.int64), spacing)
    return route, tuple(segments)


def swath_plan(field, width: float, headland: float, swaths: int | None = None, turn_radius: float | None = None,
               lead: float = 0.0, spacing: float = 0.5):
    """A plan of ``field`` (a rectangle from ``rectangle``) in straight swaths along x, ``width``
    apart, from x = headland to x = W - headland, driven back and forth, each joined to the next by
    a U-turn: two quarter circles of ``turn_radius`` (default width / 2) and the straight between
    them. The headland is not worked (target = inner). ``lead`` m of straight before the first swath
    and after the last, lifted."""
    minx, miny, maxx, maxy = field.polygon.bounds
    inner = sg.box(minx + headland, miny + headland, maxx - headland, maxy - headland).intersection(field.polygon)
    count = swaths or int(round((inner.bounds[3] - inner.bounds[1]) / width))
    length = inner.bounds[2] - inner.bounds[0]
    r = turn_radius or width / 2.0
    if r > width / 2.0:
        raise ValueError(f"turn_radius {r} m: a U-turn of two quarter circles joins swaths {width} m apart only "
                         f"for a radius up to {width / 2} m")
    pieces = [line(lead, "transit", False)] if lead > 0 else []
    lines = []
    for i in range(count):
        y = inner.bounds[1] + width * (i + 0.5)
        east = i % 2 == 0
        xs = (inner.bounds[0], inner.bounds[2]) if east else (inner.bounds[2], inner.bounds[0])
        lines.append(sg.LineString([(xs[0], y), (xs[1], y)]))
        pieces.append(line(length, "swath", True, index=i))
        if i < count - 1:
            side = 1.0 if east else -1.0
            pieces += [arc(r, side * math.pi / 2), line(width - 2 * r, "turn", False), arc(r, side * math.pi / 2)]
    if lead > 0:
        pieces.append(line(lead, "transit", False))
    start = (inner.bounds[0] - lead, inner.bounds[1] + width / 2)
    route, segments = route_of([p for p in pieces if p[1] > 0.0], start, 0.0, spacing)
    options = PlanOptions(width=width, headlands=0, work_headlands=False)
    return Plan(field=field, options=options, angle=0.0, headland_rings=(), inner=inner, target=inner,
                swaths=tuple(lines), segments=segments, route=route, turn_radius=r, headland_width=headland)


def plan_of(field, route, segments, width: float, inner=None, target=None, swaths=(), rings=()):
    """A Plan around a route built by hand."""
    inner = inner if inner is not None else field.polygon
    return Plan(field=field, options=PlanOptions(width=width), angle=0.0, headland_rings=tuple(rings), inner=inner,
                target=target if target is not None else inner, swaths=tuple(swaths), segments=segments, route=route,
                turn_radius=width / 2, headland_width=0.0)


def trace_along(plan, train, speed: float = 3.0, shift=None, lowered=None, power: float = 1.0e5):
    """A FieldTrace of ``plan``'s route worked exactly: a row at every route vertex, reached at
    ``speed``; W on the vertex moved ``shift`` m (per vertex, > 0 left of travel), every cart on
    the route's heading there (the train straight along it), the implement lowered where the route
    works (or ``lowered``), the traction power ``power`` throughout."""
    from mta_sim_ros.field.types import FieldTrace

    route = plan.route
    r = route.s.shape[0]
    shift = np.zeros(r) if shift is None else np.asarray(shift, dtype=float)
    travel = route.heading
    normal = np.column_stack((-np.sin(travel), np.cos(travel)))
    W = route.xy + shift[:, None] * normal
    cart_heading = travel + np.where(route.reverse, math.pi, 0.0)
    e = np.column_stack((np.cos(cart_heading), np.sin(cart_heading)))
    m = train.cart_index(train.implement.cart)
    carts = train.carts
    reach = sum(c.length + c.hitch_offset for c in carts[:m]) + carts[m].length - train.implement.offset
    a = W + reach * e
    axle = np.empty((r, train.n, 2))
    for k, c in enumerate(carts):
        axle[:, k] = a - c.length * e
        a = axle[:, k] - c.hitch_offset * e
    return FieldTrace(plan=plan, tick=route.spacing / speed, t=route.s / speed, implement=W,
                      lowered=np.asarray(route.working if lowered is None else lowered, dtype=bool),
                      segment=route.segment.copy(), tracking_error=shift.copy(), axle=axle,
                      heading=np.repeat(cart_heading[:, None], train.n, axis=1), hitch_angle=np.zeros((r, train.n - 1)),
                      margin=np.full(r, math.radians(80.0)), speed=np.full(r, speed), power=np.full(r, float(power)))
