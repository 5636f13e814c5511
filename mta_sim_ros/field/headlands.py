"""Headland rings: the passes along the boundary and around every obstacle, and the ground they
leave inside (the swaths' ``inner``). Shapely's buffers do all the offsetting.

Ring i (0 outermost) is the centre line of a pass at (i + 1/2) x width inside the field: the
boundary of ``polygon.buffer(-(offset + R)).buffer(R)`` (an opening by R: its convex corners are
rounded to the turn radius R, so the train can drive them; its concave corners, and every bend
round an obstacle, keep the offset as their radius). The band of ``rings`` passes is H = rings x
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
from shapely import geometry as sg


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


def headlands(polygon, rings: int, width: float, radius: float, spacing: float) -> Headlands:
    """The ``rings`` headland passes of ``width`` in ``polygon`` with corners rounded to ``radius``
    (module docstring), and the ground inside them."""
    lines, index = [], []
    for i in range(rings):
        for loop in loops(opened(polygon, (i + 0.5) * width, radius, spacing)):
            lines.append(loop)
            index.append(i)
    band = rings * width
    inner = opened(polygon, band, max(radius - width / 2, 0.0), spacing) if rings else polygon
    inner = shapely.make_valid(inner) if not inner.is_valid else inner
    return Headlands(tuple(lines), tuple(index), inner, band)
