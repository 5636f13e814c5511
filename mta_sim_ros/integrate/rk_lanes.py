"""One Runge-Kutta step of a batch of schemes, one per SIMD lane (issue 24, docs/lanes.md): ``rk.rk_step``
in the shape LLVM vectorises, for a batch stepped with one step length (the same tick and method,
no kink inside the step: the caller splits a lane's kinked step with the scalar stepper).

Arrays as in physics/kernel/batched.py, the scheme index innermost: y, tmp, out (size, L), K
(stages, size, L), the held inputs (L,), ``lag`` (5, L): per lane (on, psi0, command, release,
T0) as ``rk_step``'s (``on`` read from lane 0: on in every lane or in none), ``work`` the
right-hand side's rows.

The arithmetic is ``rk_step``'s: each stage's sum over the non-zero tableau entries left to right,
starting from its first term, and the steering angle from the actuator's closed form (walk.py's
``actuator``) where ``lag`` is on. ``stepper_with`` binds the right-hand side and the actuator's
math: with ``batched.rhs_lanes_libm`` and walk.LIBM each lane's step is ``rk_step``'s bit for bit
(test/test_batched.py)."""
from __future__ import annotations

import numpy as np

from ..jit import jitable, lanes
from ..physics.kernel.base import REC, H
from ..physics.kernel.batched import WORK_ROWS, rhs_lanes, rhs_lanes_libm
from ..physics.kernel.walk import LIBM, VMATH


def stepper_with(rhs_lanes_fn, walk):
    """``rk_step_lanes`` calling ``rhs_lanes_fn`` and walk's ``actuator``."""
    actuator = walk.actuator

    @jitable
    def steer(P, lag, at, ip, dst, max_rates):
        """The steering angle of every lane at ``at`` s into the tick, into dst[ip]."""
        for j in range(dst.shape[1]):
            dst[ip, j] = actuator(P[H.max_angle, j], P[H.time_constant, j], lag[1, j], lag[2, j], max_rates[j],
                                  lag[3, j], lag[4, j] + at)

    @jitable
    def rk_step_lanes(P, T, y, commands, v_sets, max_rates, h, K, tmp, out, rec, mode, lag, work, acc):
        """One step of length h of the tableau T from y into ``out`` for every lane; returns the stages."""
        stages = T.shape[0] - 2
        size, L = y.shape[0], y.shape[1]
        exact = lag[0, 0] != 0.0
        ip = int(P[H.n, 0]) + 2 if exact else 0
        rhs_lanes_fn(P, y, commands, v_sets, max_rates, K[0], rec, mode, work)
        for i in range(1, stages + 1):
            dst = tmp if i < stages else out
            scale = h / T[i, 0]
            for m in range(size):
                first = True
                for s in range(i if i < stages else stages):
                    a = T[i, 1 + s]
                    if a != 0.0:
                        if first:
                            for j in range(L):
                                acc[j] = a * K[s, m, j]
                        else:
                            for j in range(L):
                                acc[j] = acc[j] + a * K[s, m, j]
                        first = False
                if first:
                    for j in range(L):
                        dst[m, j] = y[m, j]
                else:
                    for j in range(L):
                        dst[m, j] = y[m, j] + scale * acc[j]
            if i < stages:
                if exact:
                    steer(P, lag, T[stages + 1, 1 + i] * h, ip, tmp, max_rates)
                rhs_lanes_fn(P, tmp, commands, v_sets, max_rates, K[i], rec, mode, work)
        if exact:
            steer(P, lag, h, ip, out, max_rates)
        return stages

    return rk_step_lanes


rk_step_lanes = stepper_with(rhs_lanes, VMATH)
rk_step_lanes_libm = stepper_with(rhs_lanes_libm, LIBM)


@jitable
def arrays(T, y):
    """(K, tmp, out, rec, work, acc) for a step of the batch y with the tableau T."""
    size, L = y.shape[0], y.shape[1]
    return (np.empty((T.shape[0] - 2, size, L)), np.empty((size, L)), np.empty((size, L)), np.empty((0, REC, L)),
            np.empty((WORK_ROWS, L)), np.empty(L))


@lanes
def step_lanes_of(P, T, y, commands, v_sets, max_rates, h, mode, lag):
    """``rk_step_lanes`` (vmath) of a batch: the stepped states as a new array."""
    K, tmp, out, rec, work, acc = arrays(T, y)
    rk_step_lanes(P, T, y, commands, v_sets, max_rates, h, K, tmp, out, rec, mode, lag, work, acc)
    return out


@lanes
def step_lanes_libm_of(P, T, y, commands, v_sets, max_rates, h, mode, lag):
    """``rk_step_lanes_libm``: each lane's ``rk.rk_step``, to the bit."""
    K, tmp, out, rec, work, acc = arrays(T, y)
    rk_step_lanes_libm(P, T, y, commands, v_sets, max_rates, h, K, tmp, out, rec, mode, lag, work, acc)
    return out
