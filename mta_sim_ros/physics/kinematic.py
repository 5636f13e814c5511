"""The kinematic level: the speed is prescribed, the forces follow by inverse dynamics.

With V(t) given, the no-side-slip chain alone moves the train (MODEL.md [12]-[16]):

    q' = G(q, psi_1) V(t),   psi_1' = actuator(command, psi_1)

and nothing about forces enters the integration: one chain walk per right-hand side instead
of the chain plus mass, velocity term and force laws. The traction F_A1 and its power are
read off afterwards from the equation of motion solved for the force (inverse dynamics):

    F_A1 = M V' + 1/2 M' V + sum_k F_Bk kapB_k          (M V' = Q - 1/2 M' V, Q = F_A1 - sum F_Bk kapB_k)

so the power balance F_A1 V - sum F_Bk s'_Bk = dT/dt holds by construction.

V(t): the speed set-point is a held input, like the steering command, and the prescribed speed
reaches it at the end of each tick: V is piecewise linear between the set-points sampled at the
ticks (a first-order hold, one tick behind the command). A step in the set-point is thus a ramp
over one tick, and the traction it asks for (M dV / tick) is what the inverse dynamics reports;
the traction law's limits (max_force, max_power) are not applied: the speed is prescribed.

State: the dynamic level's layout (``dynamics.StateLayout``), so outputs, guards, bags and replay
serve both. The speed slot holds V (integrated exactly: V' is constant over a tick) and the
governor slot holds V', the slope of the current tick's ramp (not integrated: z' = 0).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import kernel
from .chain import ChainGeometry, chain
from .dynamics import Model, StateLayout, Terms
from .outputs import Outputs, kernel_outputs, reference_outputs
from .spec import SPEED_LAWS, Traction, Train


class KinematicModel:
    """The kinematic level (levels.Level): q' = G V(t) with V(t) prescribed; Terms (traction,
    resistance, mass) by inverse dynamics."""

    name = "kinematic"

    def __init__(self, train: Train, algorithm: int = 2):
        if train.traction.law not in SPEED_LAWS:
            raise ValueError(
                f"fidelity kinematic: traction law {train.traction.law!r} of train '{train.name}' does not "
                f"command a speed; the kinematic level needs one of {', '.join(SPEED_LAWS)}")
        self.train = train
        self.algorithm = algorithm
        self.layout = StateLayout(train.n)
        self.P = kernel.pack(train, law="kinematic")  # the kernels' y' of this level: the chain only
        self.geom = ChainGeometry.of(self.P)
        self.dynamic = Model(train, algorithm=algorithm)  # the same train with its own traction law
        # The same equations with the prescribed-speed law: its traction is the inverse dynamics
        # F_A1 = M V' + R + sum F_Bk kapB_k for V' = (v_set - V) / response_time, response_time = 1 s.
        inverse = dataclasses.replace(train, traction=Traction("prescribed_speed", response_time=1.0))
        self._inverse = Model(inverse, algorithm=algorithm)
        self.P_outputs = self._inverse.P  # outputs_of(P_outputs, y, command, V + V') = this level's outputs
        self.has_kernel = algorithm == 2  # algorithm 1 reports from the reference path

    def from_dynamic_state(self, y: np.ndarray) -> np.ndarray:
        """The kinematic state for a dynamic one: the same pose and speed, V' = 0."""
        y = np.array(y, dtype=float)
        y[self.layout.governor] = 0.0
        return y

    def begin_tick(self, y: np.ndarray, v_set: float, tick: float) -> np.ndarray:
        """The state at the start of a tick that ends at speed v_set: V' = (v_set - V) / tick."""
        y = np.array(y, dtype=float)
        y[self.layout.governor] = (v_set - y[self.layout.speed]) / tick
        return y

    def rhs(self, t: float, y, command: float, v_set: float, max_rate: float | None = None) -> np.ndarray:
        """y' = (G V, psi_1', V', 0): the chain only, no forces (``kernel.rhs`` with law kinematic;
        ``reference_rhs`` is the same from chain.py)."""
        return kernel.rhs_of(self.P, np.asarray(y, dtype=np.float64), float(command), float(v_set),
                             kernel.max_rate_of(self.P, max_rate))

    def reference_rhs(self, t: float, y, command: float, v_set: float, max_rate: float | None = None) -> np.ndarray:
        """``rhs`` from the readable chain (chain.py)."""
        L = self.layout
        yl = y.tolist() if isinstance(y, np.ndarray) else list(y)
        psi1, V, accel = yl[L.steering], yl[L.speed], yl[L.governor]
        psi_rate = kernel.steering_rate(self.P, psi1, command, kernel.max_rate_of(self.P, max_rate), kernel.NATURAL)
        ch = chain(self.geom, yl[2: 2 + L.n], psi1, V, psi_rate)
        course = yl[2] + psi1
        dy = [V * math.cos(course), V * math.sin(course)]
        dy.extend(kt * V for kt in ch.kapT)
        dy.extend((psi_rate, accel, 0.0))
        return np.array(dy)

    def output_input(self, y, v_set: float) -> float:
        """The set-point under which ``P_outputs`` (prescribed speed, 1 s lag) has V' = the ramp slope."""
        return float(y[self.layout.speed]) + float(y[self.layout.governor])

    def terms(self, y, command: float, v_set: float, max_rate: float | None = None) -> Terms:
        """Inverse dynamics at y: the traction that gives the prescribed V' (the held v_set is not
        used: the ramp slope in the state is the acceleration)."""
        L = self.layout
        V, accel = float(y[L.speed]), float(y[L.governor])
        tm = self._inverse.terms(y, command, V + accel, max_rate)  # V' = (V + accel - V) / 1 s = accel
        tm.acceleration, tm.governor_rate = accel, 0.0
        return tm

    def derivative(self, y, command: float, v_set: float, max_rate: float | None = None):
        return self.rhs(0.0, y, command, v_set, max_rate), self.terms(y, command, v_set, max_rate)

    def outputs(self, t: float, y, command: float, v_set: float, max_rate: float | None = None,
                compiled: bool = True) -> Outputs:
        """What the simulator reports: the inverse dynamics of ``P_outputs`` at the ramp's V'
        (``output_input``), through the kernel (algorithm 2) or the reference path (algorithm 1)."""
        if not self.has_kernel:
            return reference_outputs(self, t, y, command, v_set, max_rate)
        return kernel_outputs(self.P_outputs, t, y, command, v_set, kernel.max_rate_of(self.P, max_rate),
                              law_input=self.output_input(y, v_set), compiled=compiled)

    def kinetic_energy(self, y, command: float = 0.0, v_set: float = 0.0) -> float:
        tm = self.terms(y, command, v_set)
        V = float(y[self.layout.speed])
        return 0.5 * tm.mass * V * V
