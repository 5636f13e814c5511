"""Plane geometry of recorded paths: the least-squares circle through points (the steady radii)
and the exact distance of points to a polyline (off-tracking, analysis.measures; the sweep's
offsets follow the same rule, run/offsets.py).
"""
from __future__ import annotations

import math

import numpy as np


def fit_circle(points: np.ndarray) -> tuple[float, float, float, float]:
    """Least-squares circle through ``points`` (m, 2): (x_c, y_c, R, rms of the radial residuals).

    An algebraic (Kasa) fit gives the start; scipy's least_squares then minimises the geometric
    residuals |P - centre| - R.
    """
    from scipy.optimize import least_squares

    x, y = points[:, 0], points[:, 1]
    mx, my = x.mean(), y.mean()
    u, v = x - mx, y - my  # centred for conditioning
    A = np.column_stack([u, v, np.ones_like(u)])
    b = u * u + v * v
    (cu, cv, c), *_ = np.linalg.lstsq(A, b, rcond=None)
    xc, yc = cu / 2, cv / 2
    r0 = math.sqrt(max(c + xc * xc + yc * yc, 0.0))

    def residual(p):
        return np.hypot(u - p[0], v - p[1]) - p[2]

    sol = least_squares(residual, [xc, yc, r0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    xc, yc, r = sol.x
    rms = float(np.sqrt(np.mean(residual(sol.x) ** 2)))
    return float(xc + mx), float(yc + my), float(abs(r)), rms


def distance_to_path(points: np.ndarray, path: np.ndarray, upto: np.ndarray | None = None):
    """Distance of each point to the nearest point of the polyline ``path`` (m, 2), exact.

    ``upto[j]`` (optional) limits point j to the path's vertices 0..upto[j] (the ground traced
    up to then). Returns ``(signed_distance, at_end)``: the distance, > 0 left of the path's
    direction at the nearest point, and whether that nearest point is the first or the last
    allowed point of the path (then the point is not beside the path). Uses a k-d tree: the
    nearest point lies on a segment with an end within (nearest allowed vertex distance + half
    the longest segment) of the query.
    """
    from scipy.spatial import cKDTree

    m = len(points)
    keep = np.ones(len(path), bool)
    keep[1:] = np.any(np.diff(path, axis=0) != 0, axis=1)  # repeated points (train standing still)
    index = np.cumsum(keep) - 1  # original vertex -> vertex of the reduced path
    path = path[keep]
    last = np.full(m, len(path) - 1) if upto is None else index[np.asarray(upto)]
    if len(path) < 2:
        return np.hypot(*(points - path[0]).T), np.ones(m, bool)
    seg = np.diff(path, axis=0)
    seg_len2 = np.einsum("ij,ij->i", seg, seg)
    half = 0.5 * math.sqrt(float(seg_len2.max()))
    tree = cKDTree(path)
    # distance to the nearest allowed vertex: k nearest, k growing until one is allowed
    d_allowed = np.full(m, np.inf)
    todo = np.arange(m)
    k = 16
    while len(todo):
        kk = min(k, len(path))
        d, i = tree.query(points[todo], k=kk)
        d, i = d.reshape(len(todo), -1), i.reshape(len(todo), -1)
        ok = i <= last[todo, None]
        found = ok.any(axis=1)
        d_allowed[todo[found]] = np.where(ok, d, np.inf)[found].min(axis=1)
        if kk == len(path):
            break
        todo, k = todo[~found], 8 * k
    candidates = tree.query_ball_point(points, d_allowed + half + 1e-9)
    rows, segs = [], []
    for j, verts in enumerate(candidates):
        s = {v for i in verts for v in (i - 1, i) if 0 <= v < last[j]}
        rows.extend([j] * len(s))
        segs.extend(s)
    rows, segs = np.array(rows, dtype=int), np.array(segs, dtype=int)
    signed = np.hypot(*(points - path[0]).T)  # a single allowed vertex: the distance to it
    at_end = last == 0
    if len(rows):
        rel = points[rows] - path[segs]
        u = np.clip(np.einsum("ij,ij->i", rel, seg[segs]) / seg_len2[segs], 0.0, 1.0)
        off = rel - u[:, None] * seg[segs]
        dist = np.hypot(off[:, 0], off[:, 1])
        order = np.lexsort((dist, rows))  # by point, nearest first
        best = order[np.r_[True, rows[order][1:] != rows[order][:-1]]]
        j = rows[best]
        cross = seg[segs[best], 0] * off[best, 1] - seg[segs[best], 1] * off[best, 0]
        signed[j] = np.where(cross >= 0, 1.0, -1.0) * dist[best]
        at_end[j] = (((segs[best] == 0) & (u[best] == 0.0))
                     | ((segs[best] == last[j] - 1) & (u[best] == 1.0)))
    return signed, at_end
