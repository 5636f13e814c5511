"""Headland turns between the ends of two antiparallel swaths, and Dubins paths for transits: the
working point's path as moves, no ROS. The turns are continuous-curvature (clothoid.py: CC turns
of the train's radius R and sharpness sigma, which turning.py chose so the train can follow them).

A turn starts where a swath ends (pose ``end``, heading u) and finishes where the next one starts,
``offset`` D across (to the left or the right) and ``along`` ahead of the end (negative: behind).
The turn's far side lies at max(0, along) ahead: the swath that ends nearer the field's edge is
extended straight into the headland (raised) so that both meet it.

- **U** (D >= min_u, the width of a CC half turn at R): a CC half turn widened to D (R' >= R),
  or two CC quarter turns with a straight between where D >= 2 T (clothoid.py).
- **bulb** (D < min_u; the "light bulb" or omega turn): CC turns away by alpha, towards the next
  swath by pi + 2 alpha and away by alpha, alpha solved for D.
- **fishtail** (D < min_u): a CC quarter turn forwards, a straight of 2 T - D driven backwards, a
  CC quarter turn forwards (the reversing controller drives the middle).
- **tight u** (``turn: u`` where D < min_u): the narrowest U scaled down to D (R and the
  clothoids by D / min_u, sigma by its square): tighter than the train follows, which the plan says.
Where D >= min_u every kind is a U. With sigma = inf the turns are the arcs of R joined with
curvature jumps (the plain Dubins turns).

How far each reaches beyond the far side is measured on its sampled path (``reach``). Dubins paths
(the shortest forward path of bounded curvature between two poses: three moves,
circle-straight-circle or three circles) are kept for a transit no CC path joins.
"""
from __future__ import annotations

import functools
import math
from typing import Optional

import numpy as np

from .clothoid import Curves, bulb_moves, fishtail_moves, min_u, u_moves
from .route import Move, Pose, end_of, sample_move

KINDS = ("u", "bulb", "fishtail")


def tight_u_moves(offset: float, curves: Curves) -> list[Move]:
    """The narrowest U scaled down to ``|offset|`` (< min_u) across."""
    f = abs(offset) / min_u(curves)
    return u_moves(offset, Curves(curves.radius * f, curves.sharpness / (f * f)))


def turn_kind(asked: str, offset: float, curves: Curves) -> str:
    """The kind of turn made for ``asked`` (auto, u, bulb, fishtail) at this offset: a U where the
    offset is at least min_u, else the one asked (auto: bulb; u: a tight u, which the plan says)."""
    if abs(offset) >= min_u(curves) * (1.0 - 1e-9):
        return "u"
    return {"auto": "bulb", "u": "tight u"}.get(asked, asked)


def kind_moves(kind: str, offset: float, curves: Curves) -> list[Move]:
    """The moves of a ``kind`` turn ``offset`` across, from its far side back to it."""
    if kind == "u":
        return u_moves(offset, curves)
    if kind == "tight u":
        return tight_u_moves(offset, curves)
    if kind == "bulb":
        return bulb_moves(offset, curves)
    return fishtail_moves(offset, curves)


@functools.lru_cache(maxsize=1024)
def reach(kind: str, offset: float, curves: Curves) -> float:
    """How far beyond the turn's far side the working point goes (its sampled path's farthest)."""
    pose, far = Pose(0.0, 0.0, 0.0), 0.0
    for move in kind_moves(kind, offset, curves):
        xy, _, _ = sample_move(pose, move, 0.1)
        far = max(far, float(xy[:, 0].max()))
        pose = end_of(pose, move)
    return far


def turn_moves(kind: str, end: Pose, start: Pose, curves: Curves, middle=None) -> list[Move]:
    """The moves of a ``kind`` turn from ``end`` (heading u) to ``start`` (heading -u); ``middle``:
    the turn's own moves where they are chosen elsewhere (turning.Shapes)."""
    u = np.array([math.cos(end.heading), math.sin(end.heading)])
    left = np.array([-u[1], u[0]])
    delta = start.xy - end.xy
    along, offset = float(delta @ u), float(delta @ left)
    far = max(0.0, along)
    return [Move(far), *(kind_moves(kind, offset, curves) if middle is None else middle), Move(far - along)]


def turn_offset(end: Pose, start: Pose) -> float:
    """The next swath's offset across the ending one (> 0 left)."""
    return float((start.xy - end.xy) @ np.array([-math.sin(end.heading), math.cos(end.heading)]))


# --------------------------------------------------------------------------- Dubins paths


def _mod(angle: float) -> float:
    return angle % (2.0 * math.pi)


def _words(alpha: float, beta: float, d: float) -> list[tuple[str, float, float, float]]:
    """(word, t, p, q) of the six Dubins words in the normalised frame (radius 1, goal at (d, 0)),
    the arcs t and q and the middle p in units of the radius; words that do not exist left out."""
    sa, ca, sb, cb = math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta)
    cab = math.cos(alpha - beta)
    out = []
    p2 = 2.0 + d * d - 2.0 * cab + 2.0 * d * (sa - sb)
    if p2 >= 0.0:
        th = math.atan2(cb - ca, d + sa - sb)
        out.append(("LSL", _mod(-alpha + th), math.sqrt(p2), _mod(beta - th)))
    p2 = 2.0 + d * d - 2.0 * cab + 2.0 * d * (sb - sa)
    if p2 >= 0.0:
        th = math.atan2(ca - cb, d - sa + sb)
        out.append(("RSR", _mod(alpha - th), math.sqrt(p2), _mod(-beta + th)))
    p2 = -2.0 + d * d + 2.0 * cab + 2.0 * d * (sa + sb)
    if p2 >= 0.0:
        p = math.sqrt(p2)
        th = math.atan2(-ca - cb, d + sa + sb) - math.atan2(-2.0, p)
        out.append(("LSR", _mod(-alpha + th), p, _mod(-_mod(beta) + th)))
    p2 = -2.0 + d * d + 2.0 * cab - 2.0 * d * (sa + sb)
    if p2 >= 0.0:
        p = math.sqrt(p2)
        th = math.atan2(ca + cb, d - sa - sb) - math.atan2(2.0, p)
        out.append(("RSL", _mod(alpha - th), p, _mod(beta - th)))
    c = (6.0 - d * d + 2.0 * cab + 2.0 * d * (sa - sb)) / 8.0
    if abs(c) <= 1.0:
        p = _mod(2.0 * math.pi - math.acos(c))
        t = _mod(alpha - math.atan2(ca - cb, d - sa + sb) + 0.5 * p)
        out.append(("RLR", t, p, _mod(alpha - beta - t + p)))
    c = (6.0 - d * d + 2.0 * cab + 2.0 * d * (sb - sa)) / 8.0
    if abs(c) <= 1.0:
        p = _mod(2.0 * math.pi - math.acos(c))
        t = _mod(-alpha - math.atan2(ca - cb, d + sa - sb) + 0.5 * p)
        out.append(("LRL", t, p, _mod(_mod(beta) - alpha - t + p)))
    return out


def dubins_paths(start: Pose, goal: Pose, radius: float) -> list[list[Move]]:
    """Every Dubins path from ``start`` to ``goal`` with arcs of ``radius``, shortest first; each
    checked to end at the goal (a word whose moves miss it by more than 1e-6 m or rad is left out)."""
    dx, dy = goal.x - start.x, goal.y - start.y
    theta = math.atan2(dy, dx)
    d = math.hypot(dx, dy) / radius
    alpha, beta = _mod(start.heading - theta), _mod(goal.heading - theta)
    found = []
    for word, t, p, q in _words(alpha, beta, d):
        moves = []
        for letter, size in zip(word, (t, p, q)):
            k = {"L": 1.0 / radius, "R": -1.0 / radius, "S": 0.0}[letter]
            moves.append(Move(size * radius, k))
        pose = start
        for move in moves:
            pose = end_of(pose, move)
        miss = max(abs(pose.x - goal.x), abs(pose.y - goal.y), abs(math.remainder(pose.heading - goal.heading,
                                                                                 2.0 * math.pi)))
        if miss <= 1e-6 * max(1.0, radius):
            found.append((sum(m.length for m in moves), moves))
    return [moves for _, moves in sorted(found, key=lambda f: f[0])]


def dubins(start: Pose, goal: Pose, radius: float) -> Optional[list[Move]]:
    """The shortest Dubins path, or None (none found: numerically degenerate)."""
    paths = dubins_paths(start, goal, radius)
    return paths[0] if paths else None
