"""The equations of motion in Cauchy form, assembled from the element lists (MODEL.md [3], [9]-[11]).

State y (``StateLayout``):  x_A1, y_A1, th_1..th_n, psi_1, V, z
    q = (x_A1, y_A1, th_1..th_n)   generalized coordinates (m, m, rad...)
    psi_1                          steering angle, a state of the actuator (rad)
    V                              pseudo-velocity: signed speed of A_1 (m/s)
    z                              integral state of the speed governor (N; constant 0 otherwise)
Input, held over a step: (steering command, rad; speed set-point, m/s).

    q'     = G(q, psi_1) V,  G = (cos(th_1 + psi_1), sin(th_1 + psi_1), kapT_1 .. kapT_n)
    psi_1' = actuator(command, psi_1)
    M V'   = F_A1 - sum_k F_Bk kapB_k - sum_k F_gk - R   (one pseudo-velocity: M is a scalar)

F_gk is cart k's grade resistance on a tilted plane (the train's terrain), -m_k g_p . v_Ck / V
with g_p gravity's component in the plane: 0 on the level.

with M and the velocity term R built by one of the article's two algorithms:
    algorithm 2 (default): direct differentiation by the pseudo-velocity,
        M = sum_k m_k kapC_k^2 + J_k kapT_k^2,   R = 1/2 M' V
    algorithm 1: the holonomic equations M_h q'' + h = Q_h of the n + 2 coordinates reduced by G,
        M = G^T M_h G,   R = G^T (M_h G' V + h)      (see ``holonomic.py``)
Both are exact; a test holds them equal to round-off.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import kernel
from .chain import Chain, ChainGeometry, chain
from .outputs import Outputs, kernel_outputs, reference_outputs
from .spec import Train


@dataclass(frozen=True)
class PoseLayout:
    """Where every level's state vector starts: x_A1, y_A1, th_1..th_n, psi_1 (n carts)."""

    n: int

    @property
    def x(self) -> int:
        return 0

    @property
    def y(self) -> int:
        return 1

    @property
    def heading(self) -> slice:
        return slice(2, 2 + self.n)

    @property
    def steering(self) -> int:
        return 2 + self.n


@dataclass(frozen=True)
class StateLayout(PoseLayout):
    """Indices into the state vector of a train with n carts: the pose, then V and the governor's
    integral."""

    @property
    def speed(self) -> int:
        return 3 + self.n

    @property
    def governor(self) -> int:
        return 4 + self.n

    @property
    def size(self) -> int:
        return 5 + self.n


@dataclass
class Terms:
    """Everything the equations produce at one state and input (SI units)."""

    chain: Chain
    mass: float  # M, kg: T = 1/2 M V^2
    velocity_term: float  # R, N
    resistance: list  # F_Bk per cart, N (signed: > 0 opposes forward motion of B_k)
    grade: list  # each cart's grade resistance referred to V, N (kernel.grade_resistance; 0 on the level)
    traction: float  # F_A1, N
    steering_rate: float  # psi_1', rad/s
    acceleration: float  # V', m/s^2
    governor_rate: float  # z', N/s

    @property
    def balance(self) -> float:
        """N: the traction that holds the speed (V' = 0), sum F_Bk kapB_k + 1/2 M' V + sum F_gk: what
        a governor's integral starts at (simulation.initial_state) and what a set speed needs
        (fidelity.unheld_speed)."""
        return resistance_force(self.resistance, self.chain.kapB) + self.velocity_term + sum(self.grade)


class Model:
    """The dynamic level (levels.Level): the equations of one train. Immutable after construction;
    the state is a numpy array."""

    name = "dynamic"

    def __init__(self, train: Train, algorithm: int = 2):
        if algorithm not in (1, 2):
            raise ValueError(f"algorithm: {algorithm} must be 1 (holonomic reduction) or 2 (direct)")
        self.train = train
        self.algorithm = algorithm
        self.layout = StateLayout(train.n)
        self.P = kernel.pack(train)  # the constants as the kernels read them
        self.P_outputs = self.P
        self.has_kernel = algorithm == 2
        self.dynamic = self
        self.geom = ChainGeometry.of(self.P)
        self.masses = kernel.column(self.P, "mass")
        self.inertias = kernel.column(self.P, "inertia")
        if algorithm == 1:
            from .holonomic import HolonomicReduction

            self._holonomic = HolonomicReduction(train)

    # -- the level's state and inputs (levels.Level) ----------------------------------------
    def from_dynamic_state(self, y) -> np.ndarray:
        return np.array(y, dtype=float)

    def begin_tick(self, y, v_set: float, tick: float):
        return y

    def output_input(self, y, v_set: float) -> float:
        return v_set

    # -- the equations ---------------------------------------------------------------------
    def terms(self, y, command: float, v_set: float, max_rate: float | None = None) -> Terms:
        """Evaluate the model at state y with the held input (command, v_set, max_rate; None: the
        actuator's own rate limit)."""
        L = self.layout
        n = L.n
        yl = y.tolist() if isinstance(y, np.ndarray) else list(y)
        heading = yl[2 : 2 + n]
        psi1, V, z = yl[L.steering], yl[L.speed], yl[L.governor]
        psi_rate = kernel.steering_rate(self.P, psi1, command, kernel.max_rate_of(self.P, max_rate), kernel.NATURAL)
        ch = chain(self.geom, heading, psi1, V, psi_rate)

        if self.algorithm == 2:
            mass, velocity_term = self._direct(ch, V)
        else:
            mass, velocity_term = self._holonomic.reduce(yl, ch, V, psi_rate)

        normal, grade = [1.0] * n, [0.0] * n
        if self.P[kernel.H.relief]:  # on a height grid: each cart's grade and normal load at its C_k
            grade, normal = self._relief_terms(yl, ch)
        resistance = [kernel.resistance(self.P, k, kb * V, kernel.NATURAL, normal[k]) for k, kb in enumerate(ch.kapB)]
        generalized_resistance = resistance_force(resistance, ch.kapB)
        if self.P[kernel.H.relief]:
            generalized_resistance = generalized_resistance + sum(grade)
        elif self.P[kernel.H.slope]:  # the grade resistances: algorithm 2 by the chain, 1 by G^T Q_h
            if self.algorithm == 2:
                grade = [kernel.grade_resistance(self.P, k, heading[k], kb, kt)
                         for k, (kb, kt) in enumerate(zip(ch.kapB, ch.kapT))]
            else:
                grade = self._holonomic.grade_resistance(yl, ch, self.P[kernel.H.gravity_x],
                                                         self.P[kernel.H.gravity_y])
            generalized_resistance = generalized_resistance + sum(grade)
        traction, acceleration, governor_rate, prescribed = kernel.traction_law(self.P, V, v_set, z, kernel.no_mode())
        if prescribed:
            traction = mass * acceleration + generalized_resistance + velocity_term  # inverse dynamics
        else:
            acceleration = cauchy_acceleration(traction, generalized_resistance, velocity_term, mass)
        return Terms(ch, mass, velocity_term, resistance, grade, traction, psi_rate, acceleration, governor_rate)

    def _relief_terms(self, yl: list, ch: Chain) -> tuple[list, list]:
        """(F_gk, cos of the local slope) of each cart on the height grid (kernel.relief_grade), its
        centre of mass placed from A_1 back (geometry.cart_points)."""
        from .geometry import cart_points

        n = self.layout.n
        centres = cart_points(self.train, yl[0], yl[1], yl[2 : 2 + n])["C"].tolist()
        pairs = [kernel.relief_grade(self.P, k, yl[2 + k], kb, kt, *centres[k])
                 for k, (kb, kt) in enumerate(zip(ch.kapB, ch.kapT))]
        return [p[0] for p in pairs], [p[1] for p in pairs]

    def _direct(self, ch: Chain, V: float) -> tuple[float, float]:
        """Algorithm 2 (``mass_terms``)."""
        return mass_terms(self.masses, self.inertias, ch, V)

    def derivative(self, y, command: float, v_set: float, max_rate: float | None = None) -> tuple[np.ndarray, Terms]:
        """y' and the terms it came from."""
        L = self.layout
        tm = self.terms(y, command, v_set, max_rate)
        V = float(y[L.speed])
        course = float(y[2]) + float(y[L.steering])  # direction of v_A1
        dy = [V * math.cos(course), V * math.sin(course)]
        dy.extend(kt * V for kt in tm.chain.kapT)
        dy.extend((tm.steering_rate, tm.acceleration, tm.governor_rate))
        return np.array(dy), tm

    def rhs(self, t: float, y, command: float, v_set: float, max_rate: float | None = None) -> np.ndarray:
        """The Cauchy form y' = f(t, y, input) with the input held (t does not enter).

        Algorithm 2: the kernel (``kernel.rhs``, compiled where numba runs), equal to
        ``derivative(y, ...)[0]`` to the last bit. Algorithm 1: ``derivative``."""
        if self.algorithm == 2:
            return kernel.rhs_of(self.P, np.asarray(y, dtype=np.float64), float(command), float(v_set),
                                 kernel.max_rate_of(self.P, max_rate))
        return self.derivative(y, command, v_set, max_rate)[0]

    def outputs(self, t: float, y, command: float, v_set: float, max_rate: float | None = None,
                compiled: bool = True) -> Outputs:
        """What the simulator reports at state y: through the kernel (algorithm 2; ``compiled`` =
        False: as plain Python), or from the reference path (algorithm 1)."""
        if not self.has_kernel:
            return reference_outputs(self, t, y, command, v_set, max_rate)
        return kernel_outputs(self.P_outputs, t, y, command, v_set, kernel.max_rate_of(self.P, max_rate),
                              compiled=compiled)

    # -- energy ----------------------------------------------------------------------------
    def kinetic_energy(self, y, command: float = 0.0, v_set: float = 0.0) -> float:
        """T = 1/2 M V^2, J."""
        tm = self.terms(y, command, v_set)
        V = float(y[self.layout.speed])
        return 0.5 * tm.mass * V * V

    def power_balance(self, y, command: float, v_set: float) -> tuple[float, float]:
        """(F_A1 V - sum F_Bk s'_Bk - sum F_gk V, dT/dt) at this state; the two are equal (MODEL.md;
        F_gk V = dU_k/dt, the rate of each cart's potential energy on a tilted plane)."""
        tm = self.terms(y, command, v_set)
        V = float(y[self.layout.speed])
        applied = tm.traction * V - sum(f * kb * V for f, kb in zip(tm.resistance, tm.chain.kapB)) \
            - sum(g * V for g in tm.grade)
        dT_dt = tm.mass * V * tm.acceleration + tm.velocity_term * V  # d/dt(1/2 M V^2) = M V V' + 1/2 M' V^2
        return applied, dT_dt


# -- the equations of algorithm 2, on numbers or on symbols (equations.py prints these) ----------------

def mass_terms(masses, inertias, ch: Chain, V):
    """Algorithm 2: (M, R) with M = sum m_k kapC_k^2 + J_k kapT_k^2 and R = 1/2 M' V, M' exact from
    the chain's rates: the inertial elements (m_k, s'_Ck) and (J_k, th'_k) of the article."""
    mass = 0.0
    mass_rate = 0.0
    for m, J, kc, kc_d, kt, kt_d in zip(masses, inertias, ch.kapC, ch.kapC_d, ch.kapT, ch.kapT_d):
        mass += m * kc * kc + J * kt * kt
        mass_rate += 2.0 * (m * kc * kc_d + J * kt * kt_d)
    return mass, 0.5 * mass_rate * V


def resistance_force(resistance, kapB):
    """sum_k F_Bk kapB_k: the resistances' share of the generalized force Q = F_A1 - sum F_Bk kapB_k
    (the force elements (F_Bk, s'_Bk))."""
    return sum(f * kb for f, kb in zip(resistance, kapB))


def cauchy_acceleration(traction, generalized_resistance, velocity_term, mass):
    """V' of the Cauchy form: M V' = F_A1 - sum F_Bk kapB_k - 1/2 M' V."""
    return (traction - generalized_resistance - velocity_term) / mass
