"""Force laws of the force elements (MODEL.md, "Force laws"). Scalar functions, no state.

Resistances act at the rear axle centres B_k against v_Bk; traction acts at A_1 along v_A1.
Each element contributes F_e * kapP_e to the generalized force Q (kapP = d(point speed)/dV).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .spec import Draft, Train

MS_TO_KMH = 3.6


def draft_force(d: Draft, speed: float) -> float:
    """ASABE D497 implement draft D = F_i (A + B S + C S^2) W T, N; S = |speed| in km/h."""
    S = abs(speed) * MS_TO_KMH
    return d.soil_factor * (d.A + d.B * S + d.C * S * S) * d.width * d.depth


@dataclass(frozen=True)
class CartResistance:
    """All resistance elements acting at one cart's B_k: rolling f m g plus any drafts."""

    rolling: float  # N, sum of f m g of the rolling elements of this cart
    drafts: tuple[Draft, ...]

    def force(self, speed: float, smoothing_speed: float) -> float:
        """Signed force opposing s'_Bk = speed, N: (f m g + D(S)) tanh(speed / v0).

        tanh smooths the sign through speed = 0 so that the right-hand side stays smooth (an
        integrator needs that); v0 = smoothing_speed is a few cm/s.
        """
        magnitude = self.rolling
        for d in self.drafts:
            magnitude += draft_force(d, speed)
        return magnitude * math.tanh(speed / smoothing_speed)


def cart_resistances(train: Train) -> tuple[CartResistance, ...]:
    """Group the train's rolling and draft elements by the cart they act on (cart order)."""
    out = []
    for cart in train.carts:
        rolling = sum(r.coefficient * cart.mass * train.gravity for r in train.rolling if r.cart == cart.name)
        drafts = tuple(d for d in train.draft if d.cart == cart.name)
        out.append(CartResistance(rolling=rolling, drafts=drafts))
    return tuple(out)


def traction_limit(traction, V: float) -> float:
    """Largest |F_A1| the tractor can give at speed V: adhesion, and engine power over speed."""
    if math.isinf(traction.max_power):
        return traction.max_force
    return min(traction.max_force, traction.max_power / max(abs(V), 0.1))


def governor(traction, V: float, v_set: float, integral: float) -> tuple[float, float]:
    """PI speed governor. Returns (F_A1, d integral/dt).

    u = kp (v_set - V) + integral, F_A1 = u clipped to +-traction_limit(V). The integral state
    follows ki (v_set - V) + (F_A1 - u) / windup_time: back-calculation anti-windup, which keeps
    the right-hand side continuous where the clip engages.
    """
    error = v_set - V
    u = traction.kp * error + integral
    limit = traction_limit(traction, V)
    force = min(max(u, -limit), limit)
    return force, traction.ki * error + (force - u) / traction.windup_time


def prescribed_acceleration(traction, V: float, v_set: float) -> float:
    """V' for the prescribed-speed law: first-order lag to v_set, limited to +-max_accel."""
    a = (v_set - V) / traction.response_time
    return min(max(a, -traction.max_accel), traction.max_accel)
