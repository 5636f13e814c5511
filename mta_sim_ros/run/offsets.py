"""Distances of points from a path, compiled and exact: the off-tracking and swept width of a run
(``batch.metrics``).

The path is the samples p_0..p_{m-1} joined piece by piece: by chords (a polyline: mta analyze's
path, analysis.track_geometry.distance_to_path; ``path_offsets``) or by circular arcs (each piece
bends by the mean of the curvatures of the circles through its ends' sample triples, so samples on
a circle give that circle, not its chords; ``arc_bends``, ``beside_offsets``, ``outline_extent``).

``path_offsets`` finds each point's nearest piece by branch and bound over a tree of the pieces'
bounding boxes (index ranges halved): a box farther than the best piece so far is passed over, so the
search is exact wherever the path comes back near itself, and cheap where it does not (the piece
nearest the point before is the first bound). ``beside_offsets`` walks on from the piece the point
before was beside (a corner of a cart moving along the tractor's path), and ``outline_extent`` takes
the extremes of that walk for every corner of every cart in one call.

The loops over points call only functions of numbers (``piece_distance``, ``shaped_distance``,
``box_distance2``, ``norm``): an array handed to a function inside the loop costs numba's reference
counting at every call, more than the arithmetic.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import entry, jitable


@entry
def path_offsets(px, py, qx, qy, growing):
    """(signed distance of each point q_i from the path p, > 0 left of its direction, m; whether
    its nearest point is an end of the path, not beside it). With ``growing`` point i sees the
    samples 0..i only (the ground the path had traced by then: distance_to_path with upto = i,
    whose exact k-d tree search the tests hold this to); else the whole path. The path's pieces are
    chords, as analyze's. Repeated samples (a train standing still) are one sample; a path of one
    sample is a point (every q_i at its end)."""
    m = px.shape[0]
    count = qx.shape[0]
    out = np.empty(count)
    at_end = np.ones(count, dtype=np.bool_)
    bend = np.zeros(max(m - 1, 0))
    size = 1
    while size < m - 1:
        size *= 2
    box, first = bounds(px, py, bend, size)
    head, prev = real_pieces(px, py)
    nearest(px, py, bend, box, first, size, head, prev, growing, qx, qy, out, at_end)
    return out, at_end


@entry
def arc_bends(px, py):
    """The curvature of each piece of the path p joined by arcs (``curvatures``), for beside_offsets."""
    return curvatures(px, py)


@entry
def beside_offsets(px, py, bend, qx, qy):
    """(signed distance of each point q_i from the path p joined by arcs of curvatures ``bend``
    (arc_bends), > 0 left of it, m;
    whether its nearest point is an end of the path). The points are taken in order, each searched
    from the piece nearest the point before, walking on while the next piece is not farther: a
    point that moves along the path (a cart's corner along the tractor's path) finds the piece it
    is beside, and a path that comes back near itself (a U-turn's other leg) is not taken for it.
    (batch.metrics takes the extremes of this walk for every corner at once, ``outline_extent``; the
    tests hold that to this per-point form.)"""
    count = qx.shape[0]
    out = np.empty(count)
    at_end = np.ones(count, dtype=np.bool_)
    head, prev = real_pieces(px, py)
    walk_beside(px, py, bend, arc_shapes(px, py, bend), head, prev, qx, qy, out, at_end)
    return out, at_end


@jitable
def walk_beside(px, py, bend, shapes, head, prev, qx, qy, out, at_end):
    """beside_offsets' search into ``out`` and ``at_end``, given the path's ``real_pieces`` (head,
    prev) and ``arc_shapes``. (The loop calls only functions of numbers: an array handed to a
    function in the loop would cost numba's reference counting at every call.)"""
    m = px.shape[0]
    if head < 0:
        for i in range(qx.shape[0]):
            out[i] = math.hypot(qx[i] - px[0], qy[i] - py[0])
            at_end[i] = True
        return
    j = 0
    for i in range(qx.shape[0]):
        x, y = qx[i], qy[i]
        best, side, u = shaped_distance(px[j], py[j], px[j + 1], py[j + 1], bend[j], x, y, shapes[j, 0], shapes[j, 1],
                                        shapes[j, 2], shapes[j, 3])
        while j + 1 <= m - 2:
            s = j + 1
            d, sd, v = shaped_distance(px[s], py[s], px[s + 1], py[s + 1], bend[s], x, y, shapes[s, 0], shapes[s, 1],
                                       shapes[s, 2], shapes[s, 3])
            if d > best:
                break
            best, side, u, j = d, sd, v, s
        out[i] = best if side >= 0.0 else -best
        # past the last piece of nonzero length (the samples of a train standing still at the end) the
        # nearest point is the path's end sample, whatever u a repeated sample's piece gives
        at_end[i] = (j <= head and u == 0.0) or (j >= prev[m - 2] and u == 1.0) or j > prev[m - 2]


@entry
def outline_extent(px, py, bend, bx, by, th, corners, start, a1x, a1y, e0x, e0y):
    """(largest left and right signed distance, ``beside_offsets``, of the points ``corners`` of every
    cart from the path p joined by arcs of curvatures ``bend``, points at its ends left out: -inf and
    inf when none is beside it; the farthest any reaches along (e0x, e0y) past (a1x, a1y) from row
    ``start`` on, -inf for start < 0). The points of cart k at row i: B_k + along e_k + across
    e_k rotated left, e_k = (cos, sin) of its heading th[i, k], for each (along, across) in
    corners[k]. A NaN distance or reach counts for nothing (a run's trace has none)."""
    rows, n = bx.shape[0], bx.shape[1]
    head, prev = real_pieces(px, py)
    shapes = arc_shapes(px, py, bend)
    left, right, reach = -math.inf, math.inf, -math.inf
    ex, ey, qx, qy = np.empty(rows), np.empty(rows), np.empty(rows), np.empty(rows)
    d, at_end = np.empty(rows), np.empty(rows, dtype=np.bool_)
    for k in range(n):
        for i in range(rows):
            ex[i], ey[i] = math.cos(th[i, k]), math.sin(th[i, k])
        for c in range(corners.shape[1]):
            along, across = corners[k, c, 0], corners[k, c, 1]
            for i in range(rows):
                qx[i] = bx[i, k] + along * ex[i] - across * ey[i]
                qy[i] = by[i, k] + along * ey[i] + across * ex[i]
            walk_beside(px, py, bend, shapes, head, prev, qx, qy, d, at_end)
            for i in range(rows):
                if not at_end[i]:  # (a NaN compares false: it counts for nothing)
                    left = d[i] if d[i] > left else left
                    right = d[i] if d[i] < right else right
                if 0 <= start <= i:
                    ahead = (qx[i] - a1x) * e0x + (qy[i] - a1y) * e0y
                    reach = ahead if ahead > reach else reach
    return left, right, reach


@jitable
def real_pieces(px, py):
    """(the first piece of nonzero length, -1 if none; for each piece s the last piece of nonzero
    length up to s, -1 if none)."""
    pieces = max(px.shape[0] - 1, 0)
    prev = np.full(pieces, -1, dtype=np.int64)
    head, latest = -1, -1
    for s in range(pieces):
        if px[s + 1] != px[s] or py[s + 1] != py[s]:
            latest = s
            if head < 0:
                head = s
        prev[s] = latest
    return head, prev


@jitable
def curvatures(px, py):
    """Each piece's signed curvature (> 0 turning left, 1/m): the mean of the curvatures of the
    circles through the sample triples about its two ends (one at the path's ends, 0 for none or
    a triple with a repeated sample), at most 1/chord (a piece turns by less than 60 deg)."""
    m = px.shape[0]
    at = np.zeros(m)
    known = np.zeros(m, dtype=np.bool_)
    for i in range(1, m - 1):
        ax, ay = px[i] - px[i - 1], py[i] - py[i - 1]
        bx, by = px[i + 1] - px[i], py[i + 1] - py[i]
        product = math.hypot(ax, ay) * math.hypot(bx, by) * math.hypot(px[i + 1] - px[i - 1], py[i + 1] - py[i - 1])
        if product > 0.0:
            at[i] = 2.0 * (ax * by - ay * bx) / product
            known[i] = True
    bend = np.zeros(max(m - 1, 0))
    for s in range(m - 1):
        total, count = 0.0, 0
        for i in (s, s + 1):
            if known[i]:
                total += at[i]
                count += 1
        chord = math.hypot(px[s + 1] - px[s], py[s + 1] - py[s])
        if count and chord > 0.0:
            bend[s] = max(-1.0 / chord, min(1.0 / chord, total / count))
    return bend


@jitable
def bounds(px, py, bend, size):
    """(boxes: rows x_min, x_max, y_min, y_max of the tree's nodes 1..2 size - 1, node s + size the
    piece s (a piece of zero length or none: an empty box), node k the union of nodes 2k and 2k+1;
    each node's first piece)."""
    box = np.empty((2 * size, 4))
    box[:, 0] = box[:, 2] = math.inf
    box[:, 1] = box[:, 3] = -math.inf
    first = np.zeros(2 * size, dtype=np.int64)
    for s in range(px.shape[0] - 1):
        chord = math.hypot(px[s + 1] - px[s], py[s + 1] - py[s])
        if chord > 0.0:
            grow = abs(bend[s]) * chord * chord / 4.0  # an arc's sagitta is less
            node = s + size
            box[node, 0] = min(px[s], px[s + 1]) - grow
            box[node, 1] = max(px[s], px[s + 1]) + grow
            box[node, 2] = min(py[s], py[s + 1]) - grow
            box[node, 3] = max(py[s], py[s + 1]) + grow
    for s in range(size):
        first[s + size] = s
    for k in range(size - 1, 0, -1):
        box[k, 0] = min(box[2 * k, 0], box[2 * k + 1, 0])
        box[k, 1] = max(box[2 * k, 1], box[2 * k + 1, 1])
        box[k, 2] = min(box[2 * k, 2], box[2 * k + 1, 2])
        box[k, 3] = max(box[2 * k, 3], box[2 * k + 1, 3])
        first[k] = first[2 * k]
    return box, first


@jitable
def box_distance2(x_min, x_max, y_min, y_max, x, y):
    """The squared distance from (x, y) to a node's box (inf for an empty box)."""
    dx = max(x_min - x, 0.0, x - x_max)
    dy = max(y_min - y, 0.0, y - y_max)
    return dx * dx + dy * dy


@jitable
def nearest(px, py, bend, box, first, size, head, prev, growing, qx, qy, out, at_end):
    """path_offsets' search into ``out`` and ``at_end``, given the tree (``bounds``) and the path's
    ``real_pieces`` (head, prev). For each point, the nearest point of the pieces 0..last (the last
    of nonzero length): from the piece nearest the point before (or the last one, if that is none
    of them or of zero length) up the tree; at each level, the sibling's subtree is searched only
    if its box is nearer than the best piece so far. (The loop calls only functions of numbers: an
    array handed to a function in the loop would cost numba's reference counting at every call.)"""
    m = px.shape[0]
    stack = np.empty(256, dtype=np.int64)
    j = -1
    for i in range(qx.shape[0]):
        x, y = qx[i], qy[i]
        last_sample = (i if i < m - 1 else m - 1) if growing else m - 1  # the last sample point i sees
        if last_sample < 1 or head < 0 or head > last_sample - 1:
            out[i] = math.hypot(x - px[0], y - py[0])
            continue
        last = prev[last_sample - 1]
        j = j if 0 <= j <= last and box[j + size, 0] <= box[j + size, 1] else last
        best, side, u = piece_distance(px[j], py[j], px[j + 1], py[j + 1], bend[j], x, y)
        node = j + size
        while node > 1:
            top = 0
            stack[0] = node ^ 1
            while top >= 0:
                k = stack[top]
                top -= 1
                if first[k] > last or box_distance2(box[k, 0], box[k, 1], box[k, 2], box[k, 3], x, y) > best * best:
                    continue
                if k >= size:
                    s = k - size
                    d, sd, v = piece_distance(px[s], py[s], px[s + 1], py[s + 1], bend[s], x, y)
                    if d < best or (d == best and s < j):
                        best, side, u, j = d, sd, v, s
                    continue
                near, far = 2 * k, 2 * k + 1
                if box_distance2(box[far, 0], box[far, 1], box[far, 2], box[far, 3], x, y) < \
                        box_distance2(box[near, 0], box[near, 1], box[near, 2], box[near, 3], x, y):
                    near, far = far, near
                stack[top + 1] = far
                stack[top + 2] = near
                top += 2
            node //= 2
        out[i] = best if side >= 0.0 else -best
        at_end[i] = (j == head and u == 0.0) or (j == last and u == 1.0)


@jitable
def piece_distance(x0, y0, x1, y1, bend, x, y):
    """(distance from (x, y) to the piece from (x0, y0) to (x1, y1), the side (> 0: left of it), the
    position u in [0, 1] of the nearest point): ``shaped_distance`` with the piece's ``arc_shape``."""
    chord, tx, ty, rise = arc_shape(x0, y0, x1, y1, bend)
    return shaped_distance(x0, y0, x1, y1, bend, x, y, chord, tx, ty, rise)


@jitable
def arc_shape(x0, y0, x1, y1, bend):
    """(chord length, unit chord (tx, ty), rise = sqrt(1 - (bend chord / 2)^2)) of the piece from (x0,
    y0) to (x1, y1), an arc of curvature ``bend``: what ``shaped_distance`` needs of it besides its
    ends; zeros for a chord (bend 0) or a repeated sample."""
    dx, dy = x1 - x0, y1 - y0
    length2 = dx * dx + dy * dy
    if length2 == 0.0 or bend == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    chord = math.sqrt(length2)
    return chord, dx / chord, dy / chord, math.sqrt(1.0 - (bend * (0.5 * chord)) ** 2)


@jitable
def arc_shapes(px, py, bend):
    """``arc_shape`` of every piece of the path: rows (chord, tx, ty, rise)."""
    shapes = np.empty((max(px.shape[0] - 1, 0), 4))
    for s in range(shapes.shape[0]):
        shapes[s, 0], shapes[s, 1], shapes[s, 2], shapes[s, 3] = arc_shape(px[s], py[s], px[s + 1], py[s + 1], bend[s])
    return shapes


@jitable
def shaped_distance(x0, y0, x1, y1, bend, x, y, chord, tx, ty, rise):
    """``piece_distance`` given the piece's ``arc_shape`` (chord, tx, ty, rise). A chord (bend 0) as
    analysis.track_geometry's segments; an arc of curvature ``bend`` over the chord, in the chord's
    frame at its middle (a along, b to the left): the signed distance to the circle (1 - |bend| D) /
    bend, D the distance to its centre (0, rise / bend), in a form without cancellation; beyond the
    arc's ends (or across its centre) the distance to the nearer end."""
    dx, dy = x1 - x0, y1 - y0
    length2 = dx * dx + dy * dy
    rx, ry = x - x0, y - y0
    if length2 == 0.0:  # a repeated sample
        return norm(rx, ry), 0.0, 0.0
    if bend == 0.0:
        u = min(max((rx * dx + ry * dy) / length2, 0.0), 1.0)
        ox, oy = rx - u * dx, ry - u * dy
        return norm(ox, oy), dx * oy - dy * ox, u
    half = 0.5 * chord
    mx, my = rx - half * tx, ry - half * ty
    a, b = mx * tx + my * ty, my * tx - mx * ty
    kd = norm(bend * a, rise - bend * b)  # |bend| D
    if rise - bend * b > 0.0 and 0.0 < kd and abs(a) <= half * kd:  # (kd = 0: the centre, every point as near)
        signed = (bend * (half * half - a * a - b * b) + 2.0 * rise * b) / (1.0 + kd)
        return abs(signed), signed, 0.5 + a / (kd * chord)
    ex, ey = rx - dx, ry - dy
    to_start, to_end = norm(rx, ry), norm(ex, ey)
    if to_start <= to_end:
        return to_start, dx * ry - dy * rx, 0.0
    return to_end, dx * ey - dy * ex, 1.0


@jitable
def norm(x, y):
    """sqrt(x^2 + y^2): within an ulp of math.hypot, at a sixth of its cost compiled (2.3 ns against
    13.7, the C library's hypot a call; the distances of a run's metrics are most of their time).
    Lengths in metres, far from where x^2 overflows."""
    return math.sqrt(x * x + y * y)


@jitable
def segment_distance2(px, py, j, first, last, x, y):
    """(squared distance from (x, y) to segment j of the polyline whose vertices are first..last,
    the side: the cross product's sign, the position u along the segment); the first and the last
    segment extend to lines beyond their ends (u < 0, u > 1): the implement controller's projection
    (controllers/implement/loop.py)."""
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
