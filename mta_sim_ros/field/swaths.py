"""Swaths: straight passes across the inner ground at one angle, and the angle that needs fewest.

Lines run along the angle's direction, ``spacing`` = width x (1 - overlap) apart across it: the
first half a width inside one side of the inner ground's extent, each next one spacing further,
and the last half a width inside the other side, where it overlaps its neighbour more than the
others do (Fields2Cover's END_OVERLAP distribution): no pass works ground outside the inner
ground's extent and none is left out. Ground narrower than a width gets one line, in its middle.
Shapely clips every line by the inner ground: a line cut by an obstacle or a bay of the boundary
gives one swath per piece. A piece shorter than MIN_SWATH_WIDTHS x width is dropped (a turn for
less ground than the implement is wide is not worth it; the plan's notes say how much).

The angle that minimises turns (Fields2Cover's NSwath objective, brute force): the fewest swaths
over whole degrees in [0, 180) and the directions of the field's longest edges (pieces too short
to keep counted too, so that dropping ground does not win), ties going to the angle whose swaths
are longest in all (more ground worked by swaths).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely import affinity
from shapely import geometry as sg

#: a piece of a line shorter than this many working widths is not a swath
MIN_SWATH_WIDTHS = 1.0
#: the field's longest edges whose directions are tried besides the whole degrees
EDGE_ANGLES = 32
#: m: lengths and offsets closer than this are equal
EPS = 1e-9


@dataclass(frozen=True)
class Swath:
    """One straight pass, in the field frame, running along the plan's angle (+u)."""

    line: sg.LineString
    row: int  # its line across the field, 0 first (the offset order)
    offset: float  # m, the line's position across the angle's direction (rotated frame y)
    start: float  # m, along the angle's direction (rotated frame x) where it begins
    end: float  # m, where it ends (> start)

    @property
    def length(self) -> float:
        return self.end - self.start


@dataclass(frozen=True)
class Swaths:
    angle: float  # rad from +x, in [0, pi)
    swaths: tuple  # Swath, by row then along
    dropped: int  # pieces shorter than the minimum
    dropped_length: float  # m, their length in all


def offsets(low: float, high: float, width: float, spacing: float) -> list[float]:
    """The lines' positions across ground extending from ``low`` to ``high`` (module docstring)."""
    extent = high - low
    if extent <= width + EPS:
        return [0.5 * (low + high)]
    count = math.floor((extent - width) / spacing + EPS) + 1
    lines = [low + 0.5 * width + k * spacing for k in range(count)]
    last = high - 0.5 * width
    if last - lines[-1] > EPS * max(1.0, extent):
        lines.append(last)
    return lines


def rotate(geometry, angle: float):
    """``geometry`` turned by ``angle`` about the origin."""
    return affinity.rotate(geometry, angle, origin=(0.0, 0.0), use_radians=True)


def pieces(inner, angle: float, width: float, spacing: float) -> list[tuple[int, float, float, float]]:
    """(row, offset, start, end) of every piece of the lines in the frame turned by -angle."""
    turned = rotate(inner, -angle)
    if turned.is_empty:
        return []
    x0, y0, x1, y1 = turned.bounds
    ys = offsets(y0, y1, width, spacing)
    lines = [sg.LineString([(x0 - 1.0, y), (x1 + 1.0, y)]) for y in ys]
    shapely.prepare(turned)
    cut = shapely.intersection(np.array(lines, dtype=object), turned)
    out = []
    for row, (y, geometry) in enumerate(zip(ys, cut)):
        merged = shapely.line_merge(geometry) if geometry.geom_type == "MultiLineString" else geometry
        parts = [g for g in getattr(merged, "geoms", [merged]) if g.geom_type == "LineString" and g.length > 0]
        spans = sorted((min(g.coords[0][0], g.coords[-1][0]), max(g.coords[0][0], g.coords[-1][0])) for g in parts)
        out.extend((row, y, a, b) for a, b in spans)
    return out


def swaths_at(inner, angle: float, width: float, overlap: float) -> Swaths:
    """The swaths across ``inner`` at ``angle`` (rad) for ``width`` and ``overlap`` (module docstring)."""
    angle = angle % math.pi
    spacing = width * (1.0 - overlap)
    keep, dropped, dropped_length = [], 0, 0.0
    c, s = math.cos(angle), math.sin(angle)
    for row, y, a, b in pieces(inner, angle, width, spacing):
        if b - a < MIN_SWATH_WIDTHS * width - EPS:
            dropped, dropped_length = dropped + 1, dropped_length + (b - a)
            continue
        line = sg.LineString([(a * c - y * s, a * s + y * c), (b * c - y * s, b * s + y * c)])
        keep.append(Swath(line, row, y, a, b))
    rows = sorted({sw.row for sw in keep})
    renumber = {r: i for i, r in enumerate(rows)}
    keep = [Swath(sw.line, renumber[sw.row], sw.offset, sw.start, sw.end) for sw in keep]
    return Swaths(angle, tuple(keep), dropped, dropped_length)


def candidate_angles(polygon) -> list[float]:
    """Whole degrees in [0, 180) and the directions of the polygon's EDGE_ANGLES longest edges."""
    edges = []
    for ring in [polygon.exterior, *polygon.interiors]:
        xy = np.asarray(ring.coords)
        d = np.diff(xy, axis=0)
        edges.extend(zip(np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0]) % math.pi))
    longest = sorted(edges, key=lambda e: -e[0])[:EDGE_ANGLES]
    return sorted({math.radians(k) for k in range(180)} | {float(a) for _, a in longest})


def best_angle(inner, polygon, width: float, overlap: float) -> tuple[Swaths, int]:
    """The swaths at the angle with the fewest, ties to the longest in all; and how many angles
    were tried."""
    angles = candidate_angles(polygon)
    best, key = None, None
    for angle in angles:
        found = swaths_at(inner, angle, width, overlap)
        k = (len(found.swaths) + found.dropped, -round(sum(sw.length for sw in found.swaths), 6))
        if key is None or k < key:
            best, key = found, k
    return best, len(angles)
