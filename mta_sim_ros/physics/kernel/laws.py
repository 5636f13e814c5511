"""The laws of the force and steering elements, compiled: the steering actuator (its rate, its
release from the rate limit and its closed-form motion), the resistances at B_k (rolling and the
ASABE draft), the traction limits, and which branch of each non-smooth law a state is on (the
switching functions' layout; ``motion.switches`` evaluates them).

Each law may be held on one branch (``mode``: NATURAL, LOW, HIGH, base.py): a step between two kinks
integrates a smooth right-hand side, outside its own region the held branch's smooth extension."""
from __future__ import annotations

import math

from ...jit import inlined, jitable
from .base import (
    CART_SIZE,
    C,
    DRAFT_SIZE,
    GOVERNOR,
    HEAD_SIZE,
    HIGH,
    KINEMATIC,
    LOW,
    MS_TO_KMH,
    NATURAL,
    PRESCRIBED,
    D,
    H,
    pymax,
    pymin,
)
from .vmath import pick
from .walk import LIBM

#: the walk's pieces with the C library's math (walk.py): the scalar kernel is the reference's to the bit
libm_grade, libm_resisted, libm_actuator = LIBM.grade, LIBM.resisted, LIBM.actuator


@jitable
def steering_rate(P, psi1, command, max_rate, branch):
    """The steering actuator (MODEL.md, Dynamics): psi_1' = clip((clip(command, +-max_angle) - psi_1)
    / tau, +-max_rate), a first-order lag with a rate limit, as a hydraulic steering cylinder moves.
    ``max_rate`` is an input held with the command (the train's own ``P[H.max_rate]``, or the rate an
    ackermann_cmd asks for); with ``branch`` HIGH the rate limit's side (+-max_rate), LOW the linear
    side, NATURAL as the state is (``steering``)."""
    return steering(P[H.max_angle], P[H.time_constant], psi1, command, max_rate, branch)


@inlined
def steering(max_angle, time_constant, psi1, command, max_rate, branch):
    """``steering_rate`` on numbers, every branch computed and one picked (a loop over lanes, each
    on its own branch, vectorises)."""
    target = pymin(pymax(command, -max_angle), max_angle)
    linear = (target - psi1) / pick(branch == HIGH, 1.0, time_constant)  # held on the rate limit: not divided
    limited = pick(target > psi1, max_rate, -max_rate)
    return pick(branch == NATURAL, pymin(pymax(linear, -max_rate), max_rate), pick(branch == HIGH, limited, linear))


@inlined
def held_abs(x, branch):
    """|x|, or with a held branch the side of it (+x for HIGH, -x for LOW)."""
    return pick(branch == NATURAL, abs(x), pick(branch == HIGH, x, -x))


@inlined
def draft_force(soil_factor, A, B, C, width, depth, speed_kmh):
    """One ASABE D497 draft, N: F_i (A + B S + C S^2) W T at S = ``speed_kmh``."""
    return soil_factor * (A + B * speed_kmh + C * speed_kmh * speed_kmh) * width * depth


@jitable
def resistance(P, k, axle_speed, branch, normal=1.0):
    """The resistance F_Bk at cart k's axle B_k, N, signed against its speed s'_Bk = ``axle_speed``
    (MODEL.md, force laws): (f m g + sum of the drafts D = F_i (A + B S + C S^2) W T) tanh(s'_Bk / v0),
    S = |s'_Bk| in km/h (ASABE D497), v0 the smoothing speed. ``branch``: the sign of the speed held
    in the draft's |S| (see held_abs); the tanh is smooth and follows the state. ``normal``: the
    cosine of the local slope on a height grid (relief.relief_grade), which scales f m g."""
    b = HEAD_SIZE + CART_SIZE * k
    first, count = int(P[b + C.draft_first]), int(P[b + C.draft_count])
    total = P[b + C.rolling] * normal
    base = HEAD_SIZE + CART_SIZE * int(P[H.n])
    for i in range(first, first + count):
        d = base + DRAFT_SIZE * i
        total += draft_force(P[d + D.soil_factor], P[d + D.A], P[d + D.B], P[d + D.C], P[d + D.width], P[d + D.depth],
                             held_abs(axle_speed, branch) * MS_TO_KMH)
    return libm_resisted(total, axle_speed, P[H.smoothing_speed])


@jitable
def grade_resistance(P, k, heading, kapB, kapT):
    """Cart k's grade resistance referred to V, N: -m_k g_p . v_Ck / V, g_p gravity's component in
    the plane (P's gravity_x, gravity_y), v_Ck / V = kapB_k e_k + c_k kapT_k n_k (its centre of mass
    C_k = B_k + c_k e_k, B_k rolling along e_k). > 0 while the cart climbs; times V it is the
    power that lifts the cart, m_k g dz_Ck/dt. It enters Q as the resistances do."""
    b = HEAD_SIZE + CART_SIZE * k
    return libm_grade(heading, kapB, kapT, P[b + C.com_offset], P[b + C.mass], P[H.gravity_x], P[H.gravity_y])


@jitable
def held_branch(mode, i):
    """The branch switching function i (``switch_layout``) is held on: NATURAL when no branch is
    held (``mode`` empty) or the law has no such switch (i < 0)."""
    return mode[1 + i] if mode.shape[0] > 0 and i >= 0 else NATURAL


@jitable
def traction_law(P, V, v_set, z, mode):
    """The traction law of P (MODEL.md, force laws) at speed V, set-point v_set and governor
    integral z: (F_A1, V', z', whether the law prescribes V'). Every level dispatches here: where
    the law gives the force, V' is left to the level's equation of motion (returned 0); where it
    prescribes V', F_A1 is left to the level's inverse dynamics (returned 0).

        constant          F_A1 = force
        governor          u = kp (v_set - V) + z, F_A1 = u clipped to +-traction_limit(V),
                          z' = ki (v_set - V) + (F_A1 - u) / windup_time (back-calculation anti-windup)
        prescribed_speed  V' = (v_set - V) / response_time clipped to +-max_accel; F_A1 then follows
                          from the equation of motion (inverse dynamics: the level's own)

    ``mode`` holds the non-smooth pieces on one branch each (``rhs``); empty: as the state is."""
    law = int(P[H.law])
    i_sat, i_limit, i_floor, i_accel, _ = switch_layout(P)
    if law == PRESCRIBED:
        return 0.0, prescribed_accel(P[H.response_time], P[H.max_accel], V, v_set, held_branch(mode, i_accel)), \
            0.0, True
    if law == GOVERNOR:
        traction, rate = governor(P[H.kp], P[H.ki], P[H.windup_time], P[H.max_force], P[H.max_power], V, v_set, z,
                                  held_branch(mode, i_sat), held_branch(mode, i_limit), held_branch(mode, i_floor))
        return traction, 0.0, rate, False
    return P[H.force], 0.0, 0.0, False


@inlined
def prescribed_accel(response_time, max_accel, V, v_set, accel_branch):
    """The prescribed speed's V' = (v_set - V) / response_time clipped to +-max_accel."""
    return clip_held((v_set - V) / response_time, max_accel, accel_branch)


@inlined
def governor(kp, ki, windup_time, max_force, max_power, V, v_set, z, sat_branch, limit_branch, floor_branch):
    """The governor's (F_A1, z') on numbers (``traction_law``)."""
    error = v_set - V
    u = kp * error + z
    traction = clip_held(u, limit_of(max_force, max_power, V, limit_branch, floor_branch), sat_branch)
    return traction, ki * error + (traction - u) / windup_time


@inlined
def governor_switches(kp, max_force, max_power, V, v_set, z):
    """The governor's switching functions (``motion.switches``): |u| - limit(V), max_force max(|V|, 0.1)
    - max_power, |V| - 0.1."""
    return abs(kp * (v_set - V) + z) - limit_of(max_force, max_power, V, NATURAL, NATURAL), \
        max_force * pymax(abs(V), 0.1) - max_power, abs(V) - 0.1


@inlined
def accel_switch(response_time, max_accel, V, v_set):
    """The prescribed speed's switching function: |v_set - V| / response_time - max_accel."""
    return abs(v_set - V) / response_time - max_accel


@inlined
def clip_held(x, limit, branch):
    """x clipped to +-limit (Python's min(max(x, -limit), limit)); with a held branch, x itself (LOW)
    or the limit on x's side (HIGH)."""
    return pick(branch == NATURAL, pymin(pymax(x, -limit), limit), pick(branch == LOW, x, pick(x > 0.0, limit, -limit)))


@jitable
def traction_limit(P, V, limit_branch, floor_branch):
    """Largest |F_A1| at speed V: adhesion, and engine power over speed,
    min(max_force, max_power / max(|V|, 0.1)); held branches: the power limit (HIGH) or the force
    limit (LOW) of the min, |V| (HIGH) or 0.1 (LOW) of the max (``limit_of``)."""
    return limit_of(P[H.max_force], P[H.max_power], V, limit_branch, floor_branch)


@inlined
def limit_of(max_force, max_power, V, limit_branch, floor_branch):
    """``traction_limit`` on numbers: max_force alone where max_power is infinite."""
    speed = pick(floor_branch == NATURAL, pymax(abs(V), 0.1), pick(floor_branch == HIGH, abs(V), 0.1))
    # divided only where the power limit can be the answer (not held on the force limit, max_power finite)
    per_power = max_power / pick((limit_branch == LOW) | math.isinf(max_power), 1.0, speed)
    limit = pick(limit_branch == NATURAL, pymin(max_force, per_power), pick(limit_branch == HIGH, per_power, max_force))
    return pick(math.isinf(max_power), max_force, limit)


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
def branches(g, m, mode):
    """mode[1 + j] = the branch switching function j is on (HIGH where g_j > 0, else LOW)."""
    for j in range(m):
        mode[1 + j] = HIGH if g[j] > 0.0 else LOW


@jitable
def actuator_release(P, psi1, command, max_rate):
    """Time (s) until the steering actuator leaves its rate limit, with the command held: inf when
    it is not rate-limited. While limited, psi_1 moves at +-max_rate exactly (a straight line), and
    the limit lets go where |target - psi_1| = tau max_rate."""
    max_angle, tau = P[H.max_angle], P[H.time_constant]
    target = pymin(pymax(command, -max_angle), max_angle)
    gap = abs(target - psi1)
    if not gap / tau > max_rate:
        return math.inf
    return (gap - tau * max_rate) / max_rate


@jitable
def actuator_psi(P, psi0, command, max_rate, release, T):
    """psi_1 at T s into a tick that started at psi0, the command held: the actuator's closed-form
    motion (rate-limited at +-max_rate until ``release``, ``actuator_release``; then the first-order
    lag, exp(-t / tau) towards the clipped command): walk.py's ``actuator``."""
    return libm_actuator(P[H.max_angle], P[H.time_constant], psi0, command, max_rate, release, T)


@jitable
def no_switches(P, y, command, v_set, g):
    """``switches`` for a right-hand side without known switches."""
    return 0
