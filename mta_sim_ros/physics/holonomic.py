"""Algorithm 1 of the article: the holonomic equations of the n + 2 coordinates, reduced by G.

Without the rolling constraints the train is a chain of rigid bodies with coordinates
q = (x_A1, y_A1, th_1..th_n). Each centre of mass is a linear combination of the axis vectors:

    C_k = A_1 + sum_j DC_kj e_j,  DC_kj = -(l_j + a_j) for j < k,  DC_kk = -(l_k - c_k),  0 for j > k
    B_k = A_1 + sum_j DB_kj e_j,  DB_kj = -(l_j + a_j) for j < k,  DB_kk = -l_k

so v_Ck = J_Ck q' with J_Ck = [I_2, DC_k1 n_1, ..., DC_kn n_n], n_j = (-sin th_j, cos th_j),
and the holonomic equations (Jourdain's principle) are

    M_h q'' + h = Q_h,   M_h = sum_k m_k J_Ck^T J_Ck + diag(0, 0, J_1..J_n),
                         h   = sum_k m_k J_Ck^T (-sum_j DC_kj th_j'^2 e_j)   (J_Ck' q').

The constraints q' = G V (G from the chain) give the article's equation [8] for the one
pseudo-velocity:  (G^T M_h G) V' = G^T Q_h - G^T (M_h G' V + h).

This is the slow, transparent reference the fast algorithm 2 is tested against; the node uses 2.
"""
from __future__ import annotations

import math

import numpy as np

from .chain import Chain


def offset_matrices(train) -> tuple[np.ndarray, np.ndarray]:
    """(DC, DB): the coefficients of e_j in C_k - A_1 and B_k - A_1 (n x n, m)."""
    n = train.n
    DC = np.zeros((n, n))
    DB = np.zeros((n, n))
    for k, cart in enumerate(train.carts):
        for j in range(k):
            prev = train.carts[j]
            DC[k, j] = DB[k, j] = -(prev.length + prev.hitch_offset)
        DC[k, k] = -(cart.length - cart.com_offset)
        DB[k, k] = -cart.length
    return DC, DB


class HolonomicReduction:
    def __init__(self, train):
        self.n = train.n
        self.DC, self.DB = offset_matrices(train)
        self.m = np.array([c.mass for c in train.carts])
        self.J = np.array([c.yaw_inertia for c in train.carts])

    def point_jacobian(self, D_row: np.ndarray, heading: np.ndarray) -> np.ndarray:
        """2 x (n+2) Jacobian d(point)/dq of a point A_1 + sum_j D_j e_j."""
        Jp = np.zeros((2, self.n + 2))
        Jp[0, 0] = Jp[1, 1] = 1.0
        Jp[0, 2:] = -D_row * np.sin(heading)
        Jp[1, 2:] = D_row * np.cos(heading)
        return Jp

    def mass_matrix(self, heading: np.ndarray) -> np.ndarray:
        Mh = np.diag(np.concatenate(([0.0, 0.0], self.J)))
        for k in range(self.n):
            Jc = self.point_jacobian(self.DC[k], heading)
            Mh += self.m[k] * Jc.T @ Jc
        return Mh

    def velocity_forces(self, heading: np.ndarray, heading_rate: np.ndarray) -> np.ndarray:
        """h(q, q'): the part of sum m_k J_Ck^T a_Ck that does not contain q''."""
        h = np.zeros(self.n + 2)
        e = np.stack((np.cos(heading), np.sin(heading)), axis=1)
        for k in range(self.n):
            centripetal = -(self.DC[k] * heading_rate**2) @ e  # J_Ck' q', a 2-vector
            h += self.m[k] * self.point_jacobian(self.DC[k], heading).T @ centripetal
        return h

    @staticmethod
    def constraint_matrix(heading, psi1: float, ch: Chain, psi_rate: float, V: float):
        """G (q' = G V) and its time derivative G' along the motion."""
        course = heading[0] + psi1
        course_rate = ch.kapT[0] * V + psi_rate
        G = np.concatenate(([math.cos(course), math.sin(course)], ch.kapT))
        G_dot = np.concatenate(([-math.sin(course) * course_rate, math.cos(course) * course_rate], ch.kapT_d))
        return G, G_dot

    def reduce(self, y: list, ch: Chain, V: float, psi_rate: float) -> tuple[float, float]:
        """(G^T M_h G, G^T (M_h G' V + h)) at this state: the reduced mass and velocity term."""
        heading = np.array(y[2 : 2 + self.n])
        psi1 = y[2 + self.n]
        G, G_dot = self.constraint_matrix(heading, psi1, ch, psi_rate, V)
        Mh = self.mass_matrix(heading)
        h = self.velocity_forces(heading, G[2:] * V)
        return float(G @ Mh @ G), float(G @ (Mh @ G_dot * V + h))

    def resistance_projection(self, y: list, ch: Chain) -> np.ndarray:
        """G^T J_Bk^T e_k for each cart: the generalized-force coefficient of a unit force at B_k
        along e_k. Equals kapB_k (the structural matrix W_P of algorithm 2)."""
        heading = np.array(y[2 : 2 + self.n])
        psi1 = y[2 + self.n]
        G, _ = self.constraint_matrix(heading, psi1, ch, 0.0, 0.0)
        out = np.empty(self.n)
        for k in range(self.n):
            e_k = np.array([math.cos(heading[k]), math.sin(heading[k])])
            out[k] = G @ (self.point_jacobian(self.DB[k], heading).T @ e_k)
        return out

    def grade_resistance(self, y: list, ch: Chain, gravity_x: float, gravity_y: float) -> list:
        """Each cart's grade resistance referred to V, N, by this algorithm's road: -G^T J_Ck^T
        m_k g_p, gravity's component g_p = (gravity_x, gravity_y) in the plane acting at C_k (the
        generalized force of a holonomic system, reduced by G). Algorithm 2 has it from the chain's
        factors (``kernel.grade_resistance``); the tests hold the two equal to round-off."""
        heading = np.array(y[2 : 2 + self.n])
        G, _ = self.constraint_matrix(heading, y[2 + self.n], ch, 0.0, 0.0)
        g = np.array([gravity_x, gravity_y])
        return [-float(G @ (self.point_jacobian(self.DC[k], heading).T @ (self.m[k] * g))) for k in range(self.n)]

    def gravity_force(self, heading: np.ndarray, gravity_x: float, gravity_y: float) -> np.ndarray:
        """Q_h of gravity's component g_p in the plane: sum_k J_Ck^T m_k g_p (n + 2; zero on the level)."""
        g = np.array([gravity_x, gravity_y])
        Q = np.zeros(self.n + 2)
        for k in range(self.n):
            Q += self.point_jacobian(self.DC[k], heading).T @ (self.m[k] * g)
        return Q
