"""The kinematic chain: velocity coefficients of every element, linear in the pseudo-velocity V.

MODEL.md [12]-[16]. With the steering angle psi_1 given, the no-side-slip constraints leave one
degree of freedom, V = s'_A1. Walking down the train from the tractor, each cart's hitch-point
speed V_k and angle psi_k (from the cart axis e_k to v_Ak) give the next ones:

    th'_k     = V_k sin(psi_k) / l_k                      kapT_k = th'_k / V
    s'_Bk     = V_k cos(psi_k)                            kapB_k = s'_Bk / V
    s'_Ck     = V_k sqrt(cos^2 psi_k + mu_k^2 sin^2 psi_k)  kapC_k = s'_Ck / V,  mu_k = c_k / l_k
    V_{k+1}   = V_k sqrt(cos^2 psi_k + lam_k^2 sin^2 psi_k)  kap_{k+1} = V_{k+1} / V, lam_k = a_k / l_k
    beta_k    = atan2(lam_k sin psi_k, cos psi_k)
    psi_{k+1} = th_k - th_{k+1} - beta_k

The kap's are the article's structural matrices W = d(element velocity)/dV. Their time
derivatives along the motion (needed for dM/dt and for G' in algorithm 1) are propagated in the
same loop by forward-mode differentiation written out by hand: every line ``x_d = ...`` is the
exact derivative of the line above it, with th'_j = kapT_j V and psi_1' = the actuator rate.
No finite differences.

This is the readable reference: one list per quantity, each line the formula of MODEL.md. The
integrators' hot path, ``Model.rhs``, runs the same recursion fused with the sums of the dynamics
in one pass over the carts (``kernel.rhs``), and the tests hold the two equal bit for bit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import kernel


@dataclass(frozen=True)
class ChainGeometry:
    """Per-cart constants of the chain, read from the packed constants (``kernel.pack``), so that
    the reference and the kernels see the same numbers."""

    length: tuple[float, ...]  # l_k
    lam: tuple[float, ...]  # a_k / l_k
    mu: tuple[float, ...]  # c_k / l_k

    @classmethod
    def of(cls, P) -> "ChainGeometry":
        """From packed constants P, or from a Train (packed here)."""
        if not isinstance(P, np.ndarray):
            P = kernel.pack(P)
        return cls(*(kernel.column(P, name) for name in ("length", "lam", "mu")))


@dataclass
class Chain:
    """Velocity coefficients per cart (index k = 0..n-1 is cart k+1), and their time derivatives.

    kap[k]   V_k / V        (speed of the hitch point A_k; kap[0] = 1)
    psi[k]   psi_k, rad     (angle from e_k to v_Ak; psi[0] is the steering angle)
    kapT[k]  th'_k / V      kapB[k] s'_Bk / V      kapC[k] s'_Ck / V
    *_d      d/dt of each, along the motion with the given V and psi_1'
    """

    kap: list
    psi: list
    kapT: list
    kapB: list
    kapC: list
    kap_d: list
    psi_d: list
    kapT_d: list
    kapB_d: list
    kapC_d: list


def chain(geom: ChainGeometry, heading, psi1: float, V: float, psi1_rate: float, fn=math) -> Chain:
    """Walk the train from the tractor back; ``heading`` holds th_1..th_n (rad).

    ``fn`` gives sin, cos, sqrt and atan2: ``math`` for numbers (the reference), or ``sympy`` for
    the same recursion on symbols (``linear.py``: its exact derivatives; the printed equations),
    so the symbolic model is this source, not a copy of it."""
    n = len(geom.length)
    kap, psi, kapT, kapB, kapC = [], [], [], [], []
    kap_d, psi_d, kapT_d, kapB_d, kapC_d = [], [], [], [], []

    k_val, k_dot = 1.0, 0.0  # kap_1 = 1 for every state
    p_val = psi1
    theta_rate_prev = 0.0
    beta_dot_prev = 0.0
    for k in range(n):
        l_k, lam, mu = geom.length[k], geom.lam[k], geom.mu[k]
        s, c = fn.sin(p_val), fn.cos(p_val)

        t_val = k_val * s / l_k  # kapT_k
        theta_rate = t_val * V  # th'_k
        # psi_k' : the steering rate for the tractor, from psi_k = th_{k-1} - th_k - beta_{k-1} else
        p_dot = psi1_rate if k == 0 else theta_rate_prev - theta_rate - beta_dot_prev
        s_dot, c_dot = c * p_dot, -s * p_dot
        t_dot = (k_dot * s + k_val * s_dot) / l_k

        b_val = k_val * c  # kapB_k
        b_dot = k_dot * c + k_val * c_dot

        rc = fn.sqrt(c * c + mu * mu * s * s)  # s'_Ck / V_k
        rc_dot = (c * c_dot + mu * mu * s * s_dot) / rc
        kc_val = k_val * rc
        kc_dot = k_dot * rc + k_val * rc_dot

        kap.append(k_val); kap_d.append(k_dot)
        psi.append(p_val); psi_d.append(p_dot)
        kapT.append(t_val); kapT_d.append(t_dot)
        kapB.append(b_val); kapB_d.append(b_dot)
        kapC.append(kc_val); kapC_d.append(kc_dot)

        if k + 1 < n:
            rl2 = c * c + lam * lam * s * s
            rl = fn.sqrt(rl2)  # V_{k+1} / V_k
            rl_dot = (c * c_dot + lam * lam * s * s_dot) / rl
            beta = fn.atan2(lam * s, c)
            beta_dot_prev = lam * p_dot / rl2  # d/dt atan2(lam s, c) = lam psi' / (c^2 + lam^2 s^2)
            k_val, k_dot = k_val * rl, k_dot * rl + k_val * rl_dot
            p_val = heading[k] - heading[k + 1] - beta
            theta_rate_prev = theta_rate
    return Chain(kap, psi, kapT, kapB, kapC, kap_d, psi_d, kapT_d, kapB_d, kapC_d)
