"""The train's equations, compiled: the right-hand side (the chain walk of MODEL.md [12]-[16] fused
with algorithm 2's sums and the force laws), the jackknife margin, every reported quantity of a state,
the drawbar pulls, and the switching functions of the force laws.

The readable reference the tests hold these to: ``physics/chain.py`` (the recursion),
``dynamics.Model.terms`` (algorithm 2 term by term) and ``holonomic.py`` (algorithm 1). Arithmetic
here is the reference's, in the same order (IEEE, no fast-math), so the kernel's y' equals the
reference's to the last bit."""
from __future__ import annotations

import math

from ...jit import jitable
from .base import (
    AX,
    AY,
    BX,
    BY,
    CART_SIZE,
    CX,
    CY,
    FRONT_LAT,
    GOVERNOR,
    GRADE,
    GRADE_POWER,
    HEAD_SIZE,
    KAPB,
    KAPB_DOT,
    KAPC,
    KAPT,
    KAPT_DOT,
    KINEMATIC,
    LAT,
    MARGIN,
    MASS,
    NATURAL,
    PHI,
    PRESCRIBED,
    PSI,
    PULL,
    REAR_X,
    REAR_Y,
    RES,
    RES_POWER,
    STEERING_RATE,
    TRACTION,
    VB,
    VC,
    VT,
    C,
    H,
    no_mode,
    pymin,
    wrap_angle,
)
from .laws import (
    accel_switch,
    governor_switches,
    grade_resistance,
    resistance,
    steering_rate,
    switch_layout,
    traction_law,
)
from .relief import off_relief, relief_grade, surface
from .walk import (
    LIBM,
    accelerations,
    forward_acceleration,
    hitch_margin,
    in_plane,
    inertia,
    inverse_traction,
    towed_pull,
)

#: the walk's pieces with the C library's math (walk.py): y' is the reference's to the bit
kinematics, chain_step, next_link, course = LIBM.kinematics, LIBM.chain_step, LIBM.next_link, LIBM.course
pose, tractor_forces = LIBM.pose, LIBM.tractor_forces


@jitable
def next_psi(P, b, y, k, s, c):
    """psi_{k+1} = th_k - th_{k+1} - beta_k, beta_k = atan2(lam_k sin psi_k, cos psi_k): the chain's
    step from cart k (constants at P[b:]) to the next (chain.py; s, c = sin psi_k, cos psi_k)."""
    return y[2 + k] - y[3 + k] - math.atan2(P[b + C.lam] * s, c)


@jitable
def rhs(P, y, command, v_set, max_rate, dy, rec, mode):
    """y' into ``dy`` under the held input (steering command, speed set-point, steering rate limit);
    returns (F_A1, M). When ``rec`` has rows (n x REC or wider), each cart's record (base.py: kapT,
    kapB, kapC, psi, F_Bk, rates, F_gk) goes into its first REC columns. ``mode`` (empty, or one
    branch per switch: ``branches``) holds each non-smooth law on one of its branches, as a step
    between two kinks needs (outside its own region a held branch is the smooth extension).

    The chain (chain.py): walking back from the tractor, V_k = kap_k V and psi_k give
    th'_k = kap_k sin(psi_k) V / l_k, s'_Bk = kap_k cos(psi_k) V, s'_Ck = kap_k rc_k V; each rate
    ``*_dot`` is the exact time derivative of the line above it. Algorithm 2 (dynamics.py):
    M = sum m kapC^2 + J kapT^2, R = 1/2 M' V, M V' = F_A1 - sum F_Bk kapB_k - sum F_gk - R, F_gk the
    grade resistances (``ground``: a tilted plane's, a height grid's at C_k; absent on the level)."""
    n = int(P[H.n])
    forces_on = int(P[H.law]) != KINEMATIC
    sloped, held, i_speed, relief = P[H.slope] != 0.0, mode.shape[0] > 0, switch_layout(P)[4], P[H.relief] != 0.0
    ax, ay = y[0], y[1]  # A_k (placed on a height grid only)
    psi1, V, z = y[n + 2], y[n + 3], y[n + 4]
    psi_rate = steering_rate(P, psi1, command, max_rate, mode[0] if held else NATURAL)

    mass, mass_rate, generalized_resistance, grade_sum = 0.0, 0.0, 0.0, 0.0
    k_val, k_dot = 1.0, 0.0  # kap_1 = 1
    p_val, p_dot = psi1, psi_rate
    theta_rate_prev, beta_dot_prev = 0.0, 0.0
    for k in range(n):
        b = HEAD_SIZE + CART_SIZE * k
        l_k = P[b + C.length]
        s, c, t_val, theta_rate, p_dot, s_dot, c_dot, b_val = kinematics(k_val, p_val, p_dot, theta_rate_prev,
                                                                         beta_dot_prev, l_k, V, k == 0)
        if forces_on:
            t_dot, kc_val, mass_k, mass_rate_k, b_dot = inertia(k_val, k_dot, s, c, s_dot, c_dot, t_val, l_k,
                                                                P[b + C.mu2], P[b + C.mass], P[b + C.inertia])
            mass += mass_k
            mass_rate += mass_rate_k
            branch = NATURAL
            if held and i_speed >= 0 and P[b + C.draft_count] > 0:
                branch = mode[1 + i_speed]
                i_speed += 1
            grade, normal, ax, ay = ground(P, k, y[2 + k], b_val, t_val, ax, ay, relief, sloped)
            force = resistance(P, k, b_val * V, branch, normal)
            generalized_resistance += force * b_val
            grade_sum += grade
            if rec.shape[0]:
                rec[k, KAPC], rec[k, RES], rec[k, GRADE] = kc_val, force, grade
                rec[k, KAPT_DOT], rec[k, KAPB_DOT] = t_dot, b_dot
        if rec.shape[0]:
            rec[k, KAPT], rec[k, KAPB], rec[k, PSI] = t_val, b_val, p_val
        dy[2 + k] = theta_rate
        if k < n - 1:  # on to cart k + 1: V_{k+1} = V_k rl_k, psi_{k+1}
            k_val, k_dot, p_val, beta_dot_prev = next_link(k_val, k_dot, s, c, s_dot, c_dot, p_dot, P[b + C.lam],
                                                           P[b + C.lam2], y[2 + k], y[3 + k])
            theta_rate_prev = theta_rate

    traction, acceleration, governor_rate = 0.0, z, 0.0  # kinematic: z is the ramp slope (kinematic.py)
    if forces_on:
        if sloped or relief:  # the grade resistances enter Q as the resistances do
            generalized_resistance = generalized_resistance + grade_sum
        traction, acceleration, governor_rate = speed_equation(P, V, v_set, z, mode, mass, 0.5 * mass_rate * V,
                                                               generalized_resistance)
    dy[0], dy[1] = course(V, y[2], psi1)  # v_A1 along th_1 + psi_1
    dy[n + 2] = psi_rate
    dy[n + 3] = acceleration
    dy[n + 4] = governor_rate
    return traction, mass


@jitable
def ground(P, k, heading, kapB, kapT, ax, ay, relief, sloped):
    """(F_gk, cos of the local slope, A_{k+1}) of cart k from A_k = (ax, ay): on a height grid
    ``relief_grade`` at C_k, on a tilted plane ``grade_resistance`` (cosine 1: the plane's is packed
    in the rolling resistance), on the level (0, 1); A_{k+1} is placed on a height grid only."""
    if relief:
        b = HEAD_SIZE + CART_SIZE * k
        ex, ey = math.cos(heading), math.sin(heading)
        bx, by = ax - P[b + C.length] * ex, ay - P[b + C.length] * ey
        grade, normal = relief_grade(P, k, heading, kapB, kapT, bx + P[b + C.com_offset] * ex,
                                     by + P[b + C.com_offset] * ey)
        return grade, normal, bx - P[b + C.hitch_offset] * ex, by - P[b + C.hitch_offset] * ey
    if sloped:
        return grade_resistance(P, k, heading, kapB, kapT), 1.0, ax, ay
    return 0.0, 1.0, ax, ay


@jitable
def speed_equation(P, V, v_set, z, mode, mass, velocity_term, generalized_resistance):
    """(F_A1, V', z') from the traction law: M V' = F_A1 - (sum F_Bk kapB_k + sum F_gk) - R, or for a
    prescribed speed the force by inverse dynamics."""
    traction, acceleration, governor_rate, prescribed = traction_law(P, V, v_set, z, mode)
    if prescribed:
        traction = inverse_traction(mass, acceleration, generalized_resistance, velocity_term)
    else:
        acceleration = forward_acceleration(traction, generalized_resistance, velocity_term, mass)
    return traction, acceleration, governor_rate


@jitable
def margin(P, y):
    """(smallest jackknife margin over the hitches, rad; index of that cart, -1 for none): per
    cart k >= 2, min(max_hitch_k - |phi_k|, pi/2 - |psi_k|) with psi_k from the chain (guards.py)."""
    n = int(P[H.n])
    best, where = math.inf, -1
    p_val = y[n + 2]
    for k in range(n - 1):
        b = HEAD_SIZE + CART_SIZE * k
        p_val = next_psi(P, b, y, k, math.sin(p_val), math.cos(p_val))  # psi_{k+1}
        phi = wrap_angle(y[2 + k] - y[3 + k])
        m = hitch_margin(P[b + CART_SIZE + C.max_hitch], phi, p_val)
        if m < best:
            best, where = m, k + 1
    return best, where


#: closer than this to a jackknife limit (rad), the Python guard (guards.check_state) decides
GUARD_SLACK = 1e-9


@jitable
def clear(P, y):
    """True when y is finite, every hitch is more than GUARD_SLACK inside its limits and, on a
    height grid, every cart's centre of mass is on it."""
    for i in range(y.shape[0]):
        if not math.isfinite(y[i]):
            return False
    return margin(P, y)[0] > GUARD_SLACK and off_relief(P, y) < 0


@jitable
def outputs(P, y, command, v_set, max_rate, cart, sc, dy):
    """Every reported quantity of state y into ``cart`` (n x OUT) and ``sc`` (SCALARS): the points
    of geometry.cart_points, the chain's factors times V, the forces, the jackknife margin, and
    the actuator's rate psi_1' under the held input."""
    n = int(P[H.n])
    traction, mass = rhs(P, y, command, v_set, max_rate, dy, cart, no_mode())
    V = y[n + 3]
    ax, ay = y[0], y[1]
    res_power, grade_power = 0.0, 0.0
    best = math.inf
    for k in range(n):
        b = HEAD_SIZE + CART_SIZE * k
        th = y[2 + k]
        cart[k, AX], cart[k, AY] = ax, ay
        _, _, cart[k, BX], cart[k, BY], cart[k, CX], cart[k, CY], ax, ay = pose(
            th, ax, ay, P[b + C.length], P[b + C.com_offset], P[b + C.hitch_offset])
        cart[k, VC], cart[k, VB], cart[k, VT] = cart[k, KAPC] * V, cart[k, KAPB] * V, cart[k, KAPT] * V
        cart[k, PULL] = cart[k, LAT] = math.nan  # not computed here (drawbar_pulls)
        res_power += cart[k, RES] * cart[k, VB]
        grade_power += cart[k, GRADE] * V
        if k:
            phi = wrap_angle(y[1 + k] - th)
            cart[k, PHI] = phi
            best = pymin(best, hitch_margin(P[b + C.max_hitch], phi, cart[k, PSI]))
        else:
            cart[k, PHI] = 0.0
    sc[REAR_X], sc[REAR_Y] = ax, ay
    sc[TRACTION], sc[MASS], sc[RES_POWER], sc[MARGIN] = traction, mass, res_power, best
    sc[STEERING_RATE], sc[GRADE_POWER], sc[FRONT_LAT] = dy[n + 2], grade_power, math.nan
    return traction


@jitable
def drawbar_pulls(P, y, acceleration, cart, sc):
    """The pull at each hitch A_k (k >= 2) along the towed cart's axis e_k, N, into cart[k, PULL],
    and the lateral force N_k n_k of each axle at B_k into cart[k, LAT] (the tractor's front axle's,
    across its wheels, into sc[FRONT_LAT]): the constraint forces of the model, by Newton-Euler on
    each towed cart from the last forward, then on the tractor. Cart k (unit axis e_k, normal n_k,
    th_k) carries the hitch force H_k at A_k, -H_{k+1} at A_{k+1}, the resistance -F_Bk e_k, the
    tyres' lateral force N_k n_k at B_k and, on a tilted plane, gravity's component m_k g_p in the
    plane at C_k (taken into a_e, a_n below). With the centre of mass C_k = B_k + c_k e_k, its
    acceleration a_e = d(s'_Bk)/dt - c_k th'_k^2, a_n = s'_Bk th'_k + c_k th''_k, where
    d(s'_Bk)/dt = kapB' V + kapB V' and th''_k = kapT' V + kapT V' (the chain's rates, ``rhs``):

        H_k . e_k = H_{k+1} . e_k + F_Bk + m_k a_e                          (Newton along e_k)
        H_k . n_k = (J_k th''_k + c_k m_k a_n - a_k H_{k+1} . n_k) / l_k   (Euler about C_k, N_k eliminated)
        N_k = m_k a_n - H_k . n_k + H_{k+1} . n_k                          (Newton along n_k)

    The tractor (traction F along its course th_1 + psi_1 at A_1, the front axle's F_f across it)
    has S = F sin(psi_1) + F_f cos(psi_1), the front forces across e_1, and N_1 from Newton along
    n_1 and Euler about C_1:

        S + N_1 = m_1 a_n + H_2 . n_1 =: R1,   (l_1 - c_1) S - c_1 N_1 = J_1 th''_1 - (a_1 + c_1) H_2 . n_1 =: R2
        S = (c_1 R1 + R2) / l_1

    ``cart`` holds the REC and VB, VT columns of ``outputs`` (``acceleration`` its dy[n + 3], ``sc`` its
    TRACTION); cart[0, PULL] is H_2 . e_1, the drawbar's load along the tractor's own axis (its tip
    margin, terrain.tip_margin; the traction at A_1 is ``outputs``' own). On a straight line at
    constant speed the pull at A_k is the sum of the resistances behind it (test_sweep_metrics)."""
    n = int(P[H.n])
    V = y[n + 3]
    sloped, relief = P[H.slope] != 0.0, P[H.relief] != 0.0
    hx, hy = 0.0, 0.0  # H_{k+1}, world frame
    for k in range(n - 1, -1, -1):
        b = HEAD_SIZE + CART_SIZE * k
        th = y[2 + k]
        ex, ey = math.cos(th), math.sin(th)
        com = P[b + C.com_offset]
        rate_dot, a_e, a_n = accelerations(cart[k, KAPT_DOT], cart[k, KAPT], cart[k, KAPB_DOT], cart[k, KAPB], V,
                                           acceleration, com, cart[k, VB], cart[k, VT])
        if sloped:  # gravity in the plane at C_k: as if the cart accelerated by -g_p
            a_e, a_n = in_plane(a_e, a_n, ex, ey, P[H.gravity_x], P[H.gravity_y])
        elif relief:  # on a height grid the horizontal force of gravity's potential at C_k: -m g grad z
            _, zx, zy = surface(P, int(P[H.relief]), cart[k, CX], cart[k, CY])
            a_e += P[H.gravity] * (zx * ex + zy * ey)
            a_n += P[H.gravity] * (zx * -ey + zy * ex)
        if k == 0:
            cart[0, LAT], sc[FRONT_LAT], cart[0, PULL] = tractor_forces(
                hx, hy, ex, ey, P[b + C.mass], a_n, P[b + C.inertia], rate_dot, P[b + C.hitch_offset], com,
                P[b + C.length], sc[TRACTION], y[n + 2])
            break
        cart[k, PULL], cart[k, LAT], hx, hy = towed_pull(hx, hy, ex, ey, cart[k, RES], P[b + C.mass], a_e, a_n,
                                                         P[b + C.inertia], rate_dot, com, P[b + C.hitch_offset],
                                                         P[b + C.length])


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
    if i_sat >= 0:  # the governor's (laws.governor_switches: its three, each where the layout has it)
        saturation, limit, floor = governor_switches(P[H.kp], P[H.max_force], P[H.max_power], V, v_set, z)
        g[i_sat] = saturation
        if i_limit >= 0:
            g[i_limit] = limit
        if i_floor >= 0:
            g[i_floor] = floor
    if i_accel >= 0:
        g[i_accel] = accel_switch(P[H.response_time], P[H.max_accel], V, v_set)
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
                _, _, k_val, p_val = chain_step(k_val, s, c, P[b + C.lam], P[b + C.lam2], y[2 + k], y[3 + k])
    return m


@jitable
def model_rhs(P, t, y, command, v_set, max_rate, dy, rec, mode):
    """The stepping routine's form of ``rhs`` (t does not enter: the input is held)."""
    rhs(P, y, command, v_set, max_rate, dy, rec, mode)
