"""Explicit Runge-Kutta methods as data: a method is its Butcher tableau (as scipy's rk.py does).

    k_i = f(t + c_i h, y + h sum_j a_ij k_j),   y_next = y + h sum_i b_i k_i

One stepping routine steps every table (``rk.rk_step``, compiled and as plain Python),
and everything else is derived from the table: the order (from the order conditions), the
stability function R(z) = 1 + sum_k z^k b^T A^(k-1) 1 (exact, in rationals) and its real-axis
stability limit (``integrate.stability``). Adding a method is adding a table to ``TABLEAUX``.

Coefficients are exact fractions. The kernel takes each row as integer numerators over the row's
common denominator, stage y + (h / d) sum_j n_j k_j, which is how euler, heun and rk4 are printed
and computed: the arithmetic of y + (h / 6)(k1 + 2 k2 + 2 k3 + k4), bit for bit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction as F
from functools import cached_property

import numpy as np


@dataclass(frozen=True)
class Tableau:
    """An explicit Runge-Kutta method: A strictly lower triangular (row i has i entries), b, c."""

    name: str
    A: tuple[tuple[F, ...], ...]
    b: tuple[F, ...]
    description: str = ""

    def __post_init__(self):
        s = len(self.b)
        if len(self.A) != s or any(len(row) != i for i, row in enumerate(self.A)):
            raise ValueError(f"tableau {self.name}: A must have rows of 0, 1, ..., {s - 1} entries")

    @property
    def stages(self) -> int:
        return len(self.b)

    @cached_property
    def c(self) -> tuple[F, ...]:
        """Nodes c_i = sum_j a_ij (the usual row-sum condition)."""
        return tuple(sum(row, F(0)) for row in self.A)

    def matrix(self) -> list[list[F]]:
        s = self.stages
        return [list(row) + [F(0)] * (s - len(row)) for row in self.A]

    @cached_property
    def order(self) -> int:
        """The highest order p <= 4 whose order conditions all hold (Butcher, for p <= 4)."""
        A, b, c = self.matrix(), self.b, self.c
        s = self.stages
        Ac = [sum(A[i][j] * c[j] for j in range(s)) for i in range(s)]
        Ac2 = [sum(A[i][j] * c[j] ** 2 for j in range(s)) for i in range(s)]
        AAc = [sum(A[i][j] * Ac[j] for j in range(s)) for i in range(s)]
        conditions = (
            (sum(b) == 1,),
            (sum(bi * ci for bi, ci in zip(b, c)) == F(1, 2),),
            (sum(bi * ci ** 2 for bi, ci in zip(b, c)) == F(1, 3), sum(bi * x for bi, x in zip(b, Ac)) == F(1, 6)),
            (sum(bi * ci ** 3 for bi, ci in zip(b, c)) == F(1, 4),
             sum(bi * ci * x for bi, ci, x in zip(b, c, Ac)) == F(1, 8),
             sum(bi * x for bi, x in zip(b, Ac2)) == F(1, 12),
             sum(bi * x for bi, x in zip(b, AAc)) == F(1, 24)),
        )
        order = 0
        for holds in conditions:
            if not all(holds):
                break
            order += 1
        return order

    @cached_property
    def stability_polynomial(self) -> tuple[F, ...]:
        """Coefficients r_0..r_s of R(z) = sum_k r_k z^k: r_0 = 1, r_k = b^T A^(k-1) 1."""
        A, s = self.matrix(), self.stages
        v = [F(1)] * s
        coeffs = [F(1)]
        for _ in range(s):
            coeffs.append(sum(bi * vi for bi, vi in zip(self.b, v)))
            v = [sum(A[i][j] * v[j] for j in range(s)) for i in range(s)]
        return tuple(coeffs)

    def stability_function(self, z: complex) -> complex:
        """R(z): the factor one step applies to y' = lambda y, z = lambda h."""
        return sum(float(r) * z ** k for k, r in enumerate(self.stability_polynomial))

    @cached_property
    def real_axis_limit(self) -> float:
        """The largest x such that |R(-u)| <= 1 for every u in (0, x]: a mode y' = -r y decays
        under steps h < x / r. The smallest positive root of R(-x)^2 = 1."""
        r = np.array([float(v) * (-1) ** k for k, v in enumerate(self.stability_polynomial)])  # R(-x)
        square = np.polynomial.polynomial.polymul(r, r)
        square[0] -= 1.0
        roots = np.polynomial.polynomial.polyroots(square)
        real = sorted(x.real for x in roots if abs(x.imag) < 1e-9 and x.real > 1e-9)
        if not real:
            return math.inf
        # polish the root with Newton on R(-x)^2 - 1 (numpy's roots are good to ~1e-12 here)
        x = real[0]
        p = np.polynomial.Polynomial(square)
        dp = p.deriv()
        for _ in range(4):
            x -= p(x) / dp(x)
        return float(x)

    @cached_property
    def packed(self) -> np.ndarray:
        """The tableau as the kernel's stepping routine reads it (``rk.rk_step``), float64
        (s + 2) x (s + 1): row i < s (d_i, numerators of a_i0..a_i,s-1) over the row's common
        denominator d_i; row s (d, numerators of b_0..b_s-1); row s + 1 (0, c_0..c_s-1)."""
        s = self.stages
        T = np.zeros((s + 2, s + 1))
        for i, row in enumerate(self.A + (self.b,)):
            d = math.lcm(*(x.denominator for x in row)) if row else 1
            T[i, 0] = d
            T[i, 1:1 + len(row)] = [float(x * d) for x in row]
        T[s + 1, 1:] = [float(x) for x in self.c]
        T.setflags(write=False)
        return T


def _table(name, A, b, description):
    return Tableau(name, tuple(tuple(F(x) for x in row) for row in A), tuple(F(x) for x in b), description)


#: the fixed-step methods, by name (the names of spec.INTEGRATOR_METHODS that are not scipy's)
TABLEAUX = {t.name: t for t in (
    _table("euler", [[]], [1], "forward Euler, order 1"),
    _table("heun", [[], [1]], [F(1, 2), F(1, 2)], "Heun's method (explicit trapezoid), order 2"),
    _table("ralston", [[], [F(2, 3)]], [F(1, 4), F(3, 4)],
           "Ralston's second-order method (least error constant of the 2-stage methods)"),
    _table("kutta3", [[], [F(1, 2)], [-1, 2]], [F(1, 6), F(2, 3), F(1, 6)], "Kutta's third-order method"),
    _table("rk4", [[], [F(1, 2)], [0, F(1, 2)], [0, 0, 1]], [F(1, 6), F(1, 3), F(1, 3), F(1, 6)],
           "the classic fourth-order Runge-Kutta method"),
    _table("rk38", [[], [F(1, 3)], [F(-1, 3), 1], [1, -1, 1]], [F(1, 8), F(3, 8), F(3, 8), F(1, 8)],
           "Kutta's 3/8 rule, order 4"),
)}
