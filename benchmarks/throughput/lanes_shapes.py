"""Three shapes of a loop over a batch of schemes, for ``python -m benchmarks lanes``: which one does
LLVM vectorise when the body walks a chain of carts?

The body is the kinematic chain's walk of physics/kernel/motion.py's ``rhs`` cut to its core (per
cart: sin and cos of psi_k, kapT_k, th'_k, the speed ratio's sqrt, psi_{k+1} by atan2), enough to
show the shapes, not a second physics: nothing here is called by the package.

scalar      one scheme a call (arrays of the scheme, ``math.*``), in a loop over schemes: what the
            kernel does today
lanes out   the same body in a loop over lanes (vmath), the number of carts a compile-time
            constant: LLVM vectorises the lanes' loop only if it unrolls the carts' loop inside it
lanes in    the carts' loop outside, a loop over lanes inside each of its steps (vmath), the values
            a cart hands to the next kept per lane: every inner loop is straight-line code
"""
from __future__ import annotations

import math

import numba
import numpy as np

from mta_sim_ros.jit import jitable
from mta_sim_ros.physics.kernel import vmath


@numba.njit
def walk_one(P, y, dy):
    n = P.shape[0] // 2
    V, k_val, p_val = y[n + 3], 1.0, y[n + 2]
    for k in range(n):
        s, c = math.sin(p_val), math.cos(p_val)
        dy[2 + k] = k_val * s / P[2 * k] * V
        if k < n - 1:
            lam = P[2 * k + 1]
            k_val = k_val * math.sqrt(c * c + lam * lam * s * s)
            p_val = y[2 + k] - y[3 + k] - math.atan2(lam * s, c)
    course = y[2] + y[n + 2]
    dy[0], dy[1] = V * math.cos(course), V * math.sin(course)


@numba.njit
def scalar(P, Y, DY, kv, pv):
    """P, Y, DY one scheme a row (``rows``): each scheme's numbers side by side, as the kernel has them."""
    for j in range(Y.shape[0]):
        walk_one(P[j], Y[j], DY[j])


def lanes_out(n: int):
    """The scalar body over lanes, n frozen into the compiled code (a closure's constant)."""
    @numba.njit(error_model="numpy")
    def run(P, Y, DY, kv, pv):
        for j in range(Y.shape[1]):
            V, k_val, p_val = Y[n + 3, j], 1.0, Y[n + 2, j]
            for k in range(n):
                s, c = vmath.sincos(p_val)
                DY[2 + k, j] = k_val * s / P[2 * k, j] * V
                if k < n - 1:
                    lam = P[2 * k + 1, j]
                    k_val = k_val * math.sqrt(c * c + lam * lam * s * s)
                    p_val = Y[2 + k, j] - Y[3 + k, j] - vmath.atan2(lam * s, c)
            s1, c1 = vmath.sincos(Y[2, j] + Y[n + 2, j])
            DY[0, j], DY[1, j] = V * c1, V * s1
    return run


def lanes_in_with(sincos, atan2):
    """The ``lanes in`` shape with its math bound at compile time: one source, two compiled forms."""
    @numba.njit(error_model="numpy")
    def run(P, Y, DY, kv, pv):
        L, n = Y.shape[1], P.shape[0] // 2
        for j in range(L):
            kv[j], pv[j] = 1.0, Y[n + 2, j]
        for k in range(n):
            nxt = min(k + 1, n - 1)  # the last cart's psi_{k+1} is computed and not used
            for j in range(L):
                s, c = sincos(pv[j])
                DY[2 + k, j] = kv[j] * s / P[2 * k, j] * Y[n + 3, j]
                lam = P[2 * k + 1, j]
                kv[j] = kv[j] * math.sqrt(c * c + lam * lam * s * s)
                pv[j] = Y[2 + k, j] - Y[2 + nxt, j] - atan2(lam * s, c)
        for j in range(L):
            s1, c1 = sincos(Y[2, j] + Y[n + 2, j])
            DY[0, j], DY[1, j] = Y[n + 3, j] * c1, Y[n + 3, j] * s1
    return run


@jitable
def libm_sincos(x):
    return math.sin(x), math.cos(x)


lanes_in = lanes_in_with(vmath.sincos, vmath.atan2)
lanes_in_libm = lanes_in_with(libm_sincos, math.atan2)


def repeated(fn):
    """``fn`` ``times`` over, from compiled code: one call's cost without Python's (at one lane: the
    node's tick as a batch of one)."""
    @numba.njit
    def run(P, Y, DY, kv, pv, times):
        for _ in range(times):
            fn(P, Y, DY, kv, pv)
            Y[0, 0] += DY[0, 0] * 1e-300  # a store after each call (y[0] is not read by the walk)
    return run


def batch(n: int, width: int, seed: int = 0) -> tuple:
    """(P, Y, DY, kv, pv) for ``width`` random trains of ``n`` carts, the scheme index innermost."""
    rng = np.random.default_rng(seed)
    P = np.empty((2 * n, width))
    P[0::2], P[1::2] = rng.uniform(2.0, 6.0, (n, width)), rng.uniform(-0.3, 0.3, (n, width))
    Y = np.zeros((n + 5, width))
    Y[2:2 + n], Y[n + 2], Y[n + 3] = rng.uniform(-0.3, 0.3, (n, width)), rng.uniform(-0.3, 0.3, width), 2.0
    return P, Y, np.zeros_like(Y), np.empty(width), np.empty(width)


def rows(arrays: tuple) -> tuple:
    """``batch``'s arrays one scheme a row, for ``scalar``."""
    P, Y, DY, kv, pv = arrays
    return np.ascontiguousarray(P.T), np.ascontiguousarray(Y.T), np.zeros_like(DY.T), kv, pv


def shapes(n: int) -> dict:
    """label -> (compiled function, whether it takes ``rows``)."""
    return {"scalar": (scalar, True), "lanes out": (lanes_out(n), False), "lanes in": (lanes_in, False)}
