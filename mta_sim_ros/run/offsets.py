"""Distances of points from a polyline, compiled: the off-tracking and swept width of a run
(``batch.metrics``)."""
from __future__ import annotations

import math

import numpy as np

from ..jit import entry, jitable


@entry
def path_offsets(px, py, qx, qy, growing):
    """(signed distance of each point q_i from the polyline p, > 0 left of its direction, m; whether
    its nearest point is an end of the polyline). With ``growing`` point i sees the vertices 0..i
    only (the ground the path had traced by then: analysis.track_geometry.distance_to_path with
    upto = i, whose exact k-d tree search the tests hold this to); else the whole polyline.

    The points are taken in order, each searched from the segment nearest the point before, walking
    on while the next segment is not farther: a point that moves along the path (a cart's axle or
    corner along the tractor's path) finds its nearest segment, and a path that comes back near
    itself is not taken for it. The end segments are extended to lines: beyond an end, a point's
    distance is from that line (``at_end`` says so; mta analyze's distance is then to the end vertex)."""
    m = px.shape[0]
    count = qx.shape[0]
    out = np.empty(count)
    at_end = np.zeros(count, dtype=np.bool_)
    j = 0
    for i in range(count):
        last = m - 1 if not growing else (i if i < m - 1 else m - 1)  # the last vertex point i sees
        if last < 1:
            out[i] = math.hypot(qx[i] - px[0], qy[i] - py[0])
            at_end[i] = True
            continue
        if j > last - 1:
            j = last - 1
        best, side, u = segment_distance2(px, py, j, 0, last, qx[i], qy[i])
        while j + 1 <= last - 1:
            d, s, v = segment_distance2(px, py, j + 1, 0, last, qx[i], qy[i])
            if d > best:
                break
            best, side, u, j = d, s, v, j + 1
        best = math.sqrt(best)
        out[i] = best if side >= 0.0 else -best
        at_end[i] = (j == 0 and u < 0.0) or (j == last - 1 and u > 1.0)
    return out, at_end


@jitable
def segment_distance2(px, py, j, first, last, x, y):
    """(squared distance from (x, y) to segment j of the polyline whose vertices are first..last,
    the side: the cross product's sign, the position u along the segment); the first and the last
    segment extend to lines beyond their ends (u < 0, u > 1)."""
    ax, ay = px[j], py[j]
    dx, dy = px[j + 1] - ax, py[j + 1] - ay
    length2 = dx * dx + dy * dy
    u = ((x - ax) * dx + (y - ay) * dy) / length2 if length2 > 0.0 else 0.0
    if u > 1.0 and j + 1 < last:
        u = 1.0
    if u < 0.0 and j > first:
        u = 0.0
    ox, oy = x - (ax + u * dx), y - (ay + u * dy)
    cross = dx * oy - dy * ox
    return ox * ox + oy * oy, cross, u
