"""Transits: getting the working point from one place of the route to the next, raised, on a path
the train can drive (CC turns of its radius R and sharpness: clothoid.py), inside the field.

A transit is the shortest CC Dubins path (CSC; a plain Dubins path of arcs where none joins) between the two poses when it stays inside the field
(obstacles excluded); otherwise it goes along the headland: a Dubins path onto the innermost
headland pass that goes round (the boundary's or an obstacle's), along that pass the shorter way,
and a Dubins path off it. Where neither stays inside, the shortest is taken and the plan says so.
Entering a headland ring to work it uses the same approach paths.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely import geometry as sg
from shapely import ops

from .route import Pose, moves_stretch, polyline_stretch
from .clothoid import Curves, cc_dubins_paths
from .turns import dubins_paths

#: how far ahead (in radii) and aside the points a path onto a ring aims at are tried
AIMS = [(k, j) for k in (0.0, 1.0, 2.0, 3.0, 4.5, 6.0) for j in (-1.0, 0.0, 1.0)]
#: m of straight loop either side of where a path joins it
STRAIGHT = 1.0


@dataclass
class Connection:
    stretches: list  # Stretch
    inside: bool  # the whole path stays inside the field


def inside(region, stretches) -> bool:
    """Every stretch within ``region`` (prepared, with a small tolerance)."""
    return all(region.covers(st.line) for st in stretches)


def loop_pose(loop: sg.LineString, t: float, forward: bool) -> Pose:
    """The pose on ``loop`` at distance ``t``, heading along it (or against it)."""
    length = loop.length
    a = loop.interpolate(t % length)
    b = loop.interpolate((t + 1e-3) % length) if (t + 1e-3) <= length else loop.interpolate(1e-3)
    heading = math.atan2(b.y - a.y, b.x - a.x) + (0.0 if forward else math.pi)
    return Pose(a.x, a.y, heading)


def loop_part(loop: sg.LineString, t0: float, t1: float, forward: bool) -> sg.LineString:
    """``loop`` from distance t0 to t1 along it (forward) or against it, wrapping round its start."""
    length = loop.length
    t0, t1 = t0 % length, t1 % length
    if not forward:
        return loop_part(loop, t1, t0, True).reverse()
    if t1 > t0:
        return ops.substring(loop, t0, t1)
    first = ops.substring(loop, t0, length)
    second = ops.substring(loop, 0.0, t1) if t1 > 0 else None
    coords = list(first.coords) if not first.is_empty and first.geom_type == "LineString" else []
    if second is not None and second.geom_type == "LineString":
        coords += list(second.coords)[1:]
    return sg.LineString(coords)


def loop_from(loop: sg.LineString, t: float, forward: bool) -> sg.LineString:
    """The whole ``loop`` starting and ending at distance ``t``, driven forward or backward."""
    length = loop.length
    t = t % length
    coords = list(ops.substring(loop, t, length).coords) if t < length else [loop.coords[0]]
    if t > 0:
        coords += list(ops.substring(loop, 0.0, t).coords)[1:]
    line = sg.LineString(coords)
    return line if forward else line.reverse()


def shortest(candidates, region) -> Connection:
    """The shortest candidate (a list of stretches) inside ``region``, else the shortest."""
    candidates = [c for c in candidates if c]
    ranked = sorted(candidates, key=lambda c: sum(st.length for st in c))
    for c in ranked:
        if inside(region, c):
            return Connection(c, True)
    return Connection(ranked[0], False)


def dubins_stretches(kind: str, start: Pose, goal: Pose, curves: Curves, region, spacing: float,
                     plain: bool = False):
    """Stretches of the shortest CC Dubins path from ``start`` to ``goal`` inside ``region`` (else
    the shortest), [] when they coincide, None where no CC path joins them (``plain``: then a plain
    Dubins path of arcs, with its curvature jumps)."""
    if math.hypot(goal.x - start.x, goal.y - start.y) < 1e-9 and \
            abs(math.remainder(goal.heading - start.heading, 2 * math.pi)) < 1e-9:
        return []
    paths = cc_dubins_paths(start, goal, curves) or (dubins_paths(start, goal, curves.radius) if plain else [])
    first = None
    for moves in paths:  # shortest first: drawn one by one until one is inside
        option = moves_stretch(kind, start, moves, spacing=spacing)
        if inside(region, option):
            return option
        first = option if first is None else first
    return first


def straight_at(loop: sg.LineString, t: float) -> bool:
    """The loop runs straight STRAIGHT m either side of distance ``t`` (a path joins it there
    without a jump of curvature)."""
    a, b = loop_pose(loop, t - STRAIGHT, True), loop_pose(loop, t + STRAIGHT, True)
    return abs(math.remainder(a.heading - b.heading, 2.0 * math.pi)) < 1e-6


def loop_aims(loop: sg.LineString, pose: Pose, curves: Curves, sense: float) -> list[float]:
    """Distances along ``loop`` where paths from (sense 1) or to (-1) ``pose`` meet it: the
    projections of points ahead (behind) and aside, where the loop is straight."""
    u = np.array([math.cos(pose.heading), math.sin(pose.heading)])
    left = np.array([-u[1], u[0]])
    found = []
    for k, j in AIMS:
        t = loop.project(sg.Point(pose.xy + sense * curves.radius * (k * u + j * left)))
        if straight_at(loop, t) and all(abs(t - f) > 1e-6 for f in found):
            found.append(t)
    return found


def straight_parts(loop: sg.LineString, pose: Pose, step: float = 10.0, most: int = 24) -> list[float]:
    """Distances along ``loop``, ``step`` apart, where it is straight: the ``most`` nearest ``pose``."""
    found = [t for t in np.arange(0.5 * step, loop.length, step) if straight_at(loop, t)]
    return sorted(found, key=lambda t: loop.interpolate(t).distance(sg.Point(pose.xy)))[:most]


def onto_loop(here: Pose, loop: sg.LineString, curves: Curves, region, spacing: float, aims=None):
    """[(stretches, t, forward)]: CC Dubins paths from ``here`` onto ``loop`` where it is straight,
    at points ahead and aside (or at ``aims``), in both directions of the loop (those that exist)."""
    out = []
    for t in (loop_aims(loop, here, curves, 1.0) if aims is None else aims):
        for forward in (True, False):
            goal = loop_pose(loop, t, forward)
            found = dubins_stretches("transit", here, goal, curves, region, spacing)
            if found is not None:
                out.append((found, t, forward))
    return out


def off_loop(goal: Pose, loop: sg.LineString, curves: Curves, region, spacing: float):
    """[(stretches, t, forward)]: CC Dubins paths from ``loop`` (where straight, at points behind
    and aside the goal) onto ``goal``."""
    out = []
    for t in loop_aims(loop, goal, curves, -1.0):
        for forward in (True, False):
            start = loop_pose(loop, t, forward)
            found = dubins_stretches("transit", start, goal, curves, region, spacing)
            if found is not None:
                out.append((found, t, forward))
    return out


def along(loop: sg.LineString, t0: float, t1: float, forward: bool) -> float:
    """The distance from t0 to t1 along ``loop`` (forward) or against it."""
    return ((t1 - t0) if forward else (t0 - t1)) % loop.length


def transit(here: Pose, goal: Pose, curves: Curves, region, loops, spacing: float) -> Connection:
    """From ``here`` to ``goal`` (module docstring)."""
    direct = dubins_stretches("transit", here, goal, curves, region, spacing)
    if direct is not None and (not direct or inside(region, direct)):
        return Connection(direct, True)
    candidates = [direct] if direct is not None else []
    for loop in loops:
        ons = [o for o in onto_loop(here, loop, curves, region, spacing) if inside(region, o[0])]
        offs = [o for o in off_loop(goal, loop, curves, region, spacing) if inside(region, o[0])]
        pairs = [(sum(st.length for st in on + off) + along(loop, t0, t1, fwd), on, off, t0, t1, fwd)
                 for on, t0, fwd in ons for off, t1, fwd1 in offs if fwd == fwd1]
        if not pairs:
            continue
        _, on, off, t0, t1, fwd = min(pairs, key=lambda p: p[0])
        part = loop_part(loop, t0, t1, fwd) if along(loop, t0, t1, fwd) > 1e-6 else None
        candidates.append(on + ([polyline_stretch("transit", part, False, spacing=spacing)] if part else []) + off)
    if not candidates:
        candidates = [dubins_stretches("transit", here, goal, curves, region, spacing, plain=True)]
    return shortest(candidates, region)


def onto_ring(here: Pose, loop: sg.LineString, curves: Curves, region, spacing: float):
    """(approach stretches, the ring driven from where they meet it, inside?): the shortest way
    onto ``loop`` that stays inside, the loop then driven once round."""
    options = onto_loop(here, loop, curves, region, spacing)
    if not any(inside(region, o[0]) for o in options):  # farther along the loop, where straight
        options += onto_loop(here, loop, curves, region, spacing, straight_parts(loop, here))
    options = options or [
        (dubins_stretches("transit", here, loop_pose(loop, t, fwd), curves, region, spacing, plain=True), t, fwd)
        for t in (loop.project(sg.Point(here.xy)),) for fwd in (True, False)]
    ranked = sorted(options, key=lambda o: sum(st.length for st in o[0]))
    for stretches, t, forward in ranked:
        if inside(region, stretches):
            return stretches, loop_from(loop, t, forward), True
    stretches, t, forward = ranked[0]
    return stretches, loop_from(loop, t, forward), False


def region_of(polygon, tolerance: float = 1e-6):
    """The field (obstacles excluded) as the checks read it, prepared."""
    region = polygon.buffer(tolerance)
    shapely.prepare(region)
    return region

