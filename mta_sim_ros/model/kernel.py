"""The physics the simulator runs, written once: compiled by numba, or run as plain Python.

Everything a tick computes lives here, on one flat float64 array of the train's constants (``P``)
and the state array, in the subset of Python numba compiles (see ``jit.py`` for the two lives of
each function and for why all of it sits in one file):

    the packed constants   HEAD, CART and DRAFT declare each field once (name, meaning, value);
                           ``pack`` and every index the kernels use are derived from them
    rhs                    y' of the dynamic level by the article's algorithm 2 (MODEL.md [12]-[16],
                           [3], [9]-[11]): the chain walk fused with the mass M, its rate M' and
                           the force laws; with law KINEMATIC, the kinematic level's y' = (G V, psi_1',
                           V', 0)
    outputs                every reported quantity of a state (points, speeds, forces, power,
                           energy, jackknife margin)
    margin                 the jackknife margin the validity guards use
    switches               the points where a force law is not smooth (a governor limit engaging,
                           a speed crossing zero under a speed-proportional draft, ...)
    actuator_release       when the steering rate limit lets go, in closed form
    rk_step, advance       one step / one tick of any explicit Runge-Kutta tableau, with the step
                           split at the actuator's release and at every located switch

The readable reference the tests hold these to: ``chain.py`` (the recursion), ``dynamics.Model.terms``
(algorithm 2 term by term) and ``holonomic.py`` (algorithm 1). Arithmetic here is the reference's,
in the same order (IEEE, no fast-math), so the kernel's y' equals the reference's to the last bit.

State layout (dynamics.StateLayout): x_A1, y_A1, th_1..th_n, psi_1, V, z (index n + 4: the
governor's integral, or the kinematic level's ramp slope V').
"""
from __future__ import annotations

import math
from collections import namedtuple
from types import SimpleNamespace

import numpy as np

from . import forces
from .jit import entry, jitable


# -- the packed constants: each field declared once ------------------------------------------------

class Fields:
    """A block of P: (name, meaning, value from a context) per field. ``index`` is the named tuple
    of offsets the kernels read (``P[b + CART.index.mass]``), ``values(ctx)`` the numbers ``pack``
    writes. A named tuple of ints, not an IntEnum: numba compiles a global tuple's fields as
    constants on every version, while numba 0.59 (Ubuntu 24.04's) cannot index an array by an
    IntEnum member (0.68 can)."""

    def __init__(self, block: str, rows):
        self.block = block
        self.rows = tuple(rows)
        names = [name for name, _, _ in self.rows]
        self.index = namedtuple(block, names)(*range(len(names)))
        self.size = len(self.rows)
        self.meaning = {name: meaning for name, meaning, _ in self.rows}

    def values(self, ctx) -> list[float]:
        return [float(value(ctx)) for _, _, value in self.rows]


#: traction law codes; KINEMATIC is the kinematic level (speed prescribed, no forces in y')
CONSTANT, GOVERNOR, PRESCRIBED, KINEMATIC = 0, 1, 2, 3
LAWS = {"constant": CONSTANT, "governor": GOVERNOR, "prescribed_speed": PRESCRIBED, "kinematic": KINEMATIC}

HEAD = Fields("Head", (
    ("n", "number of carts n", lambda s: s.train.n),
    ("law", "traction law code (LAWS)", lambda s: LAWS[s.law]),
    ("smoothing_speed", "v0 of the resistances' tanh(v / v0) through v = 0, m/s", lambda s: s.train.smoothing_speed),
    ("time_constant", "steering actuator time constant tau, s", lambda s: s.train.actuator.time_constant),
    ("max_rate", "steering actuator rate limit, rad/s", lambda s: s.train.actuator.max_rate),
    ("max_angle", "steering angle limit, rad", lambda s: s.train.actuator.max_angle),
    ("force", "constant law: F_A1, N", lambda s: s.traction.force),
    ("max_force", "governor: adhesion limit of F_A1, N", lambda s: s.traction.max_force),
    ("max_power", "governor: engine power limit of F_A1 |V|, W", lambda s: s.traction.max_power),
    ("kp", "governor: proportional gain, N per m/s", lambda s: s.traction.kp),
    ("ki", "governor: integral gain, N per m", lambda s: s.traction.ki),
    ("windup_time", "governor: back-calculation anti-windup time, s", lambda s: s.traction.windup_time),
    ("response_time", "prescribed speed: first-order lag, s", lambda s: s.traction.response_time),
    ("max_accel", "prescribed speed: acceleration limit, m/s^2", lambda s: s.traction.max_accel),
    ("speed_switches", "1 when a draft grows with |speed| (ASABE B != 0): its speed's sign is a switch",
     lambda s: any(d.B != 0.0 for d in s.train.draft)),
))

CART = Fields("Cart", (
    ("length", "l_k, A_k to B_k, m", lambda s: s.cart.length),
    ("lam", "lambda_k = a_k / l_k", lambda s: s.cart.hitch_offset / s.cart.length),
    ("lam2", "lambda_k^2", lambda s: (s.cart.hitch_offset / s.cart.length) ** 2),
    ("mu", "mu_k = c_k / l_k", lambda s: s.cart.com_offset / s.cart.length),
    ("mu2", "mu_k^2", lambda s: (s.cart.com_offset / s.cart.length) ** 2),
    ("mass", "m_k, kg", lambda s: s.cart.mass),
    ("inertia", "J_k about C_k, kg m^2", lambda s: s.cart.yaw_inertia),
    ("rolling", "sum of the rolling elements' f m g at B_k, N", lambda s: s.resistance.rolling),
    ("draft_first", "index of this cart's first draft in the DRAFT block", lambda s: s.draft_first),
    ("draft_count", "number of drafts at this cart's B_k", lambda s: len(s.resistance.drafts)),
    ("max_hitch", "largest |hitch angle| of the coupling in front of this cart, rad", lambda s: s.cart.max_hitch_angle),
    ("com_offset", "c_k, B_k forward to C_k, m", lambda s: s.cart.com_offset),
    ("hitch_offset", "a_k, B_k back to A_{k+1}, m", lambda s: s.cart.hitch_offset),
))

DRAFT = Fields("Draft", (
    ("soil_factor", "F_i", lambda d: d.soil_factor),
    ("A", "ASABE D497 A, N per width per depth", lambda d: d.A),
    ("B", "B, per km/h", lambda d: d.B),
    ("C", "C, per (km/h)^2", lambda d: d.C),
    ("width", "W, m or rows/tools", lambda d: d.width),
    ("depth", "T, cm (1 for seeding tools)", lambda d: d.depth),
))

H, C, D = HEAD.index, CART.index, DRAFT.index
HEAD_SIZE, CART_SIZE, DRAFT_SIZE = HEAD.size, CART.size, DRAFT.size


def pack(train, law: str | None = None, traction=None) -> np.ndarray:
    """The constants of ``train`` as one float64 array: HEAD, then CART per cart, then DRAFT per
    draft (grouped by cart). ``law`` / ``traction`` override the train's traction law (the
    kinematic level packs law 'kinematic' and, for its inverse dynamics, 'prescribed_speed')."""
    traction = traction or train.traction
    law = law or traction.law
    if law not in LAWS:
        raise ValueError(f"traction law {law!r} has no kernel (one of {', '.join(LAWS)})")
    values = HEAD.values(SimpleNamespace(train=train, law=law, traction=traction))
    drafts = []
    for k, (cart, resistance) in enumerate(zip(train.carts, forces.cart_resistances(train))):
        values += CART.values(SimpleNamespace(cart=cart, resistance=resistance, draft_first=len(drafts)))
        drafts += resistance.drafts
    for d in drafts:
        values += DRAFT.values(d)
    return np.array(values, dtype=np.float64)


def column(P: np.ndarray, name: str) -> tuple[float, ...]:
    """One CART field of every cart, read from the packed array (for the reference code)."""
    n, i = int(P[H.n]), getattr(C, name)
    return tuple(float(P[HEAD_SIZE + CART_SIZE * k + i]) for k in range(n))


# -- small pieces ---------------------------------------------------------------------------------

@jitable
def pymin(a, b):
    """Python's min(a, b): a unless b is strictly smaller (the same answer for -0.0 and NaN)."""
    return b if b < a else a


@jitable
def pymax(a, b):
    return b if b > a else a


#: a branch left to the state (natural), or held: LOW where the switching function is <= 0, HIGH > 0
NATURAL, LOW, HIGH = -1, 0, 1


@jitable
def steering_rate(P, psi1, command, branch):
    """psi_1' = clip((clip(command, +-max_angle) - psi_1) / tau, +-max_rate) (actuator.py); with
    ``branch`` HIGH the rate limit's side (+-max_rate), LOW the linear side, NATURAL as the state is."""
    max_angle, max_rate = P[H.max_angle], P[H.max_rate]
    target = pymin(pymax(command, -max_angle), max_angle)
    if branch == NATURAL:
        return pymin(pymax((target - psi1) / P[H.time_constant], -max_rate), max_rate)
    if branch == HIGH:
        return max_rate if target > psi1 else -max_rate
    return (target - psi1) / P[H.time_constant]


@jitable
def held_abs(x, branch):
    """|x|, or with a held branch the side of it (+x for HIGH, -x for LOW)."""
    if branch == NATURAL:
        return abs(x)
    return x if branch == HIGH else -x


@jitable
def resistance_magnitude(P, rolling, first, count, axle_speed, branch):
    """f m g plus the drafts D = F_i (A + B S + C S^2) W T at one axle, S = |speed| in km/h, summed
    in the order of forces.CartResistance.force (``branch``: the sign of the speed, see held_abs)."""
    total = rolling
    base = HEAD_SIZE + CART_SIZE * int(P[H.n])
    for i in range(first, first + count):
        d = base + DRAFT_SIZE * i
        S = held_abs(axle_speed, branch) * forces.MS_TO_KMH
        total += P[d + D.soil_factor] * (P[d + D.A] + P[d + D.B] * S + P[d + D.C] * S * S) * P[d + D.width] \
            * P[d + D.depth]
    return total


TWO_PI = 2.0 * math.pi


@jitable
def wrap_angle(a):
    """a wrapped to [-pi, pi] (geometry.wrap_angle; exact inside the interval)."""
    if -math.pi <= a <= math.pi:
        return a
    return a - TWO_PI * math.floor(a / TWO_PI + 0.5)


# -- the equations -----------------------------------------------------------------------------------

#: columns of ``rec`` (rhs's record of each cart's chain factors, for the outputs)
KAPT, KAPB, KAPC, PSI, RES, KAPT_DOT, KAPB_DOT = range(7)
REC = 7


@jitable
def rhs(P, y, command, v_set, dy, rec, mode):
    """y' into ``dy``; returns (F_A1, M). When ``rec`` has rows (n x REC or wider), each cart's
    kapT, kapB, kapC, psi and resistance F_Bk go into its first REC columns. ``mode`` (empty, or
    one branch per switch: ``branches``) holds each non-smooth law on one of its branches, as a
    step between two kinks needs (outside its own region a held branch is the smooth extension).

    The chain (chain.py): walking back from the tractor, V_k = kap_k V and psi_k give
    th'_k = kap_k sin(psi_k) V / l_k, s'_Bk = kap_k cos(psi_k) V, s'_Ck = kap_k rc_k V; each rate
    ``*_dot`` is the exact time derivative of the line above it. Algorithm 2 (dynamics.py):
    M = sum m kapC^2 + J kapT^2, R = 1/2 M' V, M V' = F_A1 - sum F_Bk kapB_k - R."""
    n = int(P[H.n])
    law = int(P[H.law])
    forces_on = law != KINEMATIC
    held = mode.shape[0] > 0
    i_sat, i_limit, i_floor, i_accel, i_speed = switch_layout(P)
    psi1, V, z = y[n + 2], y[n + 3], y[n + 4]
    psi_rate = steering_rate(P, psi1, command, mode[0] if held else NATURAL)
    v0 = P[H.smoothing_speed]

    mass = 0.0
    mass_rate = 0.0
    generalized_resistance = 0.0
    k_val, k_dot = 1.0, 0.0  # kap_1 = 1
    p_val, p_dot = psi1, psi_rate
    theta_rate_prev = 0.0
    beta_dot_prev = 0.0
    last = n - 1
    for k in range(n):
        b = HEAD_SIZE + CART_SIZE * k
        l_k = P[b + C.length]
        s, c = math.sin(p_val), math.cos(p_val)
        t_val = k_val * s / l_k  # kapT_k
        theta_rate = t_val * V
        if k:  # psi_k = th_{k-1} - th_k - beta_{k-1}
            p_dot = theta_rate_prev - theta_rate - beta_dot_prev
        s_dot, c_dot = c * p_dot, -s * p_dot
        b_val = k_val * c  # kapB_k
        cc = c * c
        if forces_on:
            mu2 = P[b + C.mu2]
            t_dot = (k_dot * s + k_val * s_dot) / l_k
            rc = math.sqrt(cc + mu2 * s * s)  # s'_Ck / V_k; (mu2 * s) * s rounds as chain's mu * mu * s * s
            rc_dot = (c * c_dot + mu2 * s * s_dot) / rc
            kc_val = k_val * rc  # kapC_k
            kc_dot = k_dot * rc + k_val * rc_dot
            m, J = P[b + C.mass], P[b + C.inertia]
            mass += m * kc_val * kc_val + J * t_val * t_val
            mass_rate += 2.0 * (m * kc_val * kc_dot + J * t_val * t_dot)
            axle_speed = b_val * V
            count = int(P[b + C.draft_count])
            branch = NATURAL
            if held and i_speed >= 0 and count > 0:
                branch = mode[1 + i_speed]
                i_speed += 1
            magnitude = resistance_magnitude(P, P[b + C.rolling], int(P[b + C.draft_first]), count, axle_speed,
                                             branch)
            resistance = magnitude * math.tanh(axle_speed / v0)
            generalized_resistance += resistance * b_val
            if rec.shape[0]:
                rec[k, KAPC], rec[k, RES] = kc_val, resistance
                rec[k, KAPT_DOT], rec[k, KAPB_DOT] = t_dot, k_dot * c + k_val * c_dot
        if rec.shape[0]:
            rec[k, KAPT], rec[k, KAPB], rec[k, PSI] = t_val, b_val, p_val
        dy[2 + k] = theta_rate
        if k < last:  # on to cart k + 1: V_{k+1} = V_k rl_k, psi_{k+1} = th_k - th_{k+1} - beta_k
            lam, lam2 = P[b + C.lam], P[b + C.lam2]
            rl2 = cc + lam2 * s * s
            rl = math.sqrt(rl2)
            rl_dot = (c * c_dot + lam2 * s * s_dot) / rl
            beta = math.atan2(lam * s, c)
            beta_dot_prev = lam * p_dot / rl2  # d/dt atan2(lam s, c)
            k_val, k_dot = k_val * rl, k_dot * rl + k_val * rl_dot
            p_val = y[2 + k] - y[3 + k] - beta
            theta_rate_prev = theta_rate

    traction = 0.0
    governor_rate = 0.0
    if law == KINEMATIC:
        acceleration = z  # the ramp slope of this tick (kinematic.py)
    else:
        velocity_term = 0.5 * mass_rate * V
        if law == PRESCRIBED:  # forces.prescribed_acceleration, then inverse dynamics
            a = (v_set - V) / P[H.response_time]
            acceleration = clip_held(a, P[H.max_accel], mode[1 + i_accel] if held and i_accel >= 0 else NATURAL)
            traction = mass * acceleration + generalized_resistance + velocity_term
        else:
            if law == GOVERNOR:  # forces.governor
                error = v_set - V
                u = P[H.kp] * error + z
                limit = traction_limit(P, V, mode[1 + i_limit] if held and i_limit >= 0 else NATURAL,
                                       mode[1 + i_floor] if held and i_floor >= 0 else NATURAL)
                traction = clip_held(u, limit, mode[1 + i_sat] if held and i_sat >= 0 else NATURAL)
                governor_rate = P[H.ki] * error + (traction - u) / P[H.windup_time]
            else:
                traction = P[H.force]
            acceleration = (traction - generalized_resistance - velocity_term) / mass
    course = y[2] + psi1  # direction of v_A1
    dy[0] = V * math.cos(course)
    dy[1] = V * math.sin(course)
    dy[n + 2] = psi_rate
    dy[n + 3] = acceleration
    dy[n + 4] = governor_rate
    return traction, mass


@jitable
def clip_held(x, limit, branch):
    """x clipped to +-limit (Python's min(max(x, -limit), limit)); with a held branch, x itself (LOW)
    or the limit on x's side (HIGH)."""
    if branch == NATURAL:
        return pymin(pymax(x, -limit), limit)
    if branch == LOW:
        return x
    return limit if x > 0.0 else -limit


@jitable
def traction_limit(P, V, limit_branch, floor_branch):
    """Largest |F_A1| at speed V: adhesion, and engine power over speed (forces.traction_limit),
    min(max_force, max_power / max(|V|, 0.1)); held branches: the power limit (HIGH) or the force
    limit (LOW) of the min, |V| (HIGH) or 0.1 (LOW) of the max."""
    if math.isinf(P[H.max_power]):
        return P[H.max_force]
    if floor_branch == NATURAL:
        speed = pymax(abs(V), 0.1)
    else:
        speed = abs(V) if floor_branch == HIGH else 0.1
    if limit_branch == NATURAL:
        return pymin(P[H.max_force], P[H.max_power] / speed)
    return P[H.max_power] / speed if limit_branch == HIGH else P[H.max_force]


@jitable
def margin(P, y):
    """(smallest jackknife margin over the hitches, rad; index of that cart, -1 for none): per
    cart k >= 2, min(max_hitch_k - |phi_k|, pi/2 - |psi_k|) with psi_k from the chain (guards.py)."""
    n = int(P[H.n])
    best, where = math.inf, -1
    p_val = y[n + 2]
    for k in range(n - 1):
        b = HEAD_SIZE + CART_SIZE * k
        lam = P[b + C.lam]
        beta = math.atan2(lam * math.sin(p_val), math.cos(p_val))
        p_val = y[2 + k] - y[3 + k] - beta  # psi_{k+1}
        phi = wrap_angle(y[2 + k] - y[3 + k])
        m = min(P[b + CART_SIZE + C.max_hitch] - abs(phi), 0.5 * math.pi - abs(p_val))
        if m < best:
            best, where = m, k + 1
    return best, where


#: closer than this to a jackknife limit (rad), the Python guard (guards.check_state) decides
GUARD_SLACK = 1e-9


@jitable
def clear(P, y):
    """True when y is finite and every hitch is more than GUARD_SLACK inside its limits."""
    for i in range(y.shape[0]):
        if not math.isfinite(y[i]):
            return False
    return margin(P, y)[0] > GUARD_SLACK


#: per-cart output columns after the REC ones: A, B, C (x, y), hitch angle phi_k, s'_Ck, s'_Bk, th'_k,
#: the drawbar pull at A_k (written by ``drawbar_pulls`` only, after ``outputs``: the node's tick,
#: which publishes no pull, does not compute it)
AX, AY, BX, BY, CX, CY, PHI, VC, VB, VT, PULL = range(REC, REC + 11)
OUT = REC + 11
#: scalar outputs
REAR_X, REAR_Y, TRACTION, MASS, RES_POWER, MARGIN = range(6)
SCALARS = 6


@jitable
def outputs(P, y, command, v_set, cart, sc, dy):
    """Every reported quantity of state y into ``cart`` (n x OUT) and ``sc`` (SCALARS): the points
    of geometry.cart_points, the chain's factors times V, the forces, and the jackknife margin."""
    n = int(P[H.n])
    traction, mass = rhs(P, y, command, v_set, dy, cart, no_mode())
    V = y[n + 3]
    ax, ay = y[0], y[1]
    res_power = 0.0
    best = math.inf
    for k in range(n):
        b = HEAD_SIZE + CART_SIZE * k
        th = y[2 + k]
        ex, ey = math.cos(th), math.sin(th)
        cart[k, AX], cart[k, AY] = ax, ay
        bx, by = ax - P[b + C.length] * ex, ay - P[b + C.length] * ey
        cart[k, BX], cart[k, BY] = bx, by
        cart[k, CX], cart[k, CY] = bx + P[b + C.com_offset] * ex, by + P[b + C.com_offset] * ey
        ax, ay = bx - P[b + C.hitch_offset] * ex, by - P[b + C.hitch_offset] * ey
        cart[k, VC], cart[k, VB], cart[k, VT] = cart[k, KAPC] * V, cart[k, KAPB] * V, cart[k, KAPT] * V
        cart[k, PULL] = math.nan  # not computed here (drawbar_pulls)
        res_power += cart[k, RES] * cart[k, VB]
        if k:
            phi = wrap_angle(y[1 + k] - th)
            cart[k, PHI] = phi
            m = min(P[b + C.max_hitch] - abs(phi), 0.5 * math.pi - abs(cart[k, PSI]))
            if m < best:
                best = m
        else:
            cart[k, PHI] = 0.0
    sc[REAR_X], sc[REAR_Y] = ax, ay
    sc[TRACTION], sc[MASS], sc[RES_POWER], sc[MARGIN] = traction, mass, res_power, best
    return traction


@jitable
def drawbar_pulls(P, y, acceleration, cart):
    """The pull at each hitch A_k (k >= 2) along the towed cart's axis e_k, N, into cart[k, PULL]:
    the constraint force of the model, by Newton-Euler on each towed cart from the last forward.
    Cart k (unit axis e_k, normal n_k, th_k) carries the hitch force H_k at A_k, -H_{k+1} at A_{k+1},
    the resistance -F_Bk e_k and the tyres' lateral force N_k n_k at B_k. With the centre of mass
    C_k = B_k + c_k e_k, its acceleration a_e = d(s'_Bk)/dt - c_k th'_k^2, a_n = s'_Bk th'_k + c_k th''_k,
    where d(s'_Bk)/dt = kapB' V + kapB V' and th''_k = kapT' V + kapT V' (the chain's rates, ``rhs``):

        H_k . e_k = H_{k+1} . e_k + F_Bk + m_k a_e                          (Newton along e_k)
        H_k . n_k = (J_k th''_k + c_k m_k a_n - a_k H_{k+1} . n_k) / l_k   (Euler about C_k, N_k eliminated)

    ``cart`` holds the REC and VB, VT columns of ``outputs`` (``acceleration`` its dy[n + 3]); cart[0, PULL] is 0 (the traction
    at A_1 is ``outputs``' own). On a straight line at constant speed the pull at A_k is the sum of
    the resistances behind it (test_sweep_metrics)."""
    n = int(P[H.n])
    V = y[n + 3]
    hx, hy = 0.0, 0.0  # H_{k+1}, world frame
    for k in range(n - 1, 0, -1):
        b = HEAD_SIZE + CART_SIZE * k
        th = y[2 + k]
        ex, ey = math.cos(th), math.sin(th)
        nx, ny = -ey, ex
        com = P[b + C.com_offset]
        m = P[b + C.mass]
        rate = cart[k, VT]
        rate_dot = cart[k, KAPT_DOT] * V + cart[k, KAPT] * acceleration
        speed_dot = cart[k, KAPB_DOT] * V + cart[k, KAPB] * acceleration
        a_e = speed_dot - com * rate * rate
        a_n = cart[k, VB] * rate + com * rate_dot
        h_e = hx * ex + hy * ey + cart[k, RES] + m * a_e
        h_n = (P[b + C.inertia] * rate_dot + com * m * a_n - P[b + C.hitch_offset] * (hx * nx + hy * ny)) / P[b + C.length]
        cart[k, PULL] = h_e
        hx, hy = h_e * ex + h_n * nx, h_e * ey + h_n * ny
    cart[0, PULL] = 0.0


# -- where the right-hand side is not smooth ----------------------------------------------------------

#: most switching functions ``switches`` writes beyond the per-cart ones
FORCE_SWITCHES = 3


@jitable
def switch_layout(P):
    """Where each switching function sits in ``switches``'s list (-1: not in this model):
    (governor saturation, governor force/power limit, governor speed floor, prescribed-speed
    acceleration limit, first draft speed sign)."""
    law = int(P[H.law])
    m = 0
    i_sat = i_limit = i_floor = i_accel = i_speed = -1
    if law == GOVERNOR:
        force_finite, power_finite = not math.isinf(P[H.max_force]), not math.isinf(P[H.max_power])
        if force_finite or power_finite:
            i_sat, m = m, m + 1
        if power_finite:
            if force_finite:
                i_limit, m = m, m + 1
            i_floor, m = m, m + 1
    elif law == PRESCRIBED and not math.isinf(P[H.max_accel]):
        i_accel, m = m, m + 1
    if P[H.speed_switches] != 0.0 and law != KINEMATIC:
        i_speed = m
    return i_sat, i_limit, i_floor, i_accel, i_speed


@jitable
def switches(P, y, command, v_set, g):
    """The force laws' switching functions at y into g; returns how many. Each is continuous and
    changes sign exactly where a law changes branch (a kink of y'):
        governor          |u| - limit(V) (the force limit engages), max_force max(|V|, 0.1) - max_power
                          (the power limit is below the adhesion limit), |V| - 0.1 (the power
                          limit's speed floor)
        prescribed speed  |v_set - V| / response_time - max_accel (the acceleration limit)
        drafts with B     s'_Bk of each cart with drafts (|S| has a corner at 0)
    The actuator's rate limit is handled in closed form (``actuator_release``)."""
    n = int(P[H.n])
    V, z = y[n + 3], y[n + 4]
    i_sat, i_limit, i_floor, i_accel, i_speed = switch_layout(P)
    if i_sat >= 0:
        g[i_sat] = abs(P[H.kp] * (v_set - V) + z) - traction_limit(P, V, NATURAL, NATURAL)
    if i_limit >= 0:
        g[i_limit] = P[H.max_force] * pymax(abs(V), 0.1) - P[H.max_power]
    if i_floor >= 0:
        g[i_floor] = abs(V) - 0.1
    if i_accel >= 0:
        g[i_accel] = abs(v_set - V) / P[H.response_time] - P[H.max_accel]
    m = max(i_sat, i_limit, i_floor, i_accel) + 1
    if i_speed >= 0:
        k_val = 1.0
        p_val = y[n + 2]
        for k in range(n):
            b = HEAD_SIZE + CART_SIZE * k
            s, c = math.sin(p_val), math.cos(p_val)
            if P[b + C.draft_count] > 0:
                g[m] = k_val * c * V  # s'_Bk
                m += 1
            if k < n - 1:
                k_val = k_val * math.sqrt(c * c + P[b + C.lam2] * s * s)
                p_val = y[2 + k] - y[3 + k] - math.atan2(P[b + C.lam] * s, c)
    return m


@jitable
def branches(g, m, mode):
    """mode[1 + j] = the branch switching function j is on (HIGH where g_j > 0, else LOW)."""
    for j in range(m):
        mode[1 + j] = HIGH if g[j] > 0.0 else LOW


@jitable
def actuator_release(P, psi1, command):
    """Time (s) until the steering actuator leaves its rate limit, with the command held: inf when
    it is not rate-limited. While limited, psi_1 moves at +-max_rate exactly (a straight line), and
    the limit lets go where |target - psi_1| = tau max_rate."""
    max_angle, max_rate, tau = P[H.max_angle], P[H.max_rate], P[H.time_constant]
    target = pymin(pymax(command, -max_angle), max_angle)
    gap = abs(target - psi1)
    if not gap / tau > max_rate:
        return math.inf
    return (gap - tau * max_rate) / max_rate


@jitable
def actuator_psi(P, psi0, command, release, T):
    """psi_1 at T s into a tick that started at psi0, the command held: the actuator's closed-form
    motion (rate-limited at +-max_rate until ``release``, ``actuator_release``; then the first-order
    lag, exp(-t / tau) towards the clipped command)."""
    max_angle, max_rate, tau = P[H.max_angle], P[H.max_rate], P[H.time_constant]
    target = pymin(pymax(command, -max_angle), max_angle)
    if math.isinf(release):
        return target + (psi0 - target) * math.exp(-T / tau)
    sign = 1.0 if target > psi0 else -1.0
    if T <= release:
        return psi0 + sign * max_rate * T
    return target - sign * tau * max_rate * math.exp(-(T - release) / tau)


@jitable
def no_switches(P, y, command, v_set, g):
    """``switches`` for a right-hand side without known switches."""
    return 0


@jitable
def no_mode():
    """No branch held: every law as the state is."""
    return np.empty(0, dtype=np.int64)


# -- explicit Runge-Kutta, any tableau ----------------------------------------------------------------

@jitable
def model_rhs(P, t, y, command, v_set, dy, rec, mode):
    """The stepping routine's form of ``rhs`` (t does not enter: the input is held)."""
    rhs(P, y, command, v_set, dy, rec, mode)


@jitable
def rk_step(f, P, T, t, y, command, v_set, h, K, tmp, out, rec, mode, lag):
    """One step of length h of the explicit tableau T from y into ``out``; returns the stages.

    ``lag`` = (on, psi0, command, release, T0): when on, the steering angle psi_1 is not stepped
    but taken from the actuator's closed form (``actuator_psi``) at each stage's time, T0 + c_i h
    after the tick's start: the actuator is a first-order lag of its own (nothing feeds back into
    it), so the train is stepped under its exact steering, and the actuator's fast pole -1/tau
    limits neither the accuracy nor the stability of the step.

    T (``integrate.tableau.Tableau.packed``) holds the tableau as the classic methods are
    printed, integer numerators over a common denominator per row: row i < s is (d_i, a_i0 ..
    a_i,s-1), stage i is y + (h / d_i) sum_j a_ij k_j; row s is (d, b_0 .. b_s-1), the step
    y + (h / d) sum_j b_j k_j; row s + 1 is (0, c_0 .. c_s-1). Sums run left to right over the
    non-zero entries: for euler, heun and rk4 the arithmetic of their textbook formulas, to the
    last bit."""
    stages = T.shape[0] - 2
    size = y.shape[0]
    exact = lag[0] != 0.0
    ip = int(P[H.n]) + 2 if exact else 0
    f(P, t, y, command, v_set, K[0], rec, mode)
    for i in range(1, stages + 1):
        scale = h / T[i, 0]
        for m in range(size):
            acc = 0.0
            first = True
            for j in range(i if i < stages else stages):
                a = T[i, 1 + j]
                if a != 0.0:
                    term = a * K[j, m]
                    acc = term if first else acc + term
                    first = False
            value = y[m] if first else y[m] + scale * acc
            if i < stages:
                tmp[m] = value
            else:
                out[m] = value
        if i < stages:
            if exact:
                tmp[ip] = actuator_psi(P, lag[1], lag[2], lag[3], lag[4] + T[stages + 1, 1 + i] * h)
            f(P, t + T[stages + 1, 1 + i] * h, tmp, command, v_set, K[i], rec, mode)
    if exact:
        out[ip] = actuator_psi(P, lag[1], lag[2], lag[3], lag[4] + h)
    return stages


#: most splits in one step (a switch crossed back and forth); past it the step is taken whole
MAX_SPLITS = 16
#: a kink closer than this share of a step to either end of it is at that end (no split)
EDGE = 1e-12


@jitable
def _changed(g0, g1, m, changed):
    """Which of the first m switching functions changed sign (> 0 against not > 0); how many."""
    count = 0
    for j in range(m):
        changed[j] = (g0[j] > 0.0) != (g1[j] > 0.0)
        if changed[j]:
            count += 1
    return count


@jitable
def illinois_point(lo, hi, f_lo, f_hi):
    """The next trial of the Illinois method (regula falsi) on the bracket [lo, hi]."""
    tau = (lo * f_hi - hi * f_lo) / (f_hi - f_lo) if f_hi != f_lo else 0.5 * (lo + hi)
    return tau if lo < tau < hi else 0.5 * (lo + hi)


@jitable
def illinois_update(lo, hi, f_lo, f_hi, side, tau, f_tau, far):
    """The bracket after a trial (tau, f_tau): the end whose sign it shares moves to it, and the
    other end's value is halved when the same end moved twice running (Illinois), which keeps
    the convergence superlinear. ``far`` is the sign (> 0) of the bracket's far end. Returns
    (lo, hi, f_lo, f_hi, side), side = +1 when hi moved, -1 when lo did."""
    if (f_tau > 0.0) == far:
        if side == 1:
            f_lo *= 0.5
        return lo, tau, f_lo, f_tau, 1
    if side == -1:
        f_hi *= 0.5
    return tau, hi, f_tau, f_hi, -1


@jitable
def _locate(f, sw, P, T, t, y, command, v_set, h, j, g_lo, g_hi, K, tmp, trial, rec, mode, lag, g):
    """The step length in (0, h] at which switching function j changes sign along this method's
    step from y with the branches ``mode`` held (the Illinois method on tau -> g_j(step(y, tau))).
    Returns (tau on the far side of the switch, right-hand sides evaluated)."""
    lo, hi = 0.0, h
    f_lo, f_hi = g_lo, g_hi
    far = f_hi > 0.0
    side = 0
    nfev = 0
    for _ in range(100):
        if hi - lo <= 4e-16 * h + 1e-300:
            break
        tau = illinois_point(lo, hi, f_lo, f_hi)
        nfev += rk_step(f, P, T, t, y, command, v_set, tau, K, tmp, trial, rec, mode, lag)
        sw(P, trial, command, v_set, g)
        lo, hi, f_lo, f_hi, side = illinois_update(lo, hi, f_lo, f_hi, side, tau, g[j], far)
    return hi, nfev


@jitable
def advance(f, sw, P, T, y0, command, v_set, t0, t1, max_step, split):
    """Integrate from t0 to t1 with the input held: ceil((t1 - t0) / max_step) equal steps of the
    tableau T. Returns (y1, right-hand sides evaluated, kinks split at).

    With ``split``, each step runs on one branch of every non-smooth law (``mode``: the branch at
    the step's start, held for all its stages), and a step that holds a kink is cut there and
    finished from it on the new branch: at the actuator's release (closed form,
    ``actuator_release``) and where a switching function (``sw``) changes sign (located along the
    held-branch step, ``_locate``). Each piece then integrates a smooth right-hand side, and the
    method keeps its order. A kernel model's steering angle then follows the actuator's closed
    form (``actuator_psi``, see ``rk_step``). Without ``split`` every law follows the state and
    psi_1 is stepped like the rest (the code before kink splitting, bit for bit)."""
    return advance_in(f, sw, P, T, y0, command, v_set, t0, t1, max_step, split, workspace(P, T, y0.shape[0]))


@jitable
def workspace(P, T, size):
    """The arrays ``advance_in`` works in: (K, tmp, y, y1, rec, lag, g0, g1, g, changed, mode, trial)."""
    n = int(P[H.n]) if P.shape[0] else 0
    width = FORCE_SWITCHES + n + 1
    return (np.empty((T.shape[0] - 2, size)), np.empty(size), np.empty(size), np.empty(size), np.empty((0, REC)),
            np.zeros(5), np.empty(width), np.empty(width), np.empty(width), np.zeros(width, dtype=np.bool_),
            np.full(1 + width, NATURAL, dtype=np.int64), np.empty(size))


@jitable
def advance_in(f, sw, P, T, y0, command, v_set, t0, t1, max_step, split, work):
    """``advance`` in the arrays of ``workspace`` (a whole run allocates them once, ``run``)."""
    K, tmp, y, y1, rec, lag, g0, g1, g, changed, mode, trial = work
    y[:] = y0
    count = max(1, math.ceil((t1 - t0) / max_step - 1e-9))
    h = (t1 - t0) / count
    nfev = 0
    lag[:] = 0.0
    if not split:
        natural = no_mode()
        for i in range(count):
            nfev += rk_step(f, P, T, t0 + i * h, y, command, v_set, h, K, tmp, y1, rec, natural, lag)
            y, y1 = y1, y
        return y.copy(), nfev, 0
    n = int(P[H.n]) if P.shape[0] else 0
    changed[:] = False
    mode[:] = NATURAL
    kinks = 0
    release = actuator_release(P, y[n + 2], command) if P.shape[0] else math.inf
    released = not EDGE * h < release < math.inf  # not rate-limited, or letting go at the start
    if P.shape[0]:  # a kernel model: its actuator in closed form (rk_step)
        lag[0], lag[1], lag[2], lag[3] = 1.0, y[n + 2], command, release
    m = sw(P, y, command, v_set, g0)
    branches(g0, m, mode)
    for i in range(count):
        ts = t0 + i * h
        done = 0.0  # time already stepped inside this step
        splits = 0
        while True:
            left = h - done
            length = left
            at_release = False
            if not released:
                until = release - (i * h + done)
                if until <= EDGE * h:
                    released = True
                elif until < left - EDGE * h:
                    length, at_release = until, True
            mode[0] = LOW if released else HIGH
            lag[4] = i * h + done
            nfev += rk_step(f, P, T, ts + done, y, command, v_set, length, K, tmp, y1, rec, mode, lag)
            sw(P, y1, command, v_set, g1)
            if m and splits < MAX_SPLITS and _changed(g0, g1, m, changed):
                tau = length
                for j in range(m):
                    if changed[j]:
                        tj, used = _locate(f, sw, P, T, ts + done, y, command, v_set, length, j, g0[j], g1[j],
                                           K, tmp, trial, rec, mode, lag, g)
                        nfev += used
                        tau = pymin(tau, tj)
                if EDGE * h < tau < length - EDGE * h:
                    nfev += rk_step(f, P, T, ts + done, y, command, v_set, tau, K, tmp, y1, rec, mode, lag)
                    y, y1 = y1, y
                    sw(P, y, command, v_set, g0)
                    branches(g0, m, mode)
                    done += tau
                    splits += 1
                    kinks += 1
                    continue
            y, y1 = y1, y
            g0, g1 = g1, g0
            branches(g0, m, mode)
            if at_release:
                released = True
                kinks += 1
                splits += 1
                done += length
                continue
            break
    return y.copy(), nfev, kinks


# -- entry points (compiled; ``.py_func`` is the plain-Python path) ----------------------------------

@entry
def rhs_of(P, y, command, v_set):
    """y' as a new array (dynamics.Model.rhs)."""
    dy = np.empty(y.shape[0])
    rhs(P, y, command, v_set, dy, np.empty((0, REC)), no_mode())
    return dy


@entry
def held_rhs_of(P, y, command, v_set, mode):
    """y' with the branches ``mode`` held (see ``rhs``, ``mode_of``)."""
    dy = np.empty(y.shape[0])
    rhs(P, y, command, v_set, dy, np.empty((0, REC)), mode)
    return dy


@entry
def mode_of(P, y, command, v_set, rate_limited):
    """The branches of every law at y: the actuator's (HIGH while ``rate_limited``), then each
    switching function's (``branches``)."""
    g = np.empty(FORCE_SWITCHES + int(P[H.n]) + 1)
    mode = np.full(g.shape[0] + 1, NATURAL, dtype=np.int64)
    branches(g, switches(P, y, command, v_set, g), mode)
    mode[0] = HIGH if rate_limited else LOW
    return mode


@entry
def tick(P, T, y0, command, v_set, t0, t1, max_step, split):
    """One tick of the model from t0 to t1 (``advance`` on ``rhs`` and ``switches``). Returns
    (y1, clear, right-hand sides evaluated, kinks split at); clear: see ``clear``."""
    y, nfev, kinks = advance(model_rhs, switches, P, T, y0, command, v_set, t0, t1, max_step, split)
    return y, clear(P, y), nfev, kinks


@entry
def outputs_of(P, y, command, v_set):
    """(cart n x OUT, scalars SCALARS) of ``outputs``."""
    n = int(P[H.n])
    cart = np.empty((n, OUT))
    sc = np.empty(SCALARS)
    outputs(P, y, command, v_set, cart, sc, np.empty(y.shape[0]))
    return cart, sc


@entry
def pulls_of(P, y, command, v_set):
    """(cart n x OUT, scalars) of ``outputs`` with the drawbar pulls' column (``drawbar_pulls``)."""
    n = int(P[H.n])
    cart = np.empty((n, OUT))
    sc = np.empty(SCALARS)
    dy = np.empty(y.shape[0])
    outputs(P, y, command, v_set, cart, sc, dy)
    drawbar_pulls(P, y, dy[n + 3], cart)
    return cart, sc


@entry
def margin_of(P, y):
    """``margin``: (margin, cart index)."""
    return margin(P, y)


@entry
def switches_of(P, y, command, v_set):
    """The switching functions at y, as a new array."""
    g = np.empty(FORCE_SWITCHES + int(P[H.n]) + 1)
    m = switches(P, y, command, v_set, g)
    return g[:m].copy()


@entry
def release_of(P, psi1, command):
    """``actuator_release``."""
    return actuator_release(P, psi1, command)


# -- a whole run in one call (a sweep's runs, ``batch.py``) --------------------------------------------

#: columns of a run's trace row: the scalars, then TRACE_CART per cart
TR_TRACTION, TR_SPEED, TR_MARGIN, TR_STEERING = range(4)
TRACE_HEAD = 4
TR_BX, TR_BY, TR_HEADING, TR_PHI, TR_PULL = range(5)
TRACE_CART = 5


@jitable
def trace_row(P, y, command, law_input, cart, sc, dy, row):
    """The outputs of a run's trace at state y into ``row`` (TRACE_HEAD + TRACE_CART n)."""
    n = int(P[H.n])
    outputs(P, y, command, law_input, cart, sc, dy)
    drawbar_pulls(P, y, dy[n + 3], cart)
    row[TR_TRACTION], row[TR_SPEED], row[TR_MARGIN], row[TR_STEERING] = sc[TRACTION], y[n + 3], sc[MARGIN], y[n + 2]
    for k in range(n):
        j = TRACE_HEAD + TRACE_CART * k
        row[j + TR_BX], row[j + TR_BY], row[j + TR_HEADING] = cart[k, BX], cart[k, BY], y[2 + k]
        row[j + TR_PHI], row[j + TR_PULL] = cart[k, PHI], cart[k, PULL]


@entry
def trace_of(P_out, y, command, law_input):
    """One trace row (``trace_row``) as a new array: a run's row 0."""
    n = int(P_out[H.n])
    row = np.empty(TRACE_HEAD + TRACE_CART * n)
    trace_row(P_out, y, command, law_input, np.empty((n, OUT)), np.empty(SCALARS), np.empty(y.shape[0]), row)
    return row


@entry
def run(P, P_out, T, y0, commands, v_sets, tick, max_step, split, start, trace):
    """Ticks start, start + 1, ... of a run, tick i from t = i tick holding commands[i] and v_sets[i],
    as ``Simulation.advance`` runs them (the kinematic level's speed ramp set at each tick's start,
    ``kinematic.begin_tick``); after tick i the outputs of P_out into trace[i + 1] (``trace_row``;
    the kinematic level reports its inverse dynamics under V + V'). Stops after the first tick whose
    state is not ``clear`` (the caller's guards.check_state decides) or after the last. Returns
    (y, ticks done, right-hand sides evaluated, kinks split at)."""
    n = int(P[H.n])
    kinematic = int(P[H.law]) == KINEMATIC
    cart = np.empty((n, OUT))
    sc = np.empty(SCALARS)
    dy = np.empty(y0.shape[0])
    y = y0.copy()
    nfev = 0
    kinks = 0
    work = workspace(P, T, y0.shape[0])
    for i in range(start, commands.shape[0]):
        t0 = i * tick
        if kinematic:
            y[n + 4] = (v_sets[i] - y[n + 3]) / tick
        y1, used, split_at = advance_in(model_rhs, switches, P, T, y, commands[i], v_sets[i], t0, t0 + tick,
                                        max_step, split, work)
        y[:] = y1
        nfev += used
        kinks += split_at
        law_input = y[n + 3] + y[n + 4] if kinematic else v_sets[i]
        trace_row(P_out, y, commands[i], law_input, cart, sc, dy, trace[i + 1])
        if not clear(P, y):
            return y, i + 1, nfev, kinks
    return y, commands.shape[0], nfev, kinks


@entry
def path_offsets(px, py, qx, qy, growing):
    """(signed distance of each point q_i from the polyline p, > 0 left of its direction, m; whether
    its nearest point is an end of the polyline). With ``growing`` point i sees the vertices 0..i
    only (the ground the path had traced by then: analyze.distance_to_path with upto = i, whose
    exact k-d tree search the tests hold this to); else the whole polyline.

    The points are taken in order, each searched from the segment nearest the point before, walking
    on while the next segment is not farther: a point that moves along the path (a cart's axle or
    corner along the tractor's path) finds its nearest segment, and a path that comes back near
    itself is not taken for it. The end segments are extended to lines: beyond an end, a point's
    distance is from that line (``at_end`` says so; analyze's distance is then to the end vertex)."""
    m = px.shape[0]
    count = qx.shape[0]
    out = np.empty(count)
    at_end = np.zeros(count, dtype=np.bool_)
    j = 0
    for i in range(count):
        last = m - 1 if not growing else (i if i < m - 1 else m - 1)  # the last vertex point i sees
        if last < 1:
            out[i] = math.hypot(qx[i] - px[0], qy[i] - py[0])
            at_end[i] = True
            continue
        if j > last - 1:
            j = last - 1
        best, side, u = _segment_distance2(px, py, j, last, qx[i], qy[i])
        while j + 1 <= last - 1:
            d, s, v = _segment_distance2(px, py, j + 1, last, qx[i], qy[i])
            if d > best:
                break
            best, side, u, j = d, s, v, j + 1
        best = math.sqrt(best)
        out[i] = best if side >= 0.0 else -best
        at_end[i] = (j == 0 and u < 0.0) or (j == last - 1 and u > 1.0)
    return out, at_end


@jitable
def _segment_distance2(px, py, j, last, x, y):
    """(squared distance from (x, y) to segment j of the polyline whose last vertex is ``last``, the side:
    the cross product's sign, the position u along the segment); the first and the last segment
    extend to lines beyond their ends (u < 0, u > 1)."""
    ax, ay = px[j], py[j]
    dx, dy = px[j + 1] - ax, py[j + 1] - ay
    length2 = dx * dx + dy * dy
    u = ((x - ax) * dx + (y - ay) * dy) / length2 if length2 > 0.0 else 0.0
    if u > 1.0 and j + 1 < last:
        u = 1.0
    if u < 0.0 and j > 0:
        u = 0.0
    ox, oy = x - (ax + u * dx), y - (ay + u * dy)
    cross = dx * oy - dy * ox
    return ox * ox + oy * oy, cross, u


ENTRIES = (rhs_of, tick, outputs_of, pulls_of, margin_of, switches_of, release_of, trace_of, run, path_offsets)
