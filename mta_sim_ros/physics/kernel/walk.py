"""The arithmetic of the chain walk, one cart at a time, on numbers: the physics ``motion.rhs`` (one
scheme) and ``batched.rhs_lanes`` (a batch of schemes, one per SIMD lane) both run, written once.

Each piece takes numbers and returns numbers: no array goes in (numba counts an array's references
when it is handed to an inlined function, and those calls keep LLVM from vectorising a loop over
lanes). The callers read the packed constants and the state, call the pieces in the same order,
and store what they return: ``rhs`` into locals, ``rhs_lanes`` into a row per quantity and a
column per lane.

The transcendental functions (sin, cos, atan2, tanh, exp) are bound when the pieces are made (``bind``): the C library's for
one scheme, so that ``rhs`` stays bit for bit the readable reference's (physics/chain.py,
dynamics.py), vmath's for a batch, whose loops then vectorise (docs/lanes.md). The arithmetic of
every piece is the reference's, in the same order (IEEE, no fast-math).

    kinematics(sincos, ...)   sin, cos of psi_k; kapT_k, th'_k, psi_k', the rates of sin and cos, kapB_k
    grade(sincos, ...)        the cart's grade resistance on a tilted plane (laws.grade_resistance)
    resisted(tanh, ...)       the resistance at B_k: its magnitude times tanh(s'_Bk / v0)
    chain_step(atan2, ...)    V_{k+1} / V_k and psi_{k+1}: on to the next cart (``motion.switches``)
    next_link(atan2, ...)     the same with their rates (``motion.rhs``)
    course(sincos, ...)       x_A1', y_A1'
    actuator(exp, ...)        psi_1 of the steering actuator in closed form (laws.actuator_psi)
    inertia(...)              kapT_k', kapC_k, the cart's share of M and M' and kapB_k' (no
                              transcendental function: one piece for both)
    forward_acceleration, inverse_traction   the speed equation M V' = F_A1 - Q - R, either way
"""
from __future__ import annotations

import math
from collections import namedtuple

from ...jit import inlined, jitable
from . import vmath
from .base import pymax, pymin
from .vmath import pick

#: the pieces, their math bound (``bind``)
Walk = namedtuple("Walk", "sincos kinematics grade resisted chain_step next_link course actuator pose tractor_forces")


def bind(sincos, atan2, tanh, exp) -> Walk:
    """The pieces with (sin x, cos x), atan2, tanh and exp bound into them (module docstring)."""

    @inlined
    def kinematics(k_val, p_val, p_dot, theta_rate_prev, beta_dot_prev, length, V, first):
        """(s, c, kapT_k, th'_k, psi_k', s', c', kapB_k) of cart k from kap_k = ``k_val`` and psi_k
        = ``p_val``: th'_k = kap_k sin(psi_k) V / l_k; psi_k' is the actuator's rate ``p_dot`` at the
        tractor (``first``), th'_{k-1} - th'_k - beta'_{k-1} behind it."""
        s, c = sincos(p_val)
        t_val = k_val * s / length
        theta_rate = t_val * V
        p_dot = pick(first, p_dot, theta_rate_prev - theta_rate - beta_dot_prev)
        return s, c, t_val, theta_rate, p_dot, c * p_dot, -s * p_dot, k_val * c

    @inlined
    def grade(heading, kapB, kapT, com_offset, mass, gravity_x, gravity_y):
        """laws.grade_resistance on numbers: -m_k g_p . v_Ck / V."""
        ey, ex = sincos(heading)
        com_rate = com_offset * kapT
        vx, vy = kapB * ex - com_rate * ey, kapB * ey + com_rate * ex
        return -mass * (gravity_x * vx + gravity_y * vy)

    @inlined
    def resisted(total, axle_speed, smoothing_speed):
        """F_Bk = (f m g + the drafts) tanh(s'_Bk / v0) (laws.resistance)."""
        return total * tanh(axle_speed / smoothing_speed)

    @inlined
    def chain_step(k_val, s, c, lam, lam2, heading, heading_next):
        """((V_{k+1} / V_k)^2, V_{k+1} / V_k, kap_{k+1}, psi_{k+1}): V_{k+1} / V_k = sqrt(cos^2 psi_k
        + lam_k^2 sin^2 psi_k), psi_{k+1} = th_k - th_{k+1} - atan2(lam_k sin psi_k, cos psi_k)."""
        rl2 = c * c + lam2 * s * s
        rl = math.sqrt(rl2)
        return rl2, rl, k_val * rl, heading - heading_next - atan2(lam * s, c)

    @inlined
    def next_link(k_val, k_dot, s, c, s_dot, c_dot, p_dot, lam, lam2, heading, heading_next):
        """(kap_{k+1}, kap_{k+1}', psi_{k+1}, beta_k'): ``chain_step`` and the rates of its factors."""
        rl2, rl, k_next, p_next = chain_step(k_val, s, c, lam, lam2, heading, heading_next)
        rl_dot = (c * c_dot + lam2 * s * s_dot) / rl
        return k_next, k_dot * rl + k_val * rl_dot, p_next, lam * p_dot / rl2

    @inlined
    def course(V, heading, psi1):
        """(x_A1', y_A1'): v_A1 along th_1 + psi_1."""
        s, c = sincos(heading + psi1)
        return V * c, V * s

    @inlined
    def actuator(max_angle, time_constant, psi0, command, max_rate, release, T):
        """laws.actuator_psi on numbers: psi_1 at T s into a tick that started at psi0 (rate-limited at
        +-max_rate until ``release``, then the first-order lag; inf: the lag from the start). One exp,
        its argument picked, never above 0."""
        target = pymin(pymax(command, -max_angle), max_angle)
        free, limited = math.isinf(release), T <= release
        sign = pick(target > psi0, 1.0, -1.0)
        tau = pick(limited & (not free), 1.0, time_constant)  # on the rate limit: not divided
        e = exp(pick(free, -T / tau, pick(limited, 0.0, -(T - release) / tau)))
        return pick(free, target + (psi0 - target) * e,
                    pick(limited, psi0 + sign * max_rate * T, target - sign * time_constant * max_rate * e))

    return Walk(sincos, kinematics, grade, resisted, chain_step, next_link, course, actuator, *frame_pieces(sincos))


def frame_pieces(sincos):
    """``pose`` and ``tractor_forces`` with (sin x, cos x) bound into them (``bind``)."""

    @inlined
    def pose(heading, ax, ay, length, com_offset, hitch_offset):
        """(e_k = (cos th_k, sin th_k), B_k, C_k, A_{k+1}) of cart k from its hitch A_k (``outputs``)."""
        ey, ex = sincos(heading)
        bx, by = ax - length * ex, ay - length * ey
        return (ex, ey, bx, by, bx + com_offset * ex, by + com_offset * ey, bx - hitch_offset * ex,
                by - hitch_offset * ey)

    @inlined
    def tractor_forces(hx, hy, ex, ey, mass, a_n, inertia_k, rate_dot, hitch_offset, com, length, traction, psi):
        """(N_1, the front axle's lateral force F_f, H_2 . e_1) of the tractor (``drawbar_pulls``): S + N_1
        = R1, (l_1 - c_1) S - c_1 N_1 = R2, S = (c_1 R1 + R2) / l_1 = F sin(psi_1) + F_f cos(psi_1)."""
        behind_n = hx * -ey + hy * ex  # H_2 . n_1
        r1 = mass * a_n + behind_n
        r2 = inertia_k * rate_dot - (hitch_offset + com) * behind_n
        across = (com * r1 + r2) / length
        s, c = sincos(psi)
        return r1 - across, (across - traction * s) / c, hx * ex + hy * ey

    return pose, tractor_forces


@inlined
def inertia(k_val, k_dot, s, c, s_dot, c_dot, t_val, length, mu2, mass, inertia_k):
    """(kapT_k', kapC_k, m kapC^2 + J kapT^2, 2 (m kapC kapC' + J kapT kapT'), kapB_k') of cart k:
    s'_Ck / V_k = sqrt(cos^2 psi_k + mu_k^2 sin^2 psi_k) and the rates of the chain's factors.
    (``(mu2 * s) * s`` rounds as chain.py's ``mu * mu * s * s``.)"""
    t_dot = (k_dot * s + k_val * s_dot) / length
    rc = math.sqrt(c * c + mu2 * s * s)
    rc_dot = (c * c_dot + mu2 * s * s_dot) / rc
    kc_val = k_val * rc
    kc_dot = k_dot * rc + k_val * rc_dot
    return t_dot, kc_val, mass * kc_val * kc_val + inertia_k * t_val * t_val, \
        2.0 * (mass * kc_val * kc_dot + inertia_k * t_val * t_dot), k_dot * c + k_val * c_dot


@inlined
def forward_acceleration(traction, generalized_resistance, velocity_term, mass):
    """V' = (F_A1 - Q - R) / M: where the traction law gives the force."""
    return (traction - generalized_resistance - velocity_term) / mass


@inlined
def inverse_traction(mass, acceleration, generalized_resistance, velocity_term):
    """F_A1 = M V' + Q + R: where the law prescribes V' (inverse dynamics)."""
    return mass * acceleration + generalized_resistance + velocity_term


@inlined
def accelerations(kapT_dot, kapT, kapB_dot, kapB, V, acceleration, com, vb, vt):
    """(th''_k, a_e, a_n): the yaw acceleration of cart k and its centre of mass's acceleration along
    and across e_k (``drawbar_pulls``): d(s'_Bk)/dt - c_k th'_k^2 and s'_Bk th'_k + c_k th''_k, from the
    chain's factors and rates (kapT', kapT, kapB', kapB), V, V', s'_Bk = vb and th'_k = vt."""
    rate_dot = kapT_dot * V + kapT * acceleration
    speed_dot = kapB_dot * V + kapB * acceleration
    return rate_dot, speed_dot - com * vt * vt, vb * vt + com * rate_dot


@inlined
def in_plane(a_e, a_n, ex, ey, gravity_x, gravity_y):
    """(a_e, a_n) on a tilted plane: gravity's component in the plane at C_k, as if the cart
    accelerated by -g_p."""
    return a_e - (gravity_x * ex + gravity_y * ey), a_n - (gravity_x * -ey + gravity_y * ex)


@inlined
def towed_pull(hx, hy, ex, ey, resistance, mass, a_e, a_n, inertia_k, rate_dot, com, hitch_offset, length):
    """(H_k . e_k, N_k, H_k) of towed cart k from the force H_{k+1} = (hx, hy) of the cart behind
    (``drawbar_pulls``: Newton along e_k, Euler about C_k, Newton along n_k)."""
    nx, ny = -ey, ex
    behind_n = hx * nx + hy * ny  # H_{k+1} . n_k
    h_e = hx * ex + hy * ey + resistance + mass * a_e
    h_n = (inertia_k * rate_dot + com * mass * a_n - hitch_offset * behind_n) / length
    return h_e, mass * a_n - h_n + behind_n, h_e * ex + h_n * nx, h_e * ey + h_n * ny


@inlined
def hitch_margin(max_hitch, phi, psi):
    """min(max_hitch - |phi_k|, pi/2 - |psi_k|): how far hitch k is from its jackknife limits."""
    return pymin(max_hitch - abs(phi), 0.5 * math.pi - abs(psi))


@jitable
def libm_sincos(x):
    """(sin x, cos x) from the C library."""
    return math.sin(x), math.cos(x)


LIBM = bind(libm_sincos, math.atan2, math.tanh, math.exp)
VMATH = bind(vmath.sincos, vmath.atan2, vmath.tanh, vmath.exp)
