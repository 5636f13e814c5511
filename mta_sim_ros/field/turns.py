"""Headland turns between the ends of two antiparallel swaths, and Dubins paths for transits: the
working point's path as moves (arcs of the train's own radius R and straights), no ROS.

A turn starts where a swath ends (pose ``end``, heading u) and finishes where the next one starts,
``offset`` D across (to the left or the right) and ``along`` ahead of the end (negative: behind).
The turn's far side lies at max(0, along) ahead: the swath that ends nearer the field's edge is
extended straight into the headland (raised) so that both meet it.

- **U** (D >= 2R): a quarter circle, a straight of D - 2R across, a quarter circle; it reaches R
  beyond the far side.
- **bulb** (D < 2R; the "light bulb" or omega turn): a circle away from the next swath by alpha,
  one towards it by pi + 2 alpha, and one away by alpha, each of radius R and tangent to the next;
  the middle circle's centre is X = sqrt(4R^2 - (D/2 + R)^2) beyond the far side, so it reaches
  X + R.
- **fishtail** (D < 2R): a quarter circle forwards, a straight of 2R - D driven backwards, a
  quarter circle forwards (the reversing controller drives the middle); it reaches R, as a U.
Where D >= 2R every kind is a U (a bulb's circles no longer touch, a fishtail's backward straight
would be forwards).

Dubins paths (the shortest forward path of bounded curvature between two poses: three moves,
circle-straight-circle or three circles) join what no turn does: cells, headland rings.
"""
from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .route import Move, Pose, end_of

KINDS = ("u", "bulb", "fishtail")


def u_moves(offset: float, radius: float) -> list[Move]:
    """A U-turn to a swath ``offset`` (> 0 left, < 0 right, |offset| >= 2 radius) across."""
    side = math.copysign(1.0, offset)
    k = side / radius
    return [Move(0.5 * math.pi * radius, k), Move(abs(offset) - 2.0 * radius), Move(0.5 * math.pi * radius, k)]


def bulb_geometry(offset: float, radius: float) -> tuple[float, float]:
    """(alpha, X) of a bulb turn to a swath ``|offset|`` < 2 radius across (module docstring)."""
    d = abs(offset)
    x = math.sqrt(max(4.0 * radius**2 - (0.5 * d + radius) ** 2, 0.0))
    alpha = 0.5 * math.pi - math.atan2(0.5 * d + radius, x)
    return alpha, x


def bulb_moves(offset: float, radius: float) -> list[Move]:
    """A bulb turn to a swath ``offset`` across (|offset| < 2 radius)."""
    side = math.copysign(1.0, offset)
    alpha, _ = bulb_geometry(offset, radius)
    k = side / radius
    return [Move(alpha * radius, -k), Move((math.pi + 2.0 * alpha) * radius, k), Move(alpha * radius, -k)]


def fishtail_moves(offset: float, radius: float) -> list[Move]:
    """A fishtail turn to a swath ``offset`` across (|offset| < 2 radius): forwards, backwards, forwards."""
    side = math.copysign(1.0, offset)
    k = side / radius
    return [Move(0.5 * math.pi * radius, k), Move(2.0 * radius - abs(offset), 0.0, reverse=True),
            Move(0.5 * math.pi * radius, k)]


def turn_kind(asked: str, offset: float, radius: float) -> str:
    """The kind of turn made for ``asked`` (auto, u, bulb, fishtail) at this offset: a U where the
    offset is at least 2R, else the one asked (auto: bulb; u: a U of the offset's own radius, too
    tight for the train, which the plan says)."""
    if abs(offset) >= 2.0 * radius * (1.0 - 1e-12):
        return "u"
    return {"auto": "bulb", "u": "tight u"}.get(asked, asked)


def reach(kind: str, offset: float, radius: float) -> float:
    """How far beyond the turn's far side the working point goes."""
    if kind == "bulb":
        return bulb_geometry(offset, radius)[1] + radius
    if kind == "tight u":
        return 0.5 * abs(offset)
    return radius


def turn_moves(kind: str, end: Pose, start: Pose, radius: float) -> list[Move]:
    """The moves of a ``kind`` turn from ``end`` (heading u) to ``start`` (heading -u)."""
    u = np.array([math.cos(end.heading), math.sin(end.heading)])
    left = np.array([-u[1], u[0]])
    delta = start.xy - end.xy
    along, offset = float(delta @ u), float(delta @ left)
    far = max(0.0, along)
    if kind == "u":
        middle = u_moves(offset, radius)
    elif kind == "tight u":
        middle = u_moves(offset, 0.5 * abs(offset))
    elif kind == "bulb":
        middle = bulb_moves(offset, radius)
    else:
        middle = fishtail_moves(offset, radius)
    return [Move(far), *middle, Move(far - along)]


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
