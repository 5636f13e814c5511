"""The train's linear model about straight motion or a steady turn (``mta linearize``). No ROS.

The states are the steering-relevant ones, at the speed V the speed control holds:

    straight  y   lateral offset of the tractor's steered axle A_1 from the line th = 0, m
              th  the tractor's heading th_1, rad
    turn      rho radial offset of A_1 from its steady circle (radius R_A1), m
              eta the tractor's heading against the circle's tangent at A_1, rad (minus its
                  steady value)
    both      phi_k = th_{k-1} - th_k, each hitch angle (k = 2..n), rad
              psi the steering angle psi_1, rad

input u, the steering command (rad). The equations are the model's own (``chain.chain``, the
readable reference of the kinematic chain, run on sympy symbols: one source):

    straight  y' = V sin(th + psi)                      turn  rho' = V cos(eta + psi)
              th' = kapT_1 V                                  eta' = kapT_1 V - V sin(eta + psi) / (R_A1 + rho)
    both      phi_k' = (kapT_{k-1} - kapT_k) V,  psi' = (u - psi) / tau  (the actuator off its rate limit)

(turn: A_1 in polar coordinates about the turn's centre, eta measured from the radius, so that
eta + psi = +-pi/2 on the circle). A = df/dx and B = df/du are the exact derivatives of these
expressions (sympy), at the operating point: straight, everything 0; a turn of steering psi_0,
the steady circle of ``steady.steady_circle``. The speed V is a parameter: on a straight line on
the level its coupling to these states vanishes exactly (V' depends on them only through even
functions, cos psi_k and squares), in a turn it is left out (the speed control holds V). On a
scene's tilted plane V' depends on the heading at first order (the grade resistances F_gk change as
the train turns up or down the slope), left out in the same way; the no-slip chain itself does not
see gravity, so A and B on any plane are the level's.

Closed forms (MODEL.md): straight, the hitch modes are -V / l_k (k = 2..n: decaying forward,
growing in reverse), the heading and the lateral offset are neutral (0, 0), the actuator -1 / tau;
n = 1 is the kinematic bicycle, th' = V sin(psi) / l_1.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..physics.chain import ChainGeometry, chain
from ..physics.steady import steady_circle


@dataclass
class LinearModel:
    """x' = A x + B u about an operating point; ``modes`` says what each eigenvalue is."""

    about: str  # "straight" or "turn"
    speed: float  # V, m/s
    steering: float  # psi_0, rad (0 on a straight line)
    states: list  # names of x
    units: list
    A: np.ndarray
    B: np.ndarray
    point: np.ndarray  # the operating point's x (its y or rho, th or eta, hitch angles, psi)
    eigenvalues: np.ndarray
    modes: list  # per eigenvalue: the state it moves most, and what that means

    def as_dict(self) -> dict:
        return {"about": self.about, "speed_m_s": self.speed, "steering_rad": self.steering, "states": self.states,
                "units": self.units, "A": self.A.tolist(), "B": self.B.ravel().tolist(),
                "operating_point": self.point.tolist(),
                "eigenvalues": [{"real": float(e.real), "imag": float(e.imag), "mode": m}
                                for e, m in zip(self.eigenvalues, self.modes)]}


def symbolic(n: int, about: str):
    """(x symbols, u, parameters, f(x, u)) of a train of n carts: the equations of the module
    docstring, from ``chain.chain`` on symbols. Parameters: V, tau, R (the turn's R_A1), and per
    cart l_k, lam_k = a_k / l_k, mu_k = c_k / l_k."""
    import sympy as sp

    V, tau, R = sp.symbols("V tau R_A1")
    l = sp.symbols(f"l1:{n + 1}", positive=True)
    lam = sp.symbols(f"lam1:{n + 1}")
    mu = sp.symbols(f"mu1:{n + 1}")
    u = sp.Symbol("u")
    first, second = sp.symbols("rho eta") if about == "turn" else sp.symbols("y th")
    phi = sp.symbols(f"phi2:{n + 1}")
    psi = sp.Symbol("psi")
    x = [first, second, *phi, psi]
    f = equations(x, u, V, tau, R, ChainGeometry(tuple(l), tuple(lam), tuple(mu)), about, sp)
    return x, u, (V, tau, R, l, lam, mu), f


def equations(x, u, V, tau, R, geom: ChainGeometry, about: str, fn) -> list:
    """f(x, u) of the module docstring, from ``chain.chain`` with ``fn``'s sin, cos, sqrt and atan2:
    sympy's on symbols (``symbolic``), or ``Dual``'s on numbers with their derivatives."""
    first, second, *phi, psi = x
    heading = [second * 0 if about == "turn" else second]  # turn: th_1 = 0 (sympy's 0, or a Dual 0)
    for p in phi:
        heading.append(heading[-1] - p)
    ch = chain(geom, heading, psi, V, 0, fn=fn)
    rates = [kt * V for kt in ch.kapT]
    if about == "turn":
        f = [V * fn.cos(second + psi), rates[0] - V * fn.sin(second + psi) / (R + first)]
    else:
        f = [V * fn.sin(second + psi), rates[0]]
    f += [rates[k - 1] - rates[k] for k in range(1, len(geom.length))]
    f.append((u - psi) / tau)
    return f


class Dual:
    """A number and its gradient, v + d . eps (forward-mode differentiation): what ``chain``
    computes on these is its value and its exact derivatives, to round-off, without sympy."""

    __slots__ = ("v", "d")

    def __init__(self, v: float, d: np.ndarray):
        self.v, self.d = float(v), d

    @staticmethod
    def of(a) -> "Dual":
        return a if isinstance(a, Dual) else Dual(a, 0.0)

    def __add__(self, o):
        o = Dual.of(o)
        return Dual(self.v + o.v, self.d + o.d)

    __radd__ = __add__

    def __sub__(self, o):
        o = Dual.of(o)
        return Dual(self.v - o.v, self.d - o.d)

    def __rsub__(self, o):
        return Dual.of(o) - self

    def __neg__(self):
        return Dual(-self.v, -self.d)

    def __mul__(self, o):
        o = Dual.of(o)
        return Dual(self.v * o.v, self.d * o.v + self.v * o.d)

    __rmul__ = __mul__

    def __truediv__(self, o):
        o = Dual.of(o)
        return Dual(self.v / o.v, (self.d * o.v - self.v * o.d) / (o.v * o.v))

    def __rtruediv__(self, o):
        return Dual.of(o) / self

    # the functions ``chain`` takes from its ``fn``
    @staticmethod
    def sin(a):
        a = Dual.of(a)
        return Dual(math.sin(a.v), math.cos(a.v) * a.d)

    @staticmethod
    def cos(a):
        a = Dual.of(a)
        return Dual(math.cos(a.v), -math.sin(a.v) * a.d)

    @staticmethod
    def sqrt(a):
        a = Dual.of(a)
        root = math.sqrt(a.v)
        return Dual(root, a.d / (2.0 * root))

    @staticmethod
    def atan2(a, b):
        a, b = Dual.of(a), Dual.of(b)
        return Dual(math.atan2(a.v, b.v), (b.v * a.d - a.v * b.d) / (a.v * a.v + b.v * b.v))


def linearize(train, about: str = "straight", speed: float = 3.0, steering: float = 0.0,
              exact: str = "dual") -> LinearModel:
    """The linear model of ``train`` about straight motion at ``speed`` (forward or reversing)
    or about the steady turn of ``steering`` (module docstring). ``exact``: how A and B are
    differentiated, both exact: "dual" (forward-mode on numbers through ``chain``: no sympy, a few
    ms for 20 carts) or "sympy" (the Jacobian of the symbolic equations: the independent check of
    the dual numbers, test_linear; its expressions double with each cart, 4 s for 4 carts, minutes
    for 7)."""
    n = train.n
    geom = ChainGeometry.of(train)
    tau = train.actuator.time_constant
    R = 1.0  # not in the straight equations
    if about == "turn":
        circle = steady_circle(train, steering)
        R = circle.R_A[0]
        side = math.copysign(math.pi / 2, steering)
        point = [0.0, side - steering, *circle.hitch_angles, steering]
    else:
        point = [0.0] * (n + 2)
    if exact == "dual":
        A, B = _jacobians_dual(point, steering, speed, tau, R, geom, about)
    else:
        A, B = _jacobians_sympy(n, point, steering, speed, tau, R, geom, about)
    eig, vectors = np.linalg.eig(A)
    order = np.lexsort((eig.imag, eig.real))
    eig, vectors = eig[order], vectors[:, order]
    names = ["rho", "eta"] if about == "turn" else ["y", "th"]
    names += [f"phi{k}" for k in range(2, n + 1)] + ["psi"]
    units = ["m", "rad"] + ["rad"] * (n - 1) + ["rad"]
    modes = [_meaning(names, A, vectors[:, i], eig[i]) for i in range(len(eig))]
    return LinearModel(about, speed, steering, names, units, A, B, np.array(point), eig, modes)


def _jacobians_sympy(n, point, steering, speed, tau_value, R_value, geom, about):
    import sympy as sp

    x, u, (V, tau, R, l, lam, mu), f = symbolic(n, about)
    values = {V: speed, tau: tau_value, R: R_value}
    values.update(zip(l, geom.length))
    values.update(zip(lam, geom.lam))
    values.update(zip(mu, geom.mu))
    at = dict(zip(x, point))
    at[u] = steering
    F = sp.Matrix(f)
    A = np.array(F.jacobian(x).subs(values).subs(at).evalf(), dtype=float)
    B = np.array(F.jacobian([u]).subs(values).subs(at).evalf(), dtype=float)
    return A, B


def _jacobians_dual(point, steering, speed, tau, R, geom, about):
    size = len(point)
    seeds = np.eye(size + 1)  # d/dx_0 .. d/dx_{size-1}, d/du
    x = [Dual(v, seeds[i]) for i, v in enumerate(point)]
    f = equations(x, Dual(steering, seeds[size]), speed, tau, R, geom, about, Dual)
    J = np.array([Dual.of(fi).d * np.ones(size + 1) for fi in f])
    return J[:, :size], J[:, size:]


def _meaning(names: list, A: np.ndarray, vector: np.ndarray, value: complex) -> str:
    """What an eigenvalue is: the state whose diagonal entry of A it is (the hitch block is
    triangular: each hitch's mode is its own row's), else the state its eigenvector moves most."""
    diagonal = [i for i in range(len(names)) if abs(A[i, i] - value) < 1e-9 * max(1.0, abs(value))]
    k = diagonal[-1] if diagonal and abs(value) > 1e-12 else int(np.argmax(np.abs(vector)))
    name = names[k]
    if abs(value.real) < 1e-12 and abs(value.imag) > 1e-12:
        return ("rho, eta: the circle's centre shifted, an orbit at the turn's rate Omega = V / R_A1 "
                "(neither restored nor growing)")
    if abs(value) < 1e-12:
        return f"{names[0]}, {names[1]}: neutral (0: the tractor's offset and heading are not restored)"
    if name == "psi":
        return "psi: the steering actuator's lag (-1/tau)"
    if name.startswith("phi"):
        trend = "decays" if value.real < 0 else "grows (the hitch folds: unstable)"
        return f"{name}: hitch {name[3:]}'s mode, {trend}"
    return f"{name}: {'stable' if value.real < 0 else 'unstable'}"


def point_row(train, cart: int, offset: float = 0.0) -> np.ndarray:
    """C with C x = the lateral offset (y, left of straight motion along +x) of the point ``offset``
    m ahead of cart ``cart``'s axle B_k on its axis (k counted from 0), to first order in the
    straight model's x = (y, th_1, phi_2..phi_n, psi): y_P = y - sum over the segments from A_1 back
    to B_k of their length times their heading (A_j to B_j, then B_j to A_{j+1}) + offset th_k, with
    th_k = th_1 - phi_2 - ... - phi_k."""
    row = np.zeros(train.n + 2)
    row[0] = 1.0
    for k in range(cart + 1):
        c = train.carts[k]
        length = c.length - offset if k == cart else c.length + c.hitch_offset  # times -th_k
        row += length * heading_row(train, k) * -1.0
    return row


def heading_row(train, cart: int) -> np.ndarray:
    """D with D x = th_k, the heading of cart ``cart`` (from 0): th_1 - phi_2 - ... - phi_k."""
    row = np.zeros(train.n + 2)
    row[1] = 1.0
    row[2:cart + 2] = -1.0
    return row


def turn_closed_form(train, speed: float, steering: float) -> list[complex]:
    """The eigenvalues about the steady turn of ``steering`` (either side): the hitch modes
    -Omega R_Bk / l_k (an axle's speed over its cart's length; k = 2..n), the orbit +-i |Omega| of
    a shifted centre, Omega = V / R_A1 the turn's rate (its sign the speed's), and the actuator's
    -1 / tau."""
    circle = steady_circle(train, steering)
    omega = speed / circle.R_A[0]  # the yaw rate's size; the hitch modes' sign is the speed's
    hitches = [-omega * circle.R_B[k] / train.carts[k].length for k in range(1, train.n)]
    return [complex(v) for v in sorted(hitches)] + [complex(0, -abs(omega)), complex(0, abs(omega)),
                                                    complex(-1.0 / train.actuator.time_constant)]


def straight_closed_form(train, speed: float) -> list[float]:
    """MODEL.md's eigenvalues about straight motion: 0, 0, -V / l_k (k = 2..n), -1 / tau."""
    return sorted([0.0, 0.0, *(-speed / c.length for c in train.carts[1:]), -1.0 / train.actuator.time_constant])


def markdown(model: LinearModel, train) -> str:
    """The model as Markdown: the operating point, A and B, the eigenvalues with their meaning."""
    head = (f"# Linear model of {train.name} about "
            + (f"straight motion at V = {model.speed:g} m/s" if model.about == "straight" else
               f"the steady turn of psi_1 = {model.steering:g} rad at V = {model.speed:g} m/s"))
    lines = [head, "", "x' = A x + B u, u the steering command (rad); states (units): "
             + ", ".join(f"{s} ({u})" for s, u in zip(model.states, model.units)) + ".", "",
             "Operating point: " + ", ".join(f"{s} = {v:.6g}" for s, v in zip(model.states, model.point)), "",
             "| A | " + " | ".join(model.states) + " | B |", "|---|" + "---:|" * (len(model.states) + 1)]
    for i, s in enumerate(model.states):
        lines.append(f"| {s}' | " + " | ".join(f"{v:.6g}" for v in model.A[i]) + f" | {model.B[i, 0]:.6g} |")
    lines += ["", "| eigenvalue, 1/s | mode |", "|---:|---|"]
    for e, m in zip(model.eigenvalues, model.modes):
        value = f"{e.real:.6g}" if abs(e.imag) < 1e-12 else f"{e.real:.6g} {e.imag:+.6g}i"
        lines.append(f"| {value} | {m} |")
    if model.about == "straight":
        lines += ["", "Closed form (MODEL.md): " + ", ".join(f"{v:.6g}" for v in straight_closed_form(train, model.speed))]
    return "\n".join(lines) + "\n"
