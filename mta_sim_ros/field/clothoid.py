"""Continuous-curvature (CC) turns: the working point's path made of straights, arcs and clothoids,
its curvature continuous and piecewise linear in s, as Fields2Cover's CC Dubins and Reeds-Shepp
curves build them (Fraichard and Scheuer's CC turns). No ROS.

The piece everything is made of is the **CC turn** of deflection beta (> 0 left): a clothoid
from curvature 0 up to kappa = 1/R at sharpness sigma (length L = kappa / sigma, deflection
delta = kappa L / 2), an arc of R over |beta| - 2 delta, and the mirror clothoid back to 0. Where
|beta| < 2 delta the arc is left out and the clothoids stop at kappa_p = sqrt(sigma |beta|) < 1/R.
A CC turn starts and ends straight, so any chain of them and straights has continuous curvature.
For |beta| >= 2 delta its end point is its start point turned by beta + 2 mu about the arc's
centre Omega, mu the angle the start's heading makes with the tangent of the circle about Omega
through it (the turn is symmetric about its bisector through Omega: the end is the start
mirrored), which makes its geometry closed form once the clothoid's end point is integrated.

Turns between antiparallel swaths ``D`` across (turns.py):

- **U**: one CC turn of pi at the radius R' >= R whose width is D, where D is below 2 T (T the
  width of a CC turn of pi/2 at R: the distance from its start to its tangents' corner); else two
  CC turns of pi/2 with a straight of D - 2 T between. The smallest U is the CC half turn at R,
  ``min_u``.
- **bulb** (D < min_u): CC turns of -alpha, pi + 2 alpha, -alpha, alpha solved for the width D.
- **fishtail**: CC turn of pi/2 forward, a straight of 2 T - D backwards, CC turn of pi/2 forward.

CC Dubins paths (CSC: CC turn, straight, CC turn, each turn either way) join poses for transits.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np
from scipy.optimize import brentq
from scipy.special import fresnel

from .route import Move, Pose, clothoid_points, end_of


@dataclass(frozen=True)
class Curves:
    """The turns' limits: the smallest radius R of the working point's path and the sharpness
    sigma (1/m^2: how fast its curvature may change along it); sigma = inf: arcs and straights
    joined with curvature jumps (the plain Dubins turns)."""

    radius: float
    sharpness: float = math.inf

    @property
    def clothoid(self) -> float:
        """m: a clothoid's length from straight to the radius, 1 / (R sigma)."""
        return 0.0 if math.isinf(self.sharpness) else 1.0 / (self.radius * self.sharpness)


def cc_turn(beta: float, curves: Curves) -> list[Move]:
    """The moves of a CC turn of ``beta`` rad (> 0 left; module docstring)."""
    size, side = abs(beta), math.copysign(1.0, beta)
    if size <= 1e-12:
        return []
    R, sigma = curves.radius, curves.sharpness
    if math.isinf(sigma):
        return [Move(size * R, side / R)]
    kappa = 1.0 / R
    L = kappa / sigma
    if size >= kappa * L:
        return [Move(L, 0.0, sharpness=side * sigma), Move((size - kappa * L) * R, side * kappa),
                Move(L, side * kappa, sharpness=-side * sigma)]
    peak = math.sqrt(sigma * size)
    Lp = peak / sigma
    return [Move(Lp, 0.0, sharpness=side * sigma), Move(Lp, side * peak, sharpness=-side * sigma)]


def clothoid_end(sharpness: float, length):
    """(x, y) of a clothoid from straight, ``length`` (array) long at ``sharpness`` > 0, in its start
    frame: the Fresnel integrals, x = sqrt(pi / sigma) C(l sqrt(sigma / pi)) (and S for y)."""
    scale = math.sqrt(math.pi / sharpness)
    S, C = fresnel(np.asarray(length) / scale)
    return scale * C, scale * S


@functools.lru_cache(maxsize=64)
def _centre(radius: float, sharpness: float) -> tuple[float, float, float]:
    """(x, y, delta): the centre Omega of a left CC turn's arc in its start frame, and one
    clothoid's deflection."""
    kappa = 1.0 / radius
    L = kappa / sharpness
    x, y = clothoid_end(sharpness, L)
    delta = 0.5 * kappa * L
    return float(x - radius * math.sin(delta)), float(y + radius * math.cos(delta)), delta


def cc_displacement(beta, curves: Curves):
    """(along, left) of a CC turn's end in its start frame (``beta`` a number or an array)."""
    beta = np.asarray(beta, dtype=float)
    size, side = np.abs(beta), np.where(beta < 0.0, -1.0, 1.0)
    if math.isinf(curves.sharpness):
        R = curves.radius
        along, left = R * np.sin(size), R * (1.0 - np.cos(size))
    else:
        cx, cy, delta = _centre(curves.radius, curves.sharpness)
        turn = size + 2.0 * math.atan2(cx, cy)  # big turns: the start turned about Omega
        along = cx - (np.cos(turn) * cx - np.sin(turn) * cy)
        left = cy - (np.sin(turn) * cx + np.cos(turn) * cy)
        # small turns (no arc): a clothoid to the bisector and its mirror, the end the start
        # reflected across the normal at the middle point M
        mx, my = clothoid_end(curves.sharpness, np.sqrt(size / curves.sharpness))
        c, s = np.cos(0.5 * size), np.sin(0.5 * size)
        a, b = -(mx * c + my * s), -(-mx * s + my * c)
        small = size < 2.0 * delta
        along = np.where(small, mx - a * c - b * s, along)
        left = np.where(small, my - a * s + b * c, left)
    if beta.ndim == 0:
        return float(along), float(side * left)
    return along, side * left


def quarter(curves: Curves) -> float:
    """T: a CC quarter turn's width (its start to the corner of its tangents)."""
    return cc_displacement(0.5 * math.pi, curves)[0]


def half_width(curves: Curves) -> float:
    """The width of a CC half turn (pi) at ``curves``: the smallest U."""
    return cc_displacement(math.pi, curves)[1]


def min_u(curves: Curves) -> float:
    """The narrowest U-turn: a CC half turn at the radius."""
    return half_width(curves)


def u_moves(offset: float, curves: Curves) -> list[Move]:
    """A U-turn to a swath ``offset`` across (> 0 left; |offset| >= min_u)."""
    side, d = math.copysign(1.0, offset), abs(offset)
    T = quarter(curves)
    if d >= 2.0 * T or math.isinf(curves.sharpness):
        R = curves.radius
        if math.isinf(curves.sharpness):
            T = R
        return [*cc_turn(side * 0.5 * math.pi, curves), Move(max(d - 2.0 * T, 0.0)),
                *cc_turn(side * 0.5 * math.pi, curves)]
    wider = wider_radius(d, curves)
    return cc_turn(side * math.pi, Curves(wider, curves.sharpness))


def wider_radius(width: float, curves: Curves) -> float:
    """The radius R' >= R whose CC half turn (same sharpness) is ``width`` wide."""
    def excess(r: float) -> float:
        return half_width(Curves(r, curves.sharpness)) - width

    if excess(curves.radius) >= 0.0:
        return curves.radius
    hi = max(width, 2.0 * curves.radius)
    while excess(hi) < 0.0:
        hi *= 2.0
    return brentq(excess, curves.radius, hi, xtol=1e-10)


def bulb_alpha(offset: float, curves: Curves) -> float:
    """alpha of a CC bulb ``|offset|`` (< min_u) wide: its three turns' width is D."""
    def width(alpha: float) -> float:
        y, heading = 0.0, 0.0
        x = 0.0
        for beta in (-alpha, math.pi + 2.0 * alpha, -alpha):
            along, left = cc_displacement(beta, curves)
            c, s = math.cos(heading), math.sin(heading)
            x, y = x + c * along - s * left, y + s * along + c * left
            heading += beta
        return y - abs(offset)

    hi = 0.05
    while width(hi) > 0.0 and hi < math.pi:
        hi += 0.05
    return brentq(width, 0.0, hi, xtol=1e-12) if width(0.0) > 0.0 else 0.0


def bulb_moves(offset: float, curves: Curves) -> list[Move]:
    side = math.copysign(1.0, offset)
    alpha = bulb_alpha(offset, curves)
    return [*cc_turn(-side * alpha, curves), *cc_turn(side * (math.pi + 2.0 * alpha), curves),
            *cc_turn(-side * alpha, curves)]


def fishtail_moves(offset: float, curves: Curves) -> list[Move]:
    """Forward a CC quarter turn, back a straight of 2 T - D, forward a CC quarter turn."""
    side = math.copysign(1.0, offset)
    T = curves.radius if math.isinf(curves.sharpness) else quarter(curves)
    return [*cc_turn(side * 0.5 * math.pi, curves), Move(max(2.0 * T - abs(offset), 0.0), 0.0, reverse=True),
            *cc_turn(side * 0.5 * math.pi, curves)]


# --------------------------------------------------------------------------- CC Dubins paths


def _csc(start: Pose, goal: Pose, s1: float, s2: float, curves: Curves) -> list[tuple[float, float, float]]:
    """[(beta1, straight, beta2)] of the CSC paths turning ``s1`` then ``s2`` (+1 left, -1 right):
    beta1 scanned over a full turn, each root of the straight's side condition refined."""
    c0, s0 = math.cos(start.heading), math.sin(start.heading)

    def parts(b1):
        a1, l1 = cc_displacement(s1 * b1, curves)
        q1x, q1y = start.x + c0 * a1 - s0 * l1, start.y + s0 * a1 + c0 * l1
        h = start.heading + s1 * b1
        b2 = (s2 * (goal.heading - h)) % (2.0 * math.pi)
        a2, l2 = cc_displacement(s2 * b2, curves)
        ch, sh = np.cos(h), np.sin(h)
        dx, dy = goal.x - ch * a2 + sh * l2 - q1x, goal.y - sh * a2 - ch * l2 - q1y
        return ch * dy - sh * dx, ch * dx + sh * dy, b2

    grid = np.linspace(0.0, 2.0 * math.pi, 97)
    side = parts(grid)[0]
    out = []
    for k in np.flatnonzero((side[:-1] == 0.0) | (side[:-1] * side[1:] < 0.0)):
        b1 = grid[k] if side[k] == 0.0 else brentq(lambda b: float(parts(b)[0]), grid[k], grid[k + 1], xtol=1e-13)
        _, straight, b2 = parts(b1)
        if straight >= -1e-9:
            out.append((float(b1), max(float(straight), 0.0), float(b2)))
    return out


def cc_dubins_paths(start: Pose, goal: Pose, curves: Curves) -> list[list[Move]]:
    """The CSC paths of CC turns from ``start`` to ``goal``, shortest first; each checked to end
    at the goal (one that misses it by more than 1e-6 m or rad is left out)."""
    found = []
    for s1 in (1.0, -1.0):
        for s2 in (1.0, -1.0):
            for b1, straight, b2 in _csc(start, goal, s1, s2, curves):
                moves = [*cc_turn(s1 * b1, curves), Move(straight), *cc_turn(s2 * b2, curves)]
                moves = [m for m in moves if m.length > 1e-9]
                pose = start
                for move in moves:
                    pose = end_of(pose, move)
                miss = max(abs(pose.x - goal.x), abs(pose.y - goal.y),
                           abs(math.remainder(pose.heading - goal.heading, 2.0 * math.pi)))
                if miss <= 1e-6 * max(1.0, curves.radius):
                    found.append((sum(m.length for m in moves), moves))
    return [moves for _, moves in sorted(found, key=lambda f: f[0])]


def first_path(start: Pose, goal: Pose, curves: Curves) -> Optional[list[Move]]:
    paths = cc_dubins_paths(start, goal, curves)
    return paths[0] if paths else None
