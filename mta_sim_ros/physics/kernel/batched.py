"""The right-hand side of a batch of schemes at once, one scheme per SIMD lane (issue 24,
docs/lanes.md): the chain walk of ``motion.rhs`` in the shape LLVM vectorises.

A batch holds schemes of one shape: the same number of carts, traction law, drafts per cart (the
same layout of P), terrain kind (level or a tilted plane; a height grid is not batched) and held
branches or none. Every array has the scheme index innermost (structure of arrays):

    P          (len(P), L)       each scheme's packed constants in a column (packing.pack)
    y, dy      (size, L)         the states and their rates
    commands, v_sets, max_rates (L,)  the held inputs
    rec        (n, REC, L)       each cart's record (base.py), or (0, REC, L) for none
    mode       (1 + width, L)    each scheme's held branches (``rhs``), or (0, L) for none
    work       (WORK_ROWS, L)    what one cart hands to the next, per lane

The carts' loop is outside; inside each of its steps, a loop over the lanes calls the walk's pieces
(walk.py), the same arithmetic as ``motion.rhs``: so each inner loop is straight-line code, which
LLVM turns into packed instructions (``lanes in``, docs/lanes.md). ``rhs_lanes_with`` binds the
math: ``rhs_lanes`` with vmath's (vectorised; within a few ulp of ``rhs``), ``rhs_lanes_libm`` with
the C library's (bit for bit ``rhs``: the tests' proof that both run one source). The steering
actuator and the traction law run once per lane, on numbers or on the lane's column of P."""
from __future__ import annotations

import numpy as np

from ...jit import jitable, lanes
from .base import (
    CART_SIZE,
    DRAFT_SIZE,
    FORCE_SWITCHES,
    GRADE,
    HEAD_SIZE,
    KAPB,
    KAPB_DOT,
    KAPC,
    KAPT,
    KAPT_DOT,
    GOVERNOR,
    KINEMATIC,
    MS_TO_KMH,
    NATURAL,
    PRESCRIBED,
    PSI,
    REC,
    RES,
    C,
    D,
    H,
)
from .laws import (
    accel_switch,
    draft_force,
    governor,
    governor_switches,
    held_abs,
    prescribed_accel,
    steering,
    switch_layout,
)
from .vmath import pick
from .walk import LIBM, VMATH, forward_acceleration, inertia, inverse_traction

#: rows of ``work``: the walk's running values (kap_k, its rate, psi_k, its rate, th'_{k-1}, beta'_{k-1},
#: the sums of M, M', Q and the grade resistances, psi_1'), then cart k's own, then F_A1 and the
#: traction law's held branches (laws.switch_layout's first four)
(K_VAL, K_DOT, P_VAL, P_DOT, TR_PREV, BD_PREV, MASS_SUM, RATE_SUM, RES_SUM, GRADE_SUM, PSI_RATE,
 S, CO, S_DOT, C_DOT, T_VAL, THETA_RATE, B_VAL, T_DOT, KC_VAL, B_DOT, GRADE_K, TOTAL, BRANCH, TRACTION_OUT, B_SAT, B_LIMIT, B_FLOOR, B_ACCEL) = range(29)
WORK_ROWS = B_ACCEL + 1


def rhs_lanes_with(walk):
    """``rhs_lanes`` with the math of ``walk`` (walk.bind) compiled into it."""
    kinematics, next_link, course = walk.kinematics, walk.next_link, walk.course
    walk_forces = forces_with(walk)

    @jitable
    def rhs_lanes(P, y, commands, v_sets, max_rates, dy, rec, mode, work):
        """y' of every lane into ``dy`` (``motion.rhs`` per lane; module docstring for the arrays)."""
        L = y.shape[1]
        n = int(P[H.n, 0])
        if P[H.relief, 0] != 0.0:
            raise ValueError("a train on a height grid is not batched (kernel.stack)")
        forces_on = int(P[H.law, 0]) != KINEMATIC
        sloped, held, recording = P[H.slope, 0] != 0.0, mode.shape[0] > 0, rec.shape[0] > 0
        i_speed = switch_layout(P[:, 0])[4]
        start_lanes(P, y, commands, max_rates, mode, work, n)
        for k in range(n):
            b = HEAD_SIZE + CART_SIZE * k
            for j in range(L):
                s, c, t_val, theta_rate, p_dot, s_dot, c_dot, b_val = kinematics(
                    work[K_VAL, j], work[P_VAL, j], work[P_DOT, j], work[TR_PREV, j], work[BD_PREV, j],
                    P[b + C.length, j], y[n + 3, j], k == 0)
                work[S, j], work[CO, j], work[T_VAL, j], work[THETA_RATE, j] = s, c, t_val, theta_rate
                work[P_DOT, j], work[S_DOT, j], work[C_DOT, j], work[B_VAL, j] = p_dot, s_dot, c_dot, b_val
                dy[2 + k, j] = theta_rate
            if forces_on:
                walk_forces(P, y, n, k, b, held, sloped, i_speed, rec, mode, work)
                if held and i_speed >= 0 and P[b + C.draft_count, 0] > 0:
                    i_speed += 1
            if recording:
                for j in range(L):
                    rec[k, KAPT, j], rec[k, KAPB, j], rec[k, PSI, j] = work[T_VAL, j], work[B_VAL, j], work[P_VAL, j]
            if k < n - 1:
                for j in range(L):
                    k_val, k_dot, p_val, beta_dot = next_link(
                        work[K_VAL, j], work[K_DOT, j], work[S, j], work[CO, j], work[S_DOT, j], work[C_DOT, j],
                        work[P_DOT, j], P[b + C.lam, j], P[b + C.lam2, j], y[2 + k, j], y[3 + k, j])
                    work[K_VAL, j], work[K_DOT, j], work[P_VAL, j], work[BD_PREV, j] = k_val, k_dot, p_val, beta_dot
                    work[TR_PREV, j] = work[THETA_RATE, j]
        for j in range(L):
            dy[0, j], dy[1, j] = course(y[n + 3, j], y[2, j], y[n + 2, j])
            dy[n + 2, j] = work[PSI_RATE, j]
        speed_lanes(P, y, v_sets, n, forces_on, sloped, mode, work, dy)

    return rhs_lanes


@jitable
def start_lanes(P, y, commands, max_rates, mode, work, n):
    """The walk's start in every lane: psi_1' of the steering actuator, kap_1 = 1, the sums at 0."""
    L = y.shape[1]
    for j in range(L):
        work[BRANCH, j] = NATURAL
    if mode.shape[0] > 0:
        for j in range(L):
            work[BRANCH, j] = mode[0, j]
    for j in range(L):
        psi_rate = steering(P[H.max_angle, j], P[H.time_constant, j], y[n + 2, j], commands[j], max_rates[j],
                            work[BRANCH, j])
        work[PSI_RATE, j], work[P_DOT, j], work[P_VAL, j] = psi_rate, psi_rate, y[n + 2, j]
        work[K_VAL, j], work[K_DOT, j], work[TR_PREV, j], work[BD_PREV, j] = 1.0, 0.0, 0.0, 0.0
        work[MASS_SUM, j], work[RATE_SUM, j], work[RES_SUM, j], work[GRADE_SUM, j] = 0.0, 0.0, 0.0, 0.0


def forces_with(walk):
    """``walk_forces`` with the math of ``walk`` compiled into it."""
    grade, resisted = walk.grade, walk.resisted

    @jitable
    def walk_forces(P, y, n, k, b, held, sloped, i_speed, rec, mode, work):
        """Cart k's share of M, M' and Q in every lane (``motion.rhs``'s forces), and its record."""
        L = y.shape[1]
        for j in range(L):
            t_dot, kc_val, mass_k, rate_k, b_dot = inertia(
                work[K_VAL, j], work[K_DOT, j], work[S, j], work[CO, j], work[S_DOT, j], work[C_DOT, j],
                work[T_VAL, j], P[b + C.length, j], P[b + C.mu2, j], P[b + C.mass, j], P[b + C.inertia, j])
            work[MASS_SUM, j] += mass_k
            work[RATE_SUM, j] += rate_k
            work[T_DOT, j], work[KC_VAL, j], work[B_DOT, j] = t_dot, kc_val, b_dot
            work[TOTAL, j] = P[b + C.rolling, j] * 1.0  # the normal's cosine: 1 on a plane
            work[GRADE_K, j] = 0.0
            work[BRANCH, j] = NATURAL
        if sloped:
            for j in range(L):
                work[GRADE_K, j] = grade(y[2 + k, j], work[B_VAL, j], work[T_VAL, j], P[b + C.com_offset, j],
                                         P[b + C.mass, j], P[H.gravity_x, j], P[H.gravity_y, j])
        first, count = int(P[b + C.draft_first, 0]), int(P[b + C.draft_count, 0])
        if held and i_speed >= 0 and count > 0:
            for j in range(L):
                work[BRANCH, j] = mode[1 + i_speed, j]
        base = HEAD_SIZE + CART_SIZE * n
        for i in range(first, first + count):
            d = base + DRAFT_SIZE * i
            for j in range(L):
                speed_kmh = held_abs(work[B_VAL, j] * y[n + 3, j], work[BRANCH, j]) * MS_TO_KMH
                work[TOTAL, j] += draft_force(P[d + D.soil_factor, j], P[d + D.A, j], P[d + D.B, j], P[d + D.C, j],
                                              P[d + D.width, j], P[d + D.depth, j], speed_kmh)
        for j in range(L):
            b_val = work[B_VAL, j]
            force = resisted(work[TOTAL, j], b_val * y[n + 3, j], P[H.smoothing_speed, j])
            work[RES_SUM, j] += force * b_val
            work[GRADE_SUM, j] += work[GRADE_K, j]
            work[TOTAL, j] = force
        if rec.shape[0]:
            for j in range(L):
                rec[k, KAPC, j], rec[k, RES, j], rec[k, GRADE, j] = work[KC_VAL, j], work[TOTAL, j], work[GRADE_K, j]
                rec[k, KAPT_DOT, j], rec[k, KAPB_DOT, j] = work[T_DOT, j], work[B_DOT, j]

    return walk_forces


@jitable
def speed_lanes(P, y, v_sets, n, forces_on, sloped, mode, work, dy):
    """V', z' and F_A1 of every lane from the traction law (``motion.speed_equation``, on numbers)."""
    L = y.shape[1]
    law = int(P[H.law, 0])
    layout = switch_layout(P[:, 0])
    for r in range(4):  # the held branches of the saturation, force/power limit, speed floor, acceleration limit
        for j in range(L):
            work[B_SAT + r, j] = NATURAL
        if mode.shape[0] > 0 and layout[r] >= 0:
            for j in range(L):
                work[B_SAT + r, j] = mode[1 + layout[r], j]
    for j in range(L):
        V, z, mass = y[n + 3, j], y[n + 4, j], work[MASS_SUM, j]
        generalized = pick(sloped, work[RES_SUM, j] + work[GRADE_SUM, j], work[RES_SUM, j])
        velocity_term = 0.5 * work[RATE_SUM, j] * V
        traction, acceleration, rate = 0.0, z, 0.0  # kinematic: z is the ramp slope
        if law == PRESCRIBED:
            acceleration = prescribed_accel(P[H.response_time, j], P[H.max_accel, j], V, v_sets[j], work[B_ACCEL, j])
            traction = inverse_traction(mass, acceleration, generalized, velocity_term)
        elif law == GOVERNOR:
            traction, rate = governor(P[H.kp, j], P[H.ki, j], P[H.windup_time, j], P[H.max_force, j],
                                      P[H.max_power, j], V, v_sets[j], z, work[B_SAT, j], work[B_LIMIT, j],
                                      work[B_FLOOR, j])
            acceleration = forward_acceleration(traction, generalized, velocity_term, mass)
        elif forces_on:
            traction = P[H.force, j]
            acceleration = forward_acceleration(traction, generalized, velocity_term, mass)
        dy[n + 3, j], dy[n + 4, j], work[TRACTION_OUT, j] = acceleration, rate, traction


def switches_lanes_with(walk):
    """``switches_lanes`` with the math of ``walk`` compiled into it."""
    sincos, chain_step = walk.sincos, walk.chain_step

    @jitable
    def switches_lanes(P, y, v_sets, g, work):
        """``motion.switches`` of every lane into the rows of g (width, L); returns how many rows."""
        L = y.shape[1]
        n = int(P[H.n, 0])
        i_sat, i_limit, i_floor, i_accel, i_speed = switch_layout(P[:, 0])
        if i_sat >= 0:
            for j in range(L):
                saturation, limit, floor = governor_switches(P[H.kp, j], P[H.max_force, j], P[H.max_power, j],
                                                             y[n + 3, j], v_sets[j], y[n + 4, j])
                g[i_sat, j] = saturation
                if i_limit >= 0:
                    g[i_limit, j] = limit
                if i_floor >= 0:
                    g[i_floor, j] = floor
        if i_accel >= 0:
            for j in range(L):
                g[i_accel, j] = accel_switch(P[H.response_time, j], P[H.max_accel, j], y[n + 3, j], v_sets[j])
        m = max(i_sat, i_limit, i_floor, i_accel) + 1
        if i_speed < 0:
            return m
        for j in range(L):
            work[K_VAL, j], work[P_VAL, j] = 1.0, y[n + 2, j]
        for k in range(n):
            b = HEAD_SIZE + CART_SIZE * k
            for j in range(L):
                work[S, j], work[CO, j] = sincos(work[P_VAL, j])
            if P[b + C.draft_count, 0] > 0:
                for j in range(L):
                    g[m, j] = work[K_VAL, j] * work[CO, j] * y[n + 3, j]  # s'_Bk
                m += 1
            if k < n - 1:
                for j in range(L):
                    _, _, k_val, p_val = chain_step(work[K_VAL, j], work[S, j], work[CO, j], P[b + C.lam, j],
                                                 P[b + C.lam2, j], y[2 + k, j], y[3 + k, j])
                    work[K_VAL, j], work[P_VAL, j] = k_val, p_val
        return m

    return switches_lanes


rhs_lanes = rhs_lanes_with(VMATH)
rhs_lanes_libm = rhs_lanes_with(LIBM)
switches_lanes = switches_lanes_with(VMATH)
switches_lanes_libm = switches_lanes_with(LIBM)



@jitable
def allocate(P, y, record):
    """(dy, rec, work) for a batch: ``rec`` (n, REC, L) when ``record``, else (0, REC, L)."""
    L = y.shape[1]
    return np.empty_like(y), np.empty((int(P[H.n, 0]) if record else 0, REC, L)), np.empty((WORK_ROWS, L))


@lanes
def rhs_lanes_of(P, y, commands, v_sets, max_rates, mode, record):
    """``rhs_lanes`` (vmath) of a batch: (dy, rec, F_A1, M) as new arrays."""
    dy, rec, work = allocate(P, y, record)
    rhs_lanes(P, y, commands, v_sets, max_rates, dy, rec, mode, work)
    return dy, rec, work[TRACTION_OUT].copy(), work[MASS_SUM].copy()


@lanes
def rhs_lanes_libm_of(P, y, commands, v_sets, max_rates, mode, record):
    """``rhs_lanes_libm`` (the C library's math: ``motion.rhs`` lane by lane, to the bit)."""
    dy, rec, work = allocate(P, y, record)
    rhs_lanes_libm(P, y, commands, v_sets, max_rates, dy, rec, mode, work)
    return dy, rec, work[TRACTION_OUT].copy(), work[MASS_SUM].copy()


@lanes
def switches_lanes_of(P, y, v_sets):
    """``switches_lanes`` (vmath) of a batch: (g rows x L, how many rows)."""
    g = np.empty((FORCE_SWITCHES + int(P[H.n, 0]) + 1, y.shape[1]))
    m = switches_lanes(P, y, v_sets, g, np.empty((WORK_ROWS, y.shape[1])))
    return g[:m].copy(), m


@lanes
def switches_lanes_libm_of(P, y, v_sets):
    """``switches_lanes_libm``: each lane's ``motion.switches``, to the bit."""
    g = np.empty((FORCE_SWITCHES + int(P[H.n, 0]) + 1, y.shape[1]))
    m = switches_lanes_libm(P, y, v_sets, g, np.empty((WORK_ROWS, y.shape[1])))
    return g[:m].copy(), m
