"""Closed-form steady turning at constant steering (MODEL.md, "Facts to test against").

With psi_1 held, every cart settles on a circle about one centre:
    R_B1 = l_1 / tan psi_1,   R_A{k+1}^2 = R_Bk^2 + a_k^2,   R_B{k+1}^2 = R_A{k+1}^2 - l_{k+1}^2,
    sin psi_{k+1} = l_{k+1} / R_A{k+1}.
The circle of cart k+1 exists only while R_A{k+1} > l_{k+1}; otherwise that cart cannot follow
and the hitch angle grows until it jackknifes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


class SteadyStateError(ValueError):
    """No steady circle exists for this train at this steering angle."""


@dataclass(frozen=True)
class SteadyCircle:
    R_A: tuple[float, ...]  # radius of each A_k, m
    R_B: tuple[float, ...]  # radius of each B_k, m
    R_C: tuple[float, ...]  # radius of each C_k, m
    psi: tuple[float, ...]  # psi_k, rad (psi_1 = the steering angle)
    hitch_angles: tuple[float, ...]  # th_{k-1} - th_k, k = 2..n, rad


#: rad: a smaller steering is straight on for steady circles (radii beyond 1e100 m)
STRAIGHT = 1e-100


def steady_circle(train, steering: float) -> SteadyCircle:
    """The steady circles for a constant steering angle 0 < |steering| < pi/2 (sign: side); a
    steering below STRAIGHT has radii past floating point (their squares overflow)."""
    if not STRAIGHT < abs(steering) < math.pi / 2:
        raise SteadyStateError(f"steering: {steering} must satisfy {STRAIGHT:g} < |steering| < pi/2 for a steady turn")
    sign = math.copysign(1.0, steering)
    psi1 = abs(steering)
    carts = train.carts
    R_A = [carts[0].length / math.sin(psi1)]
    R_B = [carts[0].length / math.tan(psi1)]
    psi = [psi1]
    for k in range(1, len(carts)):
        prev, cart = carts[k - 1], carts[k]
        RA2 = R_B[-1] ** 2 + prev.hitch_offset**2
        RB2 = RA2 - cart.length**2
        if RB2 <= 0.0:
            raise SteadyStateError(
                f"steering {steering:.4g} rad: cart '{cart.name}' cannot follow: its hitch circle "
                f"R_A = {math.sqrt(RA2):.4g} m is not larger than its length l = {cart.length:.4g} m"
            )
        R_A.append(math.sqrt(RA2))
        R_B.append(math.sqrt(RB2))
        psi.append(math.asin(cart.length / R_A[-1]))
    R_C = [math.sqrt(rb**2 + c.com_offset**2) for rb, c in zip(R_B, carts)]
    hitch = []
    for k in range(1, len(carts)):
        # th_{k-1} - th_k = psi_k + beta_{k-1}, beta = atan2(lam sin psi, cos psi) (chain.py)
        lam = carts[k - 1].hitch_offset / carts[k - 1].length
        beta = math.atan2(lam * math.sin(psi[k - 1]), math.cos(psi[k - 1]))
        hitch.append(sign * (psi[k] + beta))
    return SteadyCircle(tuple(R_A), tuple(R_B), tuple(R_C), tuple(sign * p for p in psi), tuple(hitch))
