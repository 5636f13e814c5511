"""Where the points of each cart are, from the generalized coordinates q (MODEL.md, Geometry).

    B_k = A_k - l_k e_k,   C_k = B_k + c_k e_k,   A_{k+1} = B_k - a_k e_k,   e_k = (cos th_k, sin th_k)
"""
from __future__ import annotations

import math

import numpy as np


def cart_points(train, x_a1: float, y_a1: float, heading) -> dict[str, np.ndarray]:
    """Positions (n x 2 arrays, m) of every cart's front point A_k, axle centre B_k and centre
    of mass C_k, plus the rear hitch A_{n+1} of the last cart (``rear_hitch``, 2-vector).

    Works on float or complex inputs (complex-step tests differentiate it). One O(n) walk on
    scalars, then one array per point kind.
    """
    dtype = np.result_type(type(x_a1), type(y_a1), np.asarray(heading).dtype, float)
    if dtype == np.float64:  # Python floats and math: several times faster than numpy scalars
        cos, sin, heading = math.cos, math.sin, np.asarray(heading, dtype=float).tolist()
    else:
        cos, sin = np.cos, np.sin
    A, B, C = [], [], []
    ax, ay = x_a1, y_a1
    for cart, th in zip(train.carts, heading):
        ex, ey = cos(th), sin(th)
        A.append((ax, ay))
        bx, by = ax - cart.length * ex, ay - cart.length * ey
        B.append((bx, by))
        C.append((bx + cart.com_offset * ex, by + cart.com_offset * ey))
        ax, ay = bx - cart.hitch_offset * ex, by - cart.hitch_offset * ey
    return {"A": np.array(A, dtype=dtype), "B": np.array(B, dtype=dtype), "C": np.array(C, dtype=dtype),
            "rear_hitch": np.array([ax, ay], dtype=dtype)}


def hitch_angles(heading) -> list[float]:
    """phi_k = th_{k-1} - th_k for k = 2..n, wrapped to [-pi, pi], rad (positive: cart k is to
    the right of cart k-1's axis, i.e. the train bends left)."""
    return [wrap_angle(heading[k - 1] - heading[k]) for k in range(1, len(heading))]


def wrap_angle(a: float) -> float:
    """a wrapped to [-pi, pi], rad."""
    return math.remainder(a, 2.0 * math.pi)
