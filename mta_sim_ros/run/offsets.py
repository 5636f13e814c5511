"""Distances of points from a path, compiled and exact: the off-tracking and swept width of a run
(``batch.metrics``).

The path is the samples p_0..p_{m-1} joined piece by piece: by chords (a polyline, ``curved``
False: mta analyze's path, analysis.track_geometry.distance_to_path) or by circular arcs (``curved``
True: each piece bends by the mean of the curvatures of the circles through its ends' sample
triples, so samples on a circle give that circle, not its chords). Each point's nearest piece is
found by branch and bound over a tree of the pieces' bounding boxes (index ranges halved, each box
grown by its arcs' sagittas): a box farther than the best piece so far is passed over, so the search
is exact wherever the path comes back near itself, and cheap where it does not (the piece nearest
the point before is the first bound).
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
    stack = np.empty(256, dtype=np.int64)
    j = -1
    for i in range(count):
        last = (i if i < m - 1 else m - 1) if growing else m - 1  # the last sample point i sees
        if last < 1 or head < 0 or head > last - 1:
            out[i] = math.hypot(qx[i] - px[0], qy[i] - py[0])
            continue
        j, dist, side, u = nearest(px, py, bend, box, first, size, stack, prev[last - 1], j, qx[i], qy[i])
        out[i] = dist if side >= 0.0 else -dist
        at_end[i] = (j == head and u == 0.0) or (j == prev[last - 1] and u == 1.0)
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
    is beside, and a path that comes back near itself (a U-turn's other leg) is not taken for it."""
    m = px.shape[0]
    count = qx.shape[0]
    out = np.empty(count)
    at_end = np.ones(count, dtype=np.bool_)
    head, prev = real_pieces(px, py)
    if head < 0:
        for i in range(count):
            out[i] = math.hypot(qx[i] - px[0], qy[i] - py[0])
        return out, at_end
    j = 0
    for i in range(count):
        best, side, u = piece_distance(px, py, bend[j], j, qx[i], qy[i])
        while j + 1 <= m - 2:
            d, s, v = piece_distance(px, py, bend[j + 1], j + 1, qx[i], qy[i])
            if d > best:
                break
            best, side, u, j = d, s, v, j + 1
        out[i] = best if side >= 0.0 else -best
        # past the last piece of nonzero length (the samples of a train standing still at the end) the
        # nearest point is the path's end sample, whatever u a repeated sample's piece gives
        at_end[i] = (j <= head and u == 0.0) or (j >= prev[m - 2] and u == 1.0) or j > prev[m - 2]
    return out, at_end


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
def box_distance2(box, k, x, y):
    """The squared distance from (x, y) to node k's box (inf for an empty box)."""
    dx = max(box[k, 0] - x, 0.0, x - box[k, 1])
    dy = max(box[k, 2] - y, 0.0, y - box[k, 3])
    return dx * dx + dy * dy


@jitable
def nearest(px, py, bend, box, first, size, stack, last, start, x, y):
    """(piece, distance, side, position u in [0, 1] along it) of the nearest point to (x, y) of the
    pieces 0..last (the last has nonzero length). From the piece ``start`` (or the last one, if
    ``start`` is none of them or of zero length) up the tree: at each level, the sibling's subtree
    is searched only if its box is nearer than the best piece so far."""
    j = start if 0 <= start <= last and box[start + size, 0] <= box[start + size, 1] else last
    best, side, u = piece_distance(px, py, bend[j], j, x, y)
    node = j + size
    while node > 1:
        top = 0
        stack[0] = node ^ 1
        while top >= 0:
            k = stack[top]
            top -= 1
            if first[k] > last or box_distance2(box, k, x, y) > best * best:
                continue
            if k >= size:
                s = k - size
                d, sd, v = piece_distance(px, py, bend[s], s, x, y)
                if d < best or (d == best and s < j):
                    best, side, u, j = d, sd, v, s
                continue
            near, far = 2 * k, 2 * k + 1
            if box_distance2(box, far, x, y) < box_distance2(box, near, x, y):
                near, far = far, near
            stack[top + 1] = far
            stack[top + 2] = near
            top += 2
        node //= 2
    return j, best, side, u


@jitable
def piece_distance(px, py, bend, s, x, y):
    """(distance from (x, y) to piece s, the side (> 0: left of it), the position u in [0, 1] of the
    nearest point). A chord (bend 0) as analysis.track_geometry's segments; an arc of curvature
    ``bend`` over the chord, in the chord's frame at its middle (a along, b to the left): the signed
    distance to the circle (1 - |bend| D) / bend, D the distance to its centre, in a form without
    cancellation; beyond the arc's ends (or across its centre) the distance to the nearer end."""
    ax, ay = px[s], py[s]
    dx, dy = px[s + 1] - ax, py[s + 1] - ay
    length2 = dx * dx + dy * dy
    rx, ry = x - ax, y - ay
    if length2 == 0.0:  # a repeated sample
        return math.hypot(rx, ry), 0.0, 0.0
    if bend == 0.0:
        u = min(max((rx * dx + ry * dy) / length2, 0.0), 1.0)
        ox, oy = rx - u * dx, ry - u * dy
        return math.hypot(ox, oy), dx * oy - dy * ox, u
    chord = math.sqrt(length2)
    half = 0.5 * chord
    tx, ty = dx / chord, dy / chord
    mx, my = rx - half * tx, ry - half * ty
    a, b = mx * tx + my * ty, my * tx - mx * ty
    rise = math.sqrt(1.0 - (bend * half) ** 2)  # the centre is (0, rise / bend)
    kd = math.hypot(bend * a, rise - bend * b)  # |bend| D
    if rise - bend * b > 0.0 and 0.0 < kd and abs(a) <= half * kd:  # (kd = 0: the centre, every point as near)
        signed = (bend * (half * half - a * a - b * b) + 2.0 * rise * b) / (1.0 + kd)
        return abs(signed), signed, 0.5 + a / (kd * chord)
    ex, ey = rx - dx, ry - dy
    to_start, to_end = math.hypot(rx, ry), math.hypot(ex, ey)
    if to_start <= to_end:
        return to_start, dx * ry - dy * rx, 0.0
    return to_end, dx * ey - dy * ex, 1.0


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
