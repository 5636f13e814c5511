"""Where the model stops being valid (MODEL.md): detect it and say so instead of returning numbers.

Checked after every step of a run: non-finite state, a hitch angle past its cart's mechanical
limit, and psi_k past 90 deg (cart k's hitch point would move backwards along the cart's axis:
the jackknife, where the no-slip model of the next carts breaks down).
"""
from __future__ import annotations

import math

import numpy as np

from . import kernel
from .geometry import cart_points, hitch_angles
from .steady import SteadyStateError, steady_circle

JACKKNIFE_PSI = math.pi / 2


class ModelValidityError(RuntimeError):
    """The run left the model's domain of validity. ``time`` (s) and ``cart`` say where."""

    def __init__(self, message: str, time: float, cart: str | None = None):
        super().__init__(message)
        self.time = time
        self.cart = cart


def jackknife_margin(model, y) -> tuple[float, int]:
    """(smallest margin to either jackknife limit over the hitches, rad; index of that cart).

    Margin of cart k (k >= 2) = min(max_hitch_angle_k - |phi_k|, pi/2 - |psi_k|). A single cart
    has no hitch: (inf, -1). Computed by ``kernel.margin`` (psi_k from the chain at the state's
    pose; it does not depend on the speed)."""
    # every level's state starts with x, y, th_1..th_n, psi_1: the kernel reads only those
    best, where = kernel.margin_of(model.P, np.ascontiguousarray(y[: model.layout.n + 3], dtype=np.float64))
    return float(best), int(where)


def check_state(model, t: float, y) -> None:
    """Raise ModelValidityError if y is not a state the model can continue from."""
    y = np.asarray(y)
    if not np.all(np.isfinite(y)):
        bad = [i for i, v in enumerate(y) if not math.isfinite(v)]
        raise ModelValidityError(f"non-finite state at t = {t:.4f} s: components {bad} of {model.layout.size}", t)
    off = int(kernel.off_relief_of(model.P, np.ascontiguousarray(y[: model.layout.n + 3], dtype=np.float64)))
    if off >= 0:
        grid, cart = model.train.relief, model.train.carts[off]
        heading = [float(v) for v in y[model.layout.heading]]
        cx, cy = cart_points(model.train, float(y[0]), float(y[1]), heading)["C"][off].tolist()
        raise ModelValidityError(
            f"off the terrain at t = {t:.4f} s: the centre of mass of '{cart.name}' at ({cx:.2f}, {cy:.2f}) m left the "
            f"height grid (x in [{grid.xs[0]:g}, {grid.xs[-1]:g}], y in [{grid.ys[0]:g}, {grid.ys[-1]:g}] m)", t,
            cart.name)
    margin, k = jackknife_margin(model, y)
    if margin <= 0.0:
        carts = model.train.carts
        heading = [float(v) for v in y[model.layout.heading]]
        phi = hitch_angles(heading)[k - 1]
        raise ModelValidityError(
            f"jackknife at t = {t:.4f} s: hitch between '{carts[k - 1].name}' and '{carts[k].name}' "
            f"at {math.degrees(phi):.1f} deg (limit {math.degrees(carts[k].max_hitch_angle):.1f} deg, "
            f"and the hitch point of '{carts[k].name}' may not move against its axis)"
            + steady_turn_note(model.train, float(y[model.layout.steering])),
            t,
            carts[k].name,
        )


def steady_turn_note(train, steering: float) -> str:
    """Why a held steering angle leads to a jackknife, when no steady circle exists for it."""
    if steering == 0.0:
        return ""
    try:
        steady_circle(train, steering)
    except SteadyStateError as err:
        return f"; no steady turn exists at this steering: {err}"
    return ""


def fast_modes(train, actuator: bool = True) -> list[tuple[float, str]]:
    """The model's fast decaying modes that hold everywhere along a run: (rate r, 1/s; what it is).

    Each is a pole -r of a linear part of the equations (``integrate.stability`` turns them into
    step limits): the steering actuator's lag 1/time_constant (unless ``actuator`` is False: a
    stepper that takes the actuator's closed form does not step that mode); the prescribed-speed lag
    1/response_time; the governor's proportional loop kp / sum m_k (the mass on a straight line)
    and its anti-windup 1/windup_time. Not included: the resistance smoothing through V = 0,
    (sum F_Bk) / (M smoothing_speed), which is fast only while |V| is within a few smoothing
    speeds of zero."""
    act = train.actuator
    modes = [(1.0 / act.time_constant, f"the steering actuator (time constant {act.time_constant:g} s)")] if actuator else []
    tr = train.traction
    if tr.law == "prescribed_speed":
        modes.append((1.0 / tr.response_time, f"the prescribed-speed lag (response_time {tr.response_time:g} s)"))
    elif tr.law == "governor":
        mass = sum(c.mass for c in train.carts)
        modes.append((tr.kp / mass, f"the speed governor (kp / mass = {tr.kp:g} / {mass:g})"))
        modes.append((1.0 / tr.windup_time, f"the governor's anti-windup (windup_time {tr.windup_time:g} s)"))
    return modes
