"""The ground's relief, compiled: the height z(x, y) of a scene's height grid and its gradient at any
point, and each cart's grade resistance on it.

A height grid (terrain.HeightGrid) is a bicubic B-spline interpolating every node (scipy's
RectBivariateSpline with s = 0 fits it; ``packing`` stores its knots and coefficients in P's RELIEF
block). Heights, slopes and curvatures are continuous, so the right-hand side is smooth across the
grid's lines. A point off the grid is moved onto its nearest edge (the train's positions are checked
against the grid outside the kernel: terrain.HeightGrid.covers).

On a height grid the model's x, y are horizontal (world) coordinates. Gravity is a potential force
element: the potential energy sum m_k g z(C_k) gives, referred to V, the grade resistance

    F_gk = m_k g grad z(C_k) . v_Ck / V,   v_Ck / V = kapB_k e_k + c_k kapT_k n_k

so F_gk V = m_k g dz(C_k)/dt, the power that lifts the cart, exactly; on a plane z = G . x it is the
tilted plane's grade resistance with g_p = -g G. The kinetic energy stays the horizontal motion's
(the vertical speed's share, (G . v)^2 / 2 per unit mass, is 0.25 % of it on a 5 % grade: left
out). The normal load of each cart, which sets its rolling resistance, is m_k g / sqrt(1 + |grad
z|^2) at C_k (g times the cosine of the local slope)."""
from __future__ import annotations

import math

from ...jit import jitable
from .base import CART_SIZE, HEAD_SIZE, C, H


@jitable
def knot_span(P, t, m, x):
    """(i, x clamped) with knots P[t + i] <= x < P[t + i + 1], 3 <= i < m - 4: the span of a cubic
    spline's m knots at P[t:] holding x, x first moved into [P[t + 3], P[t + m - 4]]."""
    n = m - 4
    if x <= P[t + 3]:
        return 3, P[t + 3]
    if x >= P[t + n]:
        return n - 1, P[t + n]
    lo, hi = 3, n
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if x >= P[t + mid]:
            lo = mid
        else:
            hi = mid
    return lo, x


@jitable
def cubic_basis(P, t, i, x):
    """The four cubic B-splines not zero on span i (N_{i-3} .. N_i) at x and their derivatives:
    Cox-de Boor's recursion (The NURBS Book, A2.2) written out for degree 3, the derivatives from
    the quadratic ones, N'_{j,3} = 3 (N_{j,2} / (t_{j+3} - t_j) - N_{j+1,2} / (t_{j+4} - t_{j+1}))."""
    l1, l2, l3 = x - P[t + i], x - P[t + i - 1], x - P[t + i - 2]
    r1, r2, r3 = P[t + i + 1] - x, P[t + i + 2] - x, P[t + i + 3] - x
    q = 1.0 / (r1 + l1)  # degree 1
    d0, d1 = r1 * q, l1 * q
    q0, q1 = d0 / (r1 + l2), d1 / (r2 + l1)  # degree 2
    a0, a1, a2 = r1 * q0, l2 * q0 + r2 * q1, l1 * q1
    w0, w1, w2 = a0 / (r1 + l3), a1 / (r2 + l2), a2 / (r3 + l1)  # degree 3
    b0, b1, b2, b3 = r1 * w0, l3 * w0 + r2 * w1, l2 * w1 + r3 * w2, l1 * w2
    return b0, b1, b2, b3, -3.0 * w0, 3.0 * (w0 - w1), 3.0 * (w1 - w2), 3.0 * w2


@jitable
def surface(P, g, x, y):
    """(z, dz/dx, dz/dy) of the height grid at (x, y), the point moved onto the grid (the RELIEF
    block at P[g:]: the numbers of knots along y and x, the knots along y, along x, then the
    coefficients, rows along y; P[H.relief] in a packed train)."""
    my, mx = int(P[g]), int(P[g + 1])
    ty, tx = g + 2, g + 2 + my
    coef, nx = tx + mx, mx - 4
    iy, y = knot_span(P, ty, my, y)
    ix, x = knot_span(P, tx, mx, x)
    y0, y1, y2, y3, dy0, dy1, dy2, dy3 = cubic_basis(P, ty, iy, y)
    x0, x1, x2, x3, dx0, dx1, dx2, dx3 = cubic_basis(P, tx, ix, x)
    z, zx, zy = 0.0, 0.0, 0.0
    for a in range(4):
        r = coef + (iy - 3 + a) * nx + ix - 3
        row = x0 * P[r] + x1 * P[r + 1] + x2 * P[r + 2] + x3 * P[r + 3]
        row_x = dx0 * P[r] + dx1 * P[r + 1] + dx2 * P[r + 2] + dx3 * P[r + 3]
        wy = y0 if a == 0 else y1 if a == 1 else y2 if a == 2 else y3
        wdy = dy0 if a == 0 else dy1 if a == 1 else dy2 if a == 2 else dy3
        z += wy * row
        zx += wy * row_x
        zy += wdy * row
    return z, zx, zy


@jitable
def relief_grade(P, k, heading, kapB, kapT, cx, cy):
    """(F_gk, cos of the local slope) of cart k with its centre of mass at (cx, cy) on the height
    grid: F_gk = m_k g grad z . v_Ck / V (the module docstring), > 0 while the cart climbs."""
    b = HEAD_SIZE + CART_SIZE * k
    ex, ey = math.cos(heading), math.sin(heading)
    com_rate = P[b + C.com_offset] * kapT
    vx, vy = kapB * ex - com_rate * ey, kapB * ey + com_rate * ex
    z, zx, zy = surface(P, int(P[H.relief]), cx, cy)
    return P[b + C.mass] * P[H.gravity] * (zx * vx + zy * vy), 1.0 / math.sqrt(1.0 + zx * zx + zy * zy)


@jitable
def off_relief(P, y):
    """The first cart (0-based) whose centre of mass C_k at state y is off the height grid (its knots'
    span along x and y: the grid's nodes), -1 for none (or without a grid)."""
    g = int(P[H.relief])
    if g == 0:
        return -1
    my, mx = int(P[g]), int(P[g + 1])
    ty, tx = g + 2, g + 2 + my
    ax, ay = y[0], y[1]
    for k in range(int(P[H.n])):
        b = HEAD_SIZE + CART_SIZE * k
        ex, ey = math.cos(y[2 + k]), math.sin(y[2 + k])
        bx, by = ax - P[b + C.length] * ex, ay - P[b + C.length] * ey
        cx, cy = bx + P[b + C.com_offset] * ex, by + P[b + C.com_offset] * ey
        if not (P[tx + 3] <= cx <= P[tx + mx - 4] and P[ty + 3] <= cy <= P[ty + my - 4]):
            return k
        ax, ay = bx - P[b + C.hitch_offset] * ex, by - P[b + C.hitch_offset] * ey
    return -1
