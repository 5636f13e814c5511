"""A compiled (numba) tick of the dynamic model, algorithm 2: the node's hot path without Python.

``Model._rhs_direct`` (dynamics.py) stays the reference implementation. This module mirrors it
line for line in ``_rhs`` (the same operations in the same order, IEEE arithmetic: fastmath is
off, so no reassociation and no fused multiply-add), and ``_tick`` runs whole ticks of Euler,
Heun or RK4 with the input held, mirroring ``integrate.steppers.FixedStep`` (its ``y + (h / 6)
(k1 + 2 k2 + 2 k3 + k4)`` evaluated in numpy's order). Both stay in compiled code for a whole tick:
one call from Python per tick instead of 4 right-hand sides plus a dozen array operations.
test/test_compiled.py holds the two paths equal. ``_outputs`` mirrors ``sim.evaluate_outputs``
the same way (the chain's factors and resistances recorded by ``_rhs``, then cart_points,
hitch_angles and guards.margin_of), so that ``Simulation.outputs`` costs one compiled call too.

The train's constants are packed once per model into one flat float64 array (``pack``); every
force law of the Python path is supported (rolling, ASABE drafts, the constant, governor and
prescribed-speed traction laws, the actuator's lag and limits, the tanh smoothing through V = 0).

``_tick`` also screens the new state for ``model.guards.check_state``: it reports "clear" only when
every component is finite and every hitch is more than ``GUARD_SLACK`` rad inside both jackknife
limits (computed like ``guards.jackknife_margin``). Any other state goes to the Python
``check_state``, which decides and words the error exactly as before; so the screen can only skip
checks of states that are clearly valid.

Importing this module imports numba (ImportError without it); ``sim.Simulation`` imports it only
when the compiled path is wanted (see ``Simulation(compiled=...)`` and ``MTA_SIM_NO_JIT``).
Functions are compiled on first use and cached on disk (numba ``cache=True``: __pycache__ beside
this file, or numba's user-wide cache directory when that is not writable); ``warm_up`` does it
up front and says how long it took.
"""
from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

# -- the packed constants -----------------------------------------------------------------------
# header
_N, _LAW, _V0, _TAU, _MAX_RATE, _MAX_ANGLE = 0, 1, 2, 3, 4, 5
_FORCE, _MAX_FORCE, _MAX_POWER, _KP, _KI, _WINDUP, _RESPONSE, _MAX_ACCEL = 6, 7, 8, 9, 10, 11, 12, 13
HEADER = 16
# per cart, from HEADER: l, a/l, (a/l)^2, (c/l)^2, m, J, f m g, first draft, number of drafts, hitch limit,
# and for the outputs' points (geometry.cart_points) the cart's length, centre-of-mass and hitch offsets
_L, _LAM, _LAM2, _MU2, _M, _J, _ROLL, _D_FIRST, _D_COUNT, _HITCH, _LENGTH, _COM, _HOFF = range(13)
CART = 13
# per draft, after the carts: soil factor, A, B, C, width, depth
DRAFT = 6

# columns of rec (see _rhs) and of the per-cart outputs (see _outputs)
_KAPT, _KAPB, _KAPC, _PSI, _RES = range(5)
REC = 5

LAWS = {"constant": 0, "governor": 1, "prescribed_speed": 2}
METHOD_CODES = {"euler": 0, "heun": 1, "rk4": 2}
MS_TO_KMH = 3.6  # forces.MS_TO_KMH
GUARD_SLACK = 1e-9  # rad: closer than this to a jackknife limit, the Python check_state decides


def pack(model) -> np.ndarray:
    """The constants of ``model`` (a dynamics.Model) as one float64 array, read from the very
    tuples the Python hot path uses (``model._rows``), so both see the same numbers."""
    train = model.train
    rows = model._rows
    n = len(rows)
    drafts = [d for row in rows for d in row[7]]
    P = np.zeros(HEADER + CART * n + DRAFT * len(drafts))
    tr, act = train.traction, train.actuator
    if tr.law not in LAWS:
        raise ValueError(f"traction law {tr.law!r} has no compiled form (one of {tuple(LAWS)})")
    P[_N], P[_LAW], P[_V0] = n, LAWS[tr.law], train.smoothing_speed
    P[_TAU], P[_MAX_RATE], P[_MAX_ANGLE] = act.time_constant, act.max_rate, act.max_angle
    P[_FORCE], P[_MAX_FORCE], P[_MAX_POWER] = tr.force, tr.max_force, tr.max_power
    P[_KP], P[_KI], P[_WINDUP] = tr.kp, tr.ki, tr.windup_time
    P[_RESPONSE], P[_MAX_ACCEL] = tr.response_time, tr.max_accel
    first = 0
    for k, (l_k, lam, lam2, mu2, m, J, rolling, ds) in enumerate(rows):
        b = HEADER + CART * k
        cart = train.carts[k]
        P[b:b + CART] = (l_k, lam, lam2, mu2, m, J, rolling, first, len(ds), cart.max_hitch_angle,
                         cart.length, cart.com_offset, cart.hitch_offset)
        first += len(ds)
    base = HEADER + CART * n
    for i, d in enumerate(drafts):
        P[base + DRAFT * i: base + DRAFT * (i + 1)] = (d.soil_factor, d.A, d.B, d.C, d.width, d.depth)
    return P


# -- compiled kernels -----------------------------------------------------------------------------
# Python's min(a, b) / max(a, b) (the first argument unless the second is strictly smaller / larger),
# not np.minimum: the same result for -0.0 and NaN as the reference.

@njit(cache=True)
def _pymin(a, b):
    return b if b < a else a


@njit(cache=True)
def _pymax(a, b):
    return b if b > a else a


@njit(cache=True)
def _rhs(P, y, command, v_set, dy, rec):
    """y' into dy: Model._rhs_direct + Model._traction + actuator.steering_rate + forces.*, in the
    same order of operations. Returns (traction F_A1, mass M). When ``rec`` has rows (n x REC), the
    chain's kapT, kapB, kapC, psi and the resistance F_Bk of each cart go into it (for outputs)."""
    n = int(P[_N])
    psi1, V, z = y[n + 2], y[n + 3], y[n + 4]
    # actuator.steering_rate
    max_angle, max_rate = P[_MAX_ANGLE], P[_MAX_RATE]
    target = _pymin(_pymax(command, -max_angle), max_angle)
    rate = (target - psi1) / P[_TAU]
    psi_rate = _pymin(_pymax(rate, -max_rate), max_rate)
    v0 = P[_V0]
    dbase = HEADER + CART * n

    mass = 0.0
    mass_rate = 0.0
    generalized_resistance = 0.0
    k_val, k_dot = 1.0, 0.0
    p_val, p_dot = psi1, psi_rate
    theta_rate_prev = 0.0
    beta_dot_prev = 0.0
    last = n - 1
    for k in range(n):
        b = HEADER + CART * k
        l_k, lam, lam2, mu2 = P[b + _L], P[b + _LAM], P[b + _LAM2], P[b + _MU2]
        m, J, rolling = P[b + _M], P[b + _J], P[b + _ROLL]
        s, c = math.sin(p_val), math.cos(p_val)
        t_val = k_val * s / l_k
        theta_rate = t_val * V
        if k:
            p_dot = theta_rate_prev - theta_rate - beta_dot_prev
        s_dot, c_dot = c * p_dot, -s * p_dot
        t_dot = (k_dot * s + k_val * s_dot) / l_k
        b_val = k_val * c
        cc = c * c
        rc = math.sqrt(cc + mu2 * s * s)
        rc_dot = (c * c_dot + mu2 * s * s_dot) / rc
        kc_val = k_val * rc
        kc_dot = k_dot * rc + k_val * rc_dot
        mass += m * kc_val * kc_val + J * t_val * t_val
        mass_rate += 2.0 * (m * kc_val * kc_dot + J * t_val * t_dot)
        axle_speed = b_val * V
        magnitude = rolling
        first = int(P[b + _D_FIRST])
        for i in range(first, first + int(P[b + _D_COUNT])):  # forces.draft_force
            d = dbase + DRAFT * i
            S = abs(axle_speed) * MS_TO_KMH
            magnitude += P[d] * (P[d + 1] + P[d + 2] * S + P[d + 3] * S * S) * P[d + 4] * P[d + 5]
        resistance = magnitude * math.tanh(axle_speed / v0)
        generalized_resistance += resistance * b_val
        dy[2 + k] = theta_rate
        if rec.shape[0]:
            rec[k, _KAPT], rec[k, _KAPB], rec[k, _KAPC] = t_val, b_val, kc_val
            rec[k, _PSI], rec[k, _RES] = p_val, resistance
        if k < last:
            rl2 = cc + lam2 * s * s
            rl = math.sqrt(rl2)
            rl_dot = (c * c_dot + lam2 * s * s_dot) / rl
            beta = math.atan2(lam * s, c)
            beta_dot_prev = lam * p_dot / rl2
            k_val, k_dot = k_val * rl, k_dot * rl + k_val * rl_dot
            p_val = y[2 + k] - y[3 + k] - beta
            theta_rate_prev = theta_rate

    velocity_term = 0.5 * mass_rate * V
    # Model._traction
    law = int(P[_LAW])
    governor_rate = 0.0
    if law == 2:  # prescribed_speed: forces.prescribed_acceleration
        a = (v_set - V) / P[_RESPONSE]
        acceleration = _pymin(_pymax(a, -P[_MAX_ACCEL]), P[_MAX_ACCEL])
        traction = mass * acceleration + generalized_resistance + velocity_term  # inverse dynamics
    else:
        if law == 1:  # forces.governor, forces.traction_limit
            error = v_set - V
            u = P[_KP] * error + z
            if math.isinf(P[_MAX_POWER]):
                limit = P[_MAX_FORCE]
            else:
                limit = _pymin(P[_MAX_FORCE], P[_MAX_POWER] / _pymax(abs(V), 0.1))
            traction = _pymin(_pymax(u, -limit), limit)
            governor_rate = P[_KI] * error + (traction - u) / P[_WINDUP]
        else:
            traction = P[_FORCE]
        acceleration = (traction - generalized_resistance - velocity_term) / mass
    course = y[2] + psi1
    dy[0] = V * math.cos(course)
    dy[1] = V * math.sin(course)
    dy[n + 2] = psi_rate
    dy[n + 3] = acceleration
    dy[n + 4] = governor_rate
    return traction, mass


@njit(cache=True)
def rhs(P, y, command, v_set):
    """y' as a new array (Model.rhs for algorithm 2)."""
    dy = np.empty(y.shape[0])
    _rhs(P, y, command, v_set, dy, np.empty((0, REC)))
    return dy


@njit(cache=True)
def _clear(P, y):
    """True when y is finite and every hitch is more than GUARD_SLACK inside both jackknife limits
    (guards.jackknife_margin: min(max_hitch_angle - |phi_k|, pi/2 - |psi_k|), chain at V = 0)."""
    for i in range(y.shape[0]):
        if not math.isfinite(y[i]):
            return False
    n = int(P[_N])
    p_val = y[n + 2]
    for k in range(n - 1):
        b = HEADER + CART * k
        lam = P[b + _LAM]
        s, c = math.sin(p_val), math.cos(p_val)
        beta = math.atan2(lam * s, c)
        phi = y[2 + k] - y[3 + k]
        p_val = phi - beta  # psi_{k+1}
        if not abs(phi) <= math.pi:  # hitch_angles wraps it: let Python decide
            return False
        margin = min(P[b + CART + _HITCH] - abs(phi), 0.5 * math.pi - abs(p_val))
        if not margin > GUARD_SLACK:
            return False
    return True


@njit(cache=True)
def _tick(P, y0, command, v_set, h, count, method):
    """``count`` steps of ``h`` from y0 with (command, v_set) held: FixedStep.advance's arithmetic.
    method: 0 euler, 1 heun, 2 rk4. Returns (y1, clear): see ``_clear``."""
    size = y0.shape[0]
    y = y0.copy()
    k1 = np.empty(size)
    k2 = np.empty(size)
    k3 = np.empty(size)
    k4 = np.empty(size)
    tmp = np.empty(size)
    no_rec = np.empty((0, REC))
    half = 0.5 * h
    sixth = h / 6.0
    for _ in range(count):
        _rhs(P, y, command, v_set, k1, no_rec)
        if method == 0:
            for i in range(size):
                y[i] = y[i] + h * k1[i]
        elif method == 1:
            for i in range(size):
                tmp[i] = y[i] + h * k1[i]
            _rhs(P, tmp, command, v_set, k2, no_rec)
            for i in range(size):
                y[i] = y[i] + half * (k1[i] + k2[i])
        else:
            for i in range(size):
                tmp[i] = y[i] + half * k1[i]
            _rhs(P, tmp, command, v_set, k2, no_rec)
            for i in range(size):
                tmp[i] = y[i] + half * k2[i]
            _rhs(P, tmp, command, v_set, k3, no_rec)
            for i in range(size):
                tmp[i] = y[i] + h * k3[i]
            _rhs(P, tmp, command, v_set, k4, no_rec)
            for i in range(size):
                y[i] = y[i] + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    return y, _clear(P, y)


# per-cart output columns (after the REC columns of _rhs): A, B, C (x, y), hitch angle phi_k, and the
# speeds s'_Ck = kapC V, s'_Bk = kapB V, th'_k = kapT V
_AX, _AY, _BX, _BY, _CX, _CY, _PHI, _VC, _VB, _VT = range(REC, REC + 10)
OUT = REC + 10
# scalar outputs
_REAR_X, _REAR_Y, _TRACTION, _MASS, _RES_POWER, _MARGIN, _WRAPPED = range(7)
SCALARS = 7


@njit(cache=True)
def _outputs(P, y, command, v_set):
    """sim.evaluate_outputs's numbers for state y: (cart n x OUT, scalars SCALARS), the same
    arithmetic as geometry.cart_points, chain.chain, Model.terms, geometry.hitch_angles and
    guards.margin_of. scalars[_WRAPPED] = 1 when a hitch angle lies outside [-pi, pi] (then
    hitch_angles would wrap it: the caller takes the Python path)."""
    n = int(P[_N])
    cart = np.empty((n, OUT))
    sc = np.zeros(SCALARS)
    dy = np.empty(y.shape[0])
    traction, mass = _rhs(P, y, command, v_set, dy, cart)
    V = y[n + 3]
    ax, ay = y[0], y[1]
    res_power = 0.0
    margin = math.inf
    for k in range(n):
        b = HEADER + CART * k
        th = y[2 + k]
        ex, ey = math.cos(th), math.sin(th)
        cart[k, _AX], cart[k, _AY] = ax, ay
        bx, by = ax - P[b + _LENGTH] * ex, ay - P[b + _LENGTH] * ey
        cart[k, _BX], cart[k, _BY] = bx, by
        cart[k, _CX], cart[k, _CY] = bx + P[b + _COM] * ex, by + P[b + _COM] * ey
        ax, ay = bx - P[b + _HOFF] * ex, by - P[b + _HOFF] * ey
        cart[k, _VC], cart[k, _VB], cart[k, _VT] = cart[k, _KAPC] * V, cart[k, _KAPB] * V, cart[k, _KAPT] * V
        res_power += cart[k, _RES] * cart[k, _VB]
        if k:
            phi = y[1 + k] - th
            if not abs(phi) <= math.pi:
                sc[_WRAPPED] = 1.0
            cart[k, _PHI] = phi
            m = min(P[b + _HITCH] - abs(phi), 0.5 * math.pi - abs(cart[k, _PSI]))
            if m < margin:
                margin = m
        else:
            cart[k, _PHI] = 0.0
    sc[_REAR_X], sc[_REAR_Y] = ax, ay
    sc[_TRACTION], sc[_MASS], sc[_RES_POWER], sc[_MARGIN] = traction, mass, res_power, margin
    return cart, sc


# -- the Python face ---------------------------------------------------------------------------

def supports(model) -> bool:
    """Whether ``model`` has a compiled form: the dynamic level (dynamics.Model itself, not a
    level built on it) with algorithm 2."""
    from .dynamics import Model

    return type(model) is Model and model.algorithm == 2 and model.train.traction.law in LAWS


class CompiledModel:
    """One model's packed constants and compiled kernels."""

    def __init__(self, model):
        if not supports(model):
            raise ValueError("the compiled path covers the dynamic level with algorithm 2 only")
        from ..sim import Outputs  # sim imports this module lazily: no cycle

        self.Outputs = Outputs
        self.model = model
        self.P = pack(model)
        self.size = model.layout.size

    def rhs(self, y, command: float, v_set: float) -> np.ndarray:
        """Model.rhs(t, y, command, v_set), compiled."""
        return rhs(self.P, np.ascontiguousarray(y, dtype=np.float64), float(command), float(v_set))

    def tick(self, method_code: int, y0, command: float, v_set: float, h: float, count: int):
        """(y1, clear): ``count`` steps of ``h`` with the input held."""
        return _tick(self.P, np.ascontiguousarray(y0, dtype=np.float64), float(command), float(v_set),
                     float(h), int(count), int(method_code))

    def outputs(self, t: float, y, command: float, v_set: float):
        """sim.evaluate_outputs(model, t, y, command, v_set) from compiled code, as an Outputs whose
        arrays are views of one array; None when a hitch angle needs wrapping (the caller takes
        the Python path). test/test_compiled.py holds the two equal."""
        y = np.ascontiguousarray(y, dtype=np.float64)
        cart, sc = _outputs(self.P, y, float(command), float(v_set))
        if sc[_WRAPPED]:
            return None
        n = self.model.layout.n
        V = float(y[n + 3])
        traction = float(sc[_TRACTION])
        return self.Outputs(
            t=t, front=cart[:, _AX:_AY + 1], axle=cart[:, _BX:_BY + 1], com=cart[:, _CX:_CY + 1],
            rear_hitch=sc[_REAR_X:_REAR_Y + 1], heading=y[2:2 + n].copy(), hitch_angle=cart[1:, _PHI],
            psi=cart[:, _PSI], com_speed=cart[:, _VC], axle_speed=cart[:, _VB], yaw_rate=cart[:, _VT],
            speed=V, steering=float(y[n + 2]), command=command, speed_setpoint=v_set, resistance=cart[:, _RES], traction=traction, power=traction * V,
            resistance_power=float(sc[_RES_POWER]), kinetic_energy=0.5 * float(sc[_MASS]) * V * V,
            jackknife_margin=float(sc[_MARGIN]))

    def warm_up(self, y) -> float:
        """Compile (or load from numba's cache) every kernel for the types the run passes; wall
        seconds it took (about 0 once done in this process)."""
        t0 = time.perf_counter()
        y = np.ascontiguousarray(y, dtype=np.float64)
        for code in sorted(METHOD_CODES.values()):
            self.tick(code, y, 0.0, 0.0, 1e-3, 1)
        self.rhs(y, 0.0, 0.0)
        _outputs(self.P, y, 0.0, 0.0)
        return time.perf_counter() - t0


def numba_version() -> str:
    import numba

    return numba.__version__
