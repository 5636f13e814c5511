"""Headland rings: the passes along the boundary and around every obstacle, and the ground they
leave inside (the swaths' ``inner``). Shapely's buffers do all the offsetting.

Ring i (0 outermost) is the centre line of a pass at (i + 1/2) x width inside the field: the
boundary of the field moved that far in with sharp (mitred) corners and opened by R (what is
narrower than 2 R taken off), each convex corner then a CC turn (clothoid.py: clothoid, arc of
R, clothoid, of the ring's ``curves``, which turning.ring_curves chose so the train follows them at
the working speed) tangent to its two edges: the straight edges stay on the offset, the corner is
cut by a little more than an arc of R would. Its concave corners, and every bend round an
obstacle, are arcs of the offset about the field's corner (a path farther from that corner cannot
be tangent to both edges). Corners whose fillets would overlap on a short edge are merged into one
at their edges' crossing (same sense) or the smaller is dropped (opposite senses). The band of ``rings`` passes is H = rings x
width wide; ``inner``, the ground the swaths work, is what the innermost pass's strip leaves:
``polygon.buffer(-(H + r)).buffer(r)`` with r = max(R - width / 2, 0), the inner edge of that strip
(with no ring, ``inner`` is the field itself).

Arcs are drawn with enough segments that their chords are at most ``spacing`` long: the route
follows the rings as drawn.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import shapely
import numpy as np
from shapely import geometry as sg
from shapely.geometry.polygon import orient

from .clothoid import Curves, cc_displacement, cc_turn
from .route import Move, Pose, moves_stretch

#: mitre limit of the sharp offsets (a corner sharper than ~11 deg is bevelled)
MITRE = 10.0
#: m: how much nearer than its offset a ring may come to the field's edges
CLEARANCE = 0.01
#: bisection steps of an obstacle's gap
GAP_BISECTIONS = 12


@dataclass(frozen=True)
class Headlands:
    rings: tuple  # LineStrings (closed), outermost first; each ring's loops: the boundary's, then each obstacle's
    ring_index: tuple  # for each ring line, its pass number (0 outermost)
    inner: sg.base.BaseGeometry  # the ground inside the band (Polygon, MultiPolygon or empty)
    width: float  # H, m


def quad_segs(radius: float, spacing: float) -> int:
    """Segments per quarter circle so that a chord of an arc of ``radius`` is at most ``spacing``."""
    return max(8, math.ceil(0.5 * math.pi * radius / spacing))


def polygons(geometry) -> list:
    """The Polygons of a Polygon, MultiPolygon or collection (others dropped), largest first."""
    parts = [g for g in getattr(geometry, "geoms", [geometry]) if isinstance(g, sg.Polygon) and not g.is_empty]
    return sorted(parts, key=lambda p: -p.area)


def loops(geometry) -> list:
    """The closed LineStrings bounding ``geometry``'s polygons: each exterior, then its interiors."""
    out = []
    for poly in polygons(geometry):
        out.append(sg.LineString(poly.exterior.coords))
        out.extend(sg.LineString(r.coords) for r in poly.interiors)
    return out


def opened(polygon, offset: float, radius: float, spacing: float):
    """``polygon`` moved ``offset`` inwards, its convex corners rounded to ``radius``."""
    q = quad_segs(max(radius, offset, 1.0), spacing)
    if offset <= 0.0:
        return polygon
    if radius <= 0.0:
        return polygon.buffer(-offset, quad_segs=q)
    return polygon.buffer(-(offset + radius), quad_segs=q).buffer(radius, quad_segs=q)


def headlands(polygon, rings: int, width: float, radius: float, spacing: float,
              curves: Curves | None = None, straight: float = 0.0) -> Headlands:
    """The ``rings`` headland passes of ``width`` in ``polygon`` with corners rounded to ``radius``
    (CC turns of ``curves`` where given, module docstring), and the ground inside them;
    ``straight``: the shortest straight the train needs between two corners (an obstacle's gap grows
    until its ring has it)."""
    lines, index, field = [], [], polygon
    if curves is not None and rings:
        polygon = spaced(polygon, 0.5 * width, curves, straight)
    for i in range(rings):
        offset = (i + 0.5) * width
        if curves is None:
            found = loops(opened(polygon, offset, radius, spacing))
        else:
            found = [fitted(loop, field, curves, offset, spacing) for loop in loops(mitred(polygon, offset, curves.radius))]
        for loop in found:
            lines.append(loop)
            index.append(i)
    band = rings * width
    inner = opened(polygon, band, max(radius - width / 2, 0.0), spacing) if rings else polygon
    inner = shapely.make_valid(inner) if not inner.is_valid else inner
    return Headlands(tuple(lines), tuple(index), inner, band)


# --------------------------------------------------------------------------- CC rings


def mitred(polygon, offset: float, radius: float):
    """``polygon`` moved ``offset`` inwards with sharp corners, and its parts narrower than 2
    ``radius`` taken off (an opening by ``radius``, mitred)."""
    if offset <= 0.0:
        return polygon
    core = polygon.buffer(-(offset + radius), join_style="mitre", mitre_limit=MITRE)
    return orient(shapely.make_valid(core.buffer(radius, join_style="mitre", mitre_limit=MITRE)), 1.0) \
        if not core.is_empty else core


def corner_table(xy: np.ndarray):
    """(vertices (k, 2), deflections (k,)) of a closed polyline (last point = first), collinear
    points dropped."""
    pts = xy[:-1]
    keep = []
    for i in range(len(pts)):
        a, b, c = pts[i - 1], pts[i], pts[(i + 1) % len(pts)]
        u, v = b - a, c - b
        turn = math.atan2(u[0] * v[1] - u[1] * v[0], u @ v)
        if abs(turn) > 1e-6 and np.hypot(*u) > 1e-9:
            keep.append(i)
    pts = pts[keep]
    out = []
    for i in range(len(pts)):
        u, v = pts[i] - pts[i - 1], pts[(i + 1) % len(pts)] - pts[i]
        out.append(math.atan2(u[0] * v[1] - u[1] * v[0], u @ v))
    return pts, np.array(out)


def tangent(turn: float, curves: Curves, concave: float) -> float:
    """m from a corner of deflection ``turn`` back to where its fillet starts: a CC turn of
    ``curves`` (turn > 0, convex), an arc of ``concave`` (turn < 0)."""
    if turn < 0.0 and concave is not None:
        return concave * math.tan(-0.5 * turn)
    along, left = cc_displacement(abs(turn), curves)
    return along - left / math.tan(abs(turn)) if abs(turn) < math.pi - 1e-9 else math.inf


def merged(pts: np.ndarray, turns: np.ndarray, curves: Curves, concave: float):
    """The corners, neighbours whose fillets overlap on the edge between them merged into one (at
    their edges' crossing, same sense) or the smaller dropped (opposite senses), until each fits."""
    pts, turns = list(pts), list(turns)
    while len(pts) > 3:
        k = len(pts)
        tan = [tangent(t, curves, concave) for t in turns]
        over = [tan[i] + tan[(i + 1) % k] - float(np.hypot(*(pts[(i + 1) % k] - pts[i]))) for i in range(k)]
        i = int(np.argmax(over))
        if over[i] <= 1e-9:
            break
        j = (i + 1) % k
        crossing = _crossing(pts[i - 1], pts[i], pts[j], pts[(j + 1) % k]) \
            if turns[i] * turns[j] > 0.0 and abs(turns[i] + turns[j]) < math.pi - 1e-6 else None
        # two corners of one sense merge where their edges cross within their fillets' reach: nearly
        # antiparallel edges (a U of two right angles, off by round-off) cross kilometres away
        reach = tan[i] + tan[j]
        if crossing is not None and max(np.hypot(*(crossing - pts[i])), np.hypot(*(crossing - pts[j]))) <= reach:
            pts[i], turns[i] = crossing, turns[i] + turns[j]
            del pts[j], turns[j]
        else:
            drop = i if abs(turns[i]) < abs(turns[j]) else j
            del pts[drop], turns[drop]
            pts_arr, turns_arr = corner_table(np.array(pts + [pts[0]]))
            pts, turns = list(pts_arr), list(turns_arr)
    return np.array(pts), np.array(turns)


def _crossing(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Where the line through a, b crosses the line through c, d (not parallel)."""
    u, v = b - a, d - c
    t = ((c - a)[0] * v[1] - (c - a)[1] * v[0]) / (u[0] * v[1] - u[1] * v[0])
    return a + t * u


def cc_loop(loop: sg.LineString, curves: Curves, concave, spacing: float) -> sg.LineString:
    """The closed ``loop`` (region on its left) with every convex corner a CC turn of ``curves``
    tangent to its two edges and every concave one an arc of ``concave`` (None: a CC turn too),
    drawn ``spacing`` apart."""
    pts, turns = merged(*corner_table(np.asarray(loop.coords)[:, :2]), curves, concave)
    k = len(pts)
    tan = [tangent(t, curves, concave) for t in turns]
    out = []
    for i in range(k):
        a, b = pts[i], pts[(i + 1) % k]
        e = (b - a) / np.hypot(*(b - a))
        start = a + tan[i] * e  # the fillet of corner i ends here; the edge runs to b's fillet
        heading = math.atan2(e[1], e[0])
        edge = float(np.hypot(*(b - a))) - tan[i] - tan[(i + 1) % k]
        moves = [Move(max(edge, 0.0))]
        t = turns[(i + 1) % k]
        moves += cc_turn(t, curves) if t > 0.0 or concave is None else [Move(-t * concave, -1.0 / concave)]
        for st in moves_stretch("headland", Pose(float(start[0]), float(start[1]), heading), moves, spacing=spacing):
            out.append(st.xy[:-1])
    xy = np.vstack(out)
    return sg.LineString(np.vstack([xy, xy[:1]]))


def fitted(loop: sg.LineString, polygon, curves: Curves, offset: float, spacing: float) -> sg.LineString:
    """``cc_loop`` with CC turns at its concave corners too where that keeps ``offset`` from the
    field's edges (less a centimetre), else arcs of the offset there."""
    smooth = cc_loop(loop, curves, None, spacing)
    if smooth.distance(polygon.boundary) >= offset - CLEARANCE:
        return smooth
    return cc_loop(loop, curves, offset, spacing)


def spaced(polygon, offset: float, curves: Curves, straight: float):
    """``polygon`` with each obstacle grown (mitred) by the gap that lets the first ring round it,
    ``offset`` out, turn its corners in CC turns of ``curves`` and still keep ``offset`` from it
    (a ring round an obstacle turns about each corner: at ``offset`` it would be tighter than R),
    and that leaves ``straight`` between its corners (round a small obstacle the corners come so
    close together that the chain cannot follow them one after the other)."""
    holes = []
    for ring in polygon.interiors:
        hole = sg.Polygon(ring)
        low, high = 0.0, 8.0 * curves.radius
        if clears(hole, offset, 0.0, curves, straight):
            holes.append(ring)
            continue
        for _ in range(GAP_BISECTIONS):
            mid = 0.5 * (low + high)
            low, high = (low, mid) if clears(hole, offset, mid, curves, straight) else (mid, high)
        grown = hole.buffer(high, join_style="mitre", mitre_limit=MITRE)
        holes.append(grown.exterior)
    if not holes:
        return polygon
    shell = sg.Polygon(polygon.exterior)
    out = shell.difference(shapely.union_all([sg.Polygon(h) for h in holes]))
    return orient(out, 1.0) if isinstance(out, sg.Polygon) else out


def clears(hole, offset: float, gap: float, curves: Curves, straight: float) -> bool:
    """The ring ``offset`` + ``gap`` round ``hole`` (mitred), its corners CC turns, keeps ``offset``
    and ``straight`` between its corners."""
    around = orient(hole.buffer(offset + gap, join_style="mitre", mitre_limit=MITRE), 1.0)
    line = sg.LineString(around.exterior.coords)
    pts, turns = merged(*corner_table(np.asarray(line.coords)[:, :2]), curves, None)
    tan = [tangent(t, curves, None) for t in turns]
    k = len(pts)
    edges = [float(np.hypot(*(pts[(i + 1) % k] - pts[i]))) - tan[i] - tan[(i + 1) % k] for i in range(k)]
    if min(edges) < straight - 1e-9:
        return False
    return cc_loop(line, curves, None, 1.0).distance(hole) >= offset - CLEARANCE
