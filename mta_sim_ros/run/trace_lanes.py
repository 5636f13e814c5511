"""A run's trace row for every lane of a batch at once (issue 24, docs/lanes.md): ``whole.trace_row``
(``motion.outputs`` and ``motion.drawbar_pulls``) in the shape LLVM vectorises, for whole_lanes.py.

The same pieces as the scalar row (physics/kernel/walk.py: ``pose``, ``hitch_margin``,
``accelerations``, ``in_plane``, ``towed_pull``, ``tractor_forces``), called in the carts' loop with a
loop over lanes inside, their math bound with the right-hand side's (``tracer_with``): with the C
library's each lane's row is ``trace_row``'s bit for bit (test/test_whole_lanes.py). A height grid
is not batched (packing.stack), so the relief's branch of ``drawbar_pulls`` has no lanes form.

Arrays as in batched.py, the lane index innermost: y, dy (size, L); rec (n, REC, L); ``frame``
(FRAME_ROWS, L) the walk's running values; ``out`` (TRACE_HEAD + TRACE_CART n, L) the rows of one
tick of the run's trace, a column per lane."""
from __future__ import annotations

import math

import numpy as np

from ..jit import inlined, jitable
from ..physics.kernel.base import CART_SIZE, HEAD_SIZE, KAPB, KAPB_DOT, KAPT, KAPT_DOT, PSI, REC, RES, C, H, pymin, wrap_angle
from ..physics.kernel.batched import TRACTION_OUT, WORK_ROWS, rhs_lanes, rhs_lanes_libm
from ..physics.kernel.vmath import pick
from ..physics.kernel.walk import LIBM, VMATH, accelerations, hitch_margin, in_plane, towed_pull
from .whole import TR_BX, TR_BY, TR_FRONT_LAT, TR_HEADING, TR_LAT, TR_MARGIN, TR_PHI, TR_PULL, TR_SPEED, TR_STEERING, \
    TR_TRACTION, TRACE_CART, TRACE_HEAD

#: rows of ``frame``: the hitch A_k the walk is at, the smallest jackknife margin so far, H_{k+1}
F_AX, F_AY, F_BEST, F_HX, F_HY = range(5)
FRAME_ROWS = F_HY + 1


def tracer_with(rhs_lanes_fn, walk):
    """``trace_lanes`` calling ``rhs_lanes_fn`` and walk's ``pose`` and ``tractor_forces``."""
    sincos, pose, tractor_forces = walk.sincos, walk.pose, walk.tractor_forces

    @jitable
    def poses(P, y, rec, frame, out):
        """Each cart's axle B_k, heading and hitch angle, and the smallest jackknife margin
        (``outputs``' walk from the tractor's front axle back)."""
        n, L = int(P[H.n, 0]), y.shape[1]
        for j in range(L):
            frame[F_AX, j], frame[F_AY, j], frame[F_BEST, j] = y[0, j], y[1, j], math.inf
        for k in range(n):
            b = HEAD_SIZE + CART_SIZE * k
            col = TRACE_HEAD + TRACE_CART * k
            for j in range(L):
                _, _, bx, by, _, _, ax, ay = pose(y[2 + k, j], frame[F_AX, j], frame[F_AY, j], P[b + C.length, j],
                                                  P[b + C.com_offset, j], P[b + C.hitch_offset, j])
                out[col + TR_BX, j], out[col + TR_BY, j], out[col + TR_HEADING, j] = bx, by, y[2 + k, j]
                frame[F_AX, j], frame[F_AY, j] = ax, ay
            if k:
                for j in range(L):
                    phi = wrap_angle(y[1 + k, j] - y[2 + k, j])
                    out[col + TR_PHI, j] = phi
                    frame[F_BEST, j] = pymin(frame[F_BEST, j], hitch_margin(P[b + C.max_hitch, j], phi, rec[k, PSI, j]))
            else:
                for j in range(L):
                    out[col + TR_PHI, j] = 0.0
        for j in range(L):
            out[TR_MARGIN, j] = frame[F_BEST, j]

    @jitable
    def pulls(P, y, dy, rec, work, frame, out):
        """The pull and the lateral force at each hitch and axle (``drawbar_pulls``' walk from the
        last cart forward: the towed carts, then the tractor). Each loop over lanes is straight-line
        code (a tilted plane's gravity picked, not branched on), so that LLVM vectorises it."""
        n, L = int(P[H.n, 0]), y.shape[1]
        sloped = P[H.slope, 0] != 0.0
        for j in range(L):
            frame[F_HX, j], frame[F_HY, j] = 0.0, 0.0
        for k in range(n - 1, 0, -1):
            b = HEAD_SIZE + CART_SIZE * k
            col = TRACE_HEAD + TRACE_CART * k
            for j in range(L):
                ey, ex = sincos(y[2 + k, j])
                rate_dot, a_e, a_n = cart_motion(
                    ex, ey, y[n + 3, j], dy[n + 3, j], rec[k, KAPT_DOT, j], rec[k, KAPT, j], rec[k, KAPB_DOT, j],
                    rec[k, KAPB, j], P[b + C.com_offset, j], P[H.gravity_x, j], P[H.gravity_y, j], sloped)
                pull, lat, hx, hy = towed_pull(frame[F_HX, j], frame[F_HY, j], ex, ey, rec[k, RES, j],
                                               P[b + C.mass, j], a_e, a_n, P[b + C.inertia, j], rate_dot,
                                               P[b + C.com_offset, j], P[b + C.hitch_offset, j], P[b + C.length, j])
                out[col + TR_PULL, j], out[col + TR_LAT, j] = pull, lat
                frame[F_HX, j], frame[F_HY, j] = hx, hy
        b = HEAD_SIZE
        for j in range(L):
            ey, ex = sincos(y[2, j])
            rate_dot, a_e, a_n = cart_motion(
                ex, ey, y[n + 3, j], dy[n + 3, j], rec[0, KAPT_DOT, j], rec[0, KAPT, j], rec[0, KAPB_DOT, j],
                rec[0, KAPB, j], P[b + C.com_offset, j], P[H.gravity_x, j], P[H.gravity_y, j], sloped)
            lat, front, pull = tractor_forces(frame[F_HX, j], frame[F_HY, j], ex, ey, P[b + C.mass, j], a_n,
                                              P[b + C.inertia, j], rate_dot, P[b + C.hitch_offset, j],
                                              P[b + C.com_offset, j], P[b + C.length, j], work[TRACTION_OUT, j],
                                              y[n + 2, j])
            out[TRACE_HEAD + TR_LAT, j], out[TR_FRONT_LAT, j], out[TRACE_HEAD + TR_PULL, j] = lat, front, pull

    @jitable
    def trace_lanes(P_out, y, commands, law_inputs, max_rates, dy, rec, mode, work, frame, out):
        """``whole.trace_row`` of every lane into the columns of ``out``; ``mode`` (0, L): no held branch."""
        n, L = int(P_out[H.n, 0]), y.shape[1]
        rhs_lanes_fn(P_out, y, commands, law_inputs, max_rates, dy, rec, mode, work)
        for j in range(L):
            out[TR_TRACTION, j], out[TR_SPEED, j], out[TR_STEERING, j] = work[TRACTION_OUT, j], y[n + 3, j], y[n + 2, j]
        poses(P_out, y, rec, frame, out)
        pulls(P_out, y, dy, rec, work, frame, out)

    return trace_lanes


@inlined
def cart_motion(ex, ey, V, acceleration, kapT_dot, kapT, kapB_dot, kapB, com, gravity_x, gravity_y, sloped):
    """(th''_k, a_e, a_n) of a cart whose axis is e_k = (ex, ey) (``accelerations``; on a tilted plane
    ``in_plane``), on numbers (an array handed to an inlined function keeps LLVM from vectorising the
    loop)."""
    rate_dot, a_e, a_n = accelerations(kapT_dot, kapT, kapB_dot, kapB, V, acceleration, com, kapB * V, kapT * V)
    tilted_e, tilted_n = in_plane(a_e, a_n, ex, ey, gravity_x, gravity_y)
    return rate_dot, pick(sloped, tilted_e, a_e), pick(sloped, tilted_n, a_n)


trace_lanes = tracer_with(rhs_lanes, VMATH)
trace_lanes_libm = tracer_with(rhs_lanes_libm, LIBM)


@jitable
def trace_arrays(P_out, y):
    """(dy, rec, mode, work, frame) for ``trace_lanes`` of the batch y."""
    n, L = int(P_out[H.n, 0]), y.shape[1]
    return (np.empty_like(y), np.empty((n, REC, L)), np.empty((0, L), dtype=np.int64), np.empty((WORK_ROWS, L)),
            np.empty((FRAME_ROWS, L)))

