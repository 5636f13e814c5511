"""The slip level: lateral tyre compliance in place of the no-side-slip constraints.

The carts are planar rigid bodies joined by hitch pins (holonomic), so the coordinates are the
same q = (x_A1, y_A1, th_1..th_n) as the article's, but the rolling constraints are dropped:
all n + 2 velocities u = q' are states, and every axle pushes back on its own side slip with a
linear tyre (cornering stiffness C_alpha, N/rad):

    axle at P with rolling direction d (steered at A_1: th_1 + psi_1; e_k at B_k), normal n:
        slip angle  alpha = atan(v_P.n / sqrt((v_P.d)^2 + v0^2)),   F_lat = -C_alpha alpha  along n

The longitudinal elements are the dynamic level's: traction F_A1 along the steered wheels at A_1
(the same laws; the governor acts on V = v_A1.d, the speed of A_1 along its wheels) and rolling
resistance and draft at B_k against v_Bk.e_k (forces.py). The equations of motion are the
holonomic ones of ``holonomic.py``, M_h(q) u' + h(q, u) = Q_h, with
Q_h = sum over point forces of J_P^T F_P (J_P = dP/dq, P = A_1 + sum_j D_j e_j).

v0 (the train's smoothing_speed) keeps alpha finite at standstill. It does not remove the
stiffness: the lateral damping of an axle is C_alpha / sqrt(V^2 + v0^2), so the eigenvalues grow
like C_alpha / (m V) as V -> 0 (and like C_alpha as C_alpha grows): see docs/fidelity.md for the
measurement and the method that survives it (``DEFAULT_METHOD``).

As C_alpha -> infinity the side slips vanish like 1/C_alpha and the motion tends to the
nonholonomic (dynamic) level's.

State (``SlipLayout``): x_A1, y_A1, th_1..th_n, psi_1, u = (x'_A1, y'_A1, th'_1..th'_n), z.
Positions, headings and steering sit where the dynamic level keeps them, so the guards and the
geometry read both.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import kernel
from .chain import ChainGeometry, chain
from .dynamics import Model, PoseLayout
from .geometry import cart_points, hitch_angles
from .holonomic import HolonomicReduction
from .outputs import Outputs
from .spec import Train
from .terrain import PlaneFrame

# Normalised cornering stiffness C_alpha / F_z of an agricultural tyre on soil, per rad. An
# assumption, not a measurement and not taken from a checked source: road car tyres give
# ~15-20 /rad on asphalt, and large, soft tractor tyres on deformable soil are stiff several times
# less (the off-road tyre literature, e.g. the Journal of Terramechanics, treats this; we have not
# fitted a value to it). 5 /rad is taken as a mid value; give ``cornering_stiffness`` per cart for
# a measured one. docs/fidelity.md shows how the levels' errors scale with it (~1/C).
CORNERING_COEFFICIENT = 5.0

# The method the slip level uses unless one is forced. The tyres are stiff at low speed: the
# largest eigenvalue is ~16 1/s at 3 m/s, ~410 at 0.1 m/s, ~920 at standstill (default train), so
# RK4 at 0.01 s (stable for |lambda| < 278 1/s) chatters below ~0.3 m/s: at 0.1 m/s its poses are
# off by 7 cm after 3 s (bounded only because atan saturates). LSODA switches to BDF where the
# problem is stiff; it was the cheapest method that kept the error < 1e-6 m at 0.1 and 3 m/s
# (docs/fidelity.md, ``python -m benchmarks fidelity``).
DEFAULT_METHOD = "LSODA"
DEFAULT_RTOL = 1e-6
DEFAULT_ATOL = 1e-6


def axle_stiffness(train: Train) -> tuple[float, np.ndarray]:
    """(C_alpha of the tractor's front axle at A_1, C_alpha of each cart's axle at B_k), N/rad.

    A cart's ``cornering_stiffness`` if given (the tractor's front and rear axles both take it),
    else CORNERING_COEFFICIENT times the static axle load: the tractor's weight split between its
    axles by the position of its centre of mass (front share c_1 / l_1), a trailer's weight
    carried by its axle and its hitch in the same way (axle share 1 - c_k / l_k). Hitch loads
    passed on to the cart in front are neglected. On a tilted plane the load is the normal one,
    m g cos(slope)."""
    g = train.gravity
    if train.terrain is not None:
        g *= PlaneFrame.of(train.terrain).z[2]
    rear = []
    front = 0.0
    for k, cart in enumerate(train.carts):
        share = min(max(cart.com_offset / cart.length, 0.05), 0.95)  # front (hitch) share of the weight
        if cart.cornering_stiffness is not None:
            rear.append(cart.cornering_stiffness)
            if k == 0:
                front = cart.cornering_stiffness
            continue
        rear.append(CORNERING_COEFFICIENT * cart.mass * g * (1.0 - share))
        if k == 0:
            front = CORNERING_COEFFICIENT * cart.mass * g * share
    return front, np.array(rear)


@dataclass(frozen=True)
class SlipLayout(PoseLayout):
    """Indices into the slip level's state vector for n carts: the pose, then the velocities u
    and the governor's integral."""

    @property
    def velocity(self) -> slice:
        """u = q' = (x'_A1, y'_A1, th'_1..th'_n)."""
        return slice(3 + self.n, 5 + 2 * self.n)

    @property
    def governor(self) -> int:
        return 5 + 2 * self.n

    @property
    def size(self) -> int:
        return 6 + 2 * self.n


@dataclass
class SlipTerms:
    """Everything the slip equations produce at one state and input (SI units)."""

    speed: float  # V = v_A1 . d, m/s (d: direction of the steered front wheels)
    steering_rate: float  # psi_1', rad/s
    accel: np.ndarray  # u', n + 2
    governor_rate: float  # z', N/s
    traction: float  # F_A1, N, along d
    resistance: np.ndarray  # F_Bk, N, > 0 opposes v_Bk . e_k
    axle_speed: np.ndarray  # v_Bk . e_k, m/s
    front_slip: float  # alpha at A_1, rad
    slip: np.ndarray  # alpha at each B_k, rad
    front_lateral: float  # N, along the wheels' normal
    lateral: np.ndarray  # N, along n_k at B_k
    mass_matrix: np.ndarray  # M_h


class SlipModel:
    """Planar carts joined by pins, linear tyres at every axle; traction and resistance laws as
    in the dynamic level."""

    name = "slip"
    has_kernel = False  # its own Python right-hand side and outputs

    def __init__(self, train: Train, algorithm: int = 2):
        self.train = train
        self.algorithm = algorithm
        self.layout = SlipLayout(train.n)
        self.geom = ChainGeometry.of(train)  # for the guards (jackknife margin)
        self.dynamic = Model(train, algorithm=algorithm)
        self.P = self.P_outputs = self.dynamic.P  # the train's constants: laws, actuator, guards
        self._hol = HolonomicReduction(train)
        DB = self._hol.DB
        self._DB = DB
        self._DC = self._hol.DC
        DA = DB.copy()  # A_k (k >= 2) = B_{k-1} - a_{k-1} e_{k-1}: the row of B_k without its own e_k
        np.fill_diagonal(DA, 0.0)
        self._DA = DA
        self.front_stiffness, self.stiffness = axle_stiffness(train)
        self.train_masses = self._hol.m
        self._gravity = np.array([self.P[kernel.H.gravity_x], self.P[kernel.H.gravity_y]])

    # -- conversion from the no-slip state ----------------------------------------------------
    def from_dynamic_state(self, y: np.ndarray) -> np.ndarray:
        """The slip state moving as the dynamic state does (no side slip yet): u = G V."""
        n = self.train.n
        Ld = self.dynamic.layout
        L = self.layout
        heading = [float(v) for v in y[Ld.heading]]
        psi1, V = float(y[Ld.steering]), float(y[Ld.speed])
        ch = chain(self.geom, heading, psi1, V, 0.0)
        out = np.zeros(L.size)
        out[: n + 3] = y[: n + 3]  # x, y, headings, psi_1
        course = heading[0] + psi1
        out[L.velocity] = [V * math.cos(course), V * math.sin(course)] + [kt * V for kt in ch.kapT]
        out[L.governor] = y[Ld.governor]
        return out

    def begin_tick(self, y, v_set: float, tick: float):
        return y

    def output_input(self, y, v_set: float) -> float:
        return v_set

    # -- the equations -------------------------------------------------------------------------
    def _generalized(self, front_force: np.ndarray, forces_B: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """Q_h = J_A1^T F_A + sum_k J_Bk^T F_Bk, with J_P^T F = (F, D_j n_j.F for each j)."""
        n = self.train.n
        Q = np.empty(n + 2)
        Q[:2] = front_force + forces_B.sum(axis=0)
        weighted = self._DB.T @ forces_B  # row j: sum_k DB_kj F_Bk
        Q[2:] = np.einsum("ij,ij->i", normals, weighted)
        return Q

    def terms(self, y, command: float, v_set: float, max_rate: float | None = None) -> SlipTerms:
        L = self.layout
        n = L.n
        tr = self.train
        y = np.asarray(y, dtype=float)
        heading = y[L.heading]
        psi1 = float(y[L.steering])
        u = y[L.velocity]
        z = float(y[L.governor])
        w = u[2:]
        cos_h, sin_h = np.cos(heading), np.sin(heading)
        E = np.stack((cos_h, sin_h), axis=1)
        N = np.stack((-sin_h, cos_h), axis=1)
        vA = u[:2]
        vB = vA + self._DB @ (w[:, None] * N)
        v_long = np.einsum("ij,ij->i", vB, E)
        v_lat = np.einsum("ij,ij->i", vB, N)
        course = float(heading[0]) + psi1
        d = np.array([math.cos(course), math.sin(course)])
        nd = np.array([-d[1], d[0]])
        V = float(vA @ d)
        v_lat_front = float(vA @ nd)
        v0 = tr.smoothing_speed

        front_slip = math.atan(v_lat_front / math.hypot(V, v0))
        slip = np.arctan(v_lat / np.hypot(v_long, v0))
        front_lateral = -self.front_stiffness * front_slip
        lateral = -self.stiffness * slip
        P = self.P
        resistance = np.array([kernel.resistance(P, k, vl, kernel.NATURAL) for k, vl in enumerate(v_long.tolist())])
        forces_B = -resistance[:, None] * E + lateral[:, None] * N
        Q = self._generalized(front_lateral * nd, forces_B, N)
        if P[kernel.H.slope]:  # gravity's component in the plane, at each C_k
            Q = Q + self._hol.gravity_force(heading, P[kernel.H.gravity_x], P[kernel.H.gravity_y])
        Mh = self._hol.mass_matrix(heading)
        h = self._hol.velocity_forces(heading, w)
        unit = np.zeros(n + 2)
        unit[:2] = d  # generalized force of a unit traction along d at A_1
        psi_rate = kernel.steering_rate(P, psi1, command, kernel.max_rate_of(P, max_rate), kernel.NATURAL)

        traction, target, governor_rate, prescribed = kernel.traction_law(P, V, v_set, z, kernel.no_mode())
        if prescribed:
            base, per_newton = np.linalg.solve(Mh, np.stack((Q - h, unit), axis=1)).T
            # V' = d.u'_xy + (v_A1.n_d) (th_1' + psi_1') must equal the prescribed acceleration
            course_rate = float(w[0]) + psi_rate
            traction = (target - float(d @ base[:2]) - v_lat_front * course_rate) / float(d @ per_newton[:2])
            accel = base + traction * per_newton
        else:
            accel = np.linalg.solve(Mh, Q + traction * unit - h)
        return SlipTerms(V, psi_rate, accel, governor_rate, traction, resistance, v_long, front_slip, slip,
                         front_lateral, lateral, Mh)

    def rhs(self, t: float, y, command: float, v_set: float, max_rate: float | None = None) -> np.ndarray:
        L = self.layout
        tm = self.terms(y, command, v_set, max_rate)
        dy = np.empty(L.size)
        dy[: L.n + 2] = y[L.velocity]
        dy[L.steering] = tm.steering_rate
        dy[L.velocity] = tm.accel
        dy[L.governor] = tm.governor_rate
        return dy

    def kinetic_energy(self, y, command: float = 0.0, v_set: float = 0.0) -> float:
        """T = 1/2 u^T M_h u, J."""
        u = np.asarray(y[self.layout.velocity], dtype=float)
        return 0.5 * float(u @ self._hol.mass_matrix(np.asarray(y[self.layout.heading], dtype=float)) @ u)

    # -- what the simulator reports ------------------------------------------------------------
    def point_velocities(self, y, D: np.ndarray) -> np.ndarray:
        """Velocities (n x 2) of the points A_1 + sum_j D_kj e_j."""
        L = self.layout
        heading = np.asarray(y[L.heading], dtype=float)
        u = np.asarray(y[L.velocity], dtype=float)
        N = np.stack((-np.sin(heading), np.cos(heading)), axis=1)
        return u[:2] + D @ (u[2:, None] * N)

    def outputs(self, t: float, y, command: float, v_set: float, max_rate: float | None = None,
                compiled: bool = True) -> Outputs:
        """The same Outputs as the other levels (``compiled`` does not apply: no kernel). psi_k
        (k >= 2) is the angle from e_k to the actual velocity of A_k; axle_speed is v_Bk . e_k, the
        speed the resistance acts on."""
        from .guards import jackknife_margin

        L = self.layout
        y = np.asarray(y, dtype=float)
        tm = self.terms(y, command, v_set, max_rate)
        heading = y[L.heading]
        pts = cart_points(self.train, float(y[L.x]), float(y[L.y]), heading)
        vA = self.point_velocities(y, self._DA)
        vC = self.point_velocities(y, self._DC)
        psi = np.arctan2(-np.sin(heading) * vA[:, 0] + np.cos(heading) * vA[:, 1],
                         np.cos(heading) * vA[:, 0] + np.sin(heading) * vA[:, 1])
        psi[0] = y[L.steering]
        return Outputs(
            t=t,
            front=pts["A"], axle=pts["B"], com=pts["C"], rear_hitch=pts["rear_hitch"],
            heading=np.array(heading, dtype=float),
            hitch_angle=np.array(hitch_angles(heading.tolist())),
            psi=psi,
            com_speed=np.hypot(vC[:, 0], vC[:, 1]),
            axle_speed=tm.axle_speed,
            yaw_rate=np.array(y[L.velocity][2:], dtype=float),
            speed=tm.speed,
            steering=float(y[L.steering]),
            steering_rate=tm.steering_rate,
            command=command,
            speed_setpoint=v_set,
            resistance=tm.resistance,
            traction=tm.traction,
            power=tm.traction * tm.speed,
            resistance_power=float(tm.resistance @ tm.axle_speed),
            grade_power=-float(np.sum(self.train_masses[:, None] * vC * self._gravity)),
            kinetic_energy=0.5 * float(y[L.velocity] @ tm.mass_matrix @ y[L.velocity]),
            jackknife_margin=jackknife_margin(self, y)[0],
        )


def no_slip_tyre_forces(model: SlipModel, y_dynamic, command: float, v_set: float) -> tuple[float, np.ndarray]:
    """The lateral tyre forces (N; front axle at A_1, then each B_k) that the no-slip (dynamic)
    level implies at its state ``y_dynamic``: the constraint forces of its rolling constraints.

    The slip level at the same pose and velocities (no slip yet, so no tyre forces) accelerates
    by u'_0; the no-slip motion by u'_ns = G V' + G' V. The difference is made by the constraint
    forces: M_h (u'_ns - u'_0) = sum_i lambda_i J_i^T n_i, n + 1 unknowns in n + 2 equations
    (consistent: solved by least squares). Divided by C_alpha, they are the slip angles a tyre
    of that stiffness would need: the error of the no-slip model, before it builds up."""
    dyn = model.dynamic
    Ld = dyn.layout
    y_dynamic = np.asarray(y_dynamic, dtype=float)
    tm = dyn.terms(y_dynamic, command, v_set)
    heading = y_dynamic[Ld.heading]
    V = float(y_dynamic[Ld.speed])
    G, G_dot = HolonomicReduction.constraint_matrix(heading, float(y_dynamic[Ld.steering]), tm.chain,
                                                    tm.steering_rate, V)
    accel_ns = G * tm.acceleration + G_dot * V
    ys = model.from_dynamic_state(y_dynamic)
    accel_0 = model.terms(ys, command, v_set).accel
    Mh = model._hol.mass_matrix(heading)
    n = model.train.n
    course = float(heading[0]) + float(y_dynamic[Ld.steering])
    N = np.stack((-np.sin(heading), np.cos(heading)), axis=1)
    columns = [np.concatenate(([-math.sin(course), math.cos(course)], np.zeros(n)))]
    for k in range(n):
        col = np.empty(n + 2)
        col[:2] = N[k]
        col[2:] = model._DB[k] * (N @ N[k])  # J_Bk^T n_k: D_kj n_j . n_k
        columns.append(col)
    B = np.stack(columns, axis=1)
    lam = np.linalg.lstsq(B, Mh @ (accel_ns - accel_0), rcond=None)[0]
    return float(lam[0]), lam[1:]
