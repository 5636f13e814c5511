"""The actuator and traction laws as docs/model.md states them, written here apart from the
package (whose laws are written once, in physics/kernel/laws.py), for tests to hold the kernel to.
Plain Python on a spec.Actuator / spec.Traction."""
from __future__ import annotations


def clip(x: float, limit: float) -> float:
    return min(max(x, -limit), limit)


def steering_rate(act, psi1: float, command: float, max_rate: float | None = None) -> float:
    """psi_1' = clip((clip(command, +-max_angle) - psi_1) / time_constant, +-max_rate)."""
    rate = act.max_rate if max_rate is None else max_rate
    return clip((clip(command, act.max_angle) - psi1) / act.time_constant, rate)


def traction_limit(traction, V: float) -> float:
    """Largest |F_A1| at speed V: adhesion, and engine power over speed (floored at 0.1 m/s)."""
    return min(traction.max_force, traction.max_power / max(abs(V), 0.1))


def governor(traction, V: float, v_set: float, integral: float) -> tuple[float, float]:
    """PI governor with back-calculation anti-windup: (F_A1, d integral / dt)."""
    u = traction.kp * (v_set - V) + integral
    force = clip(u, traction_limit(traction, V))
    return force, traction.ki * (v_set - V) + (force - u) / traction.windup_time


def prescribed_acceleration(traction, V: float, v_set: float) -> float:
    """First-order lag to v_set, limited to +-max_accel."""
    return clip((v_set - V) / traction.response_time, traction.max_accel)
