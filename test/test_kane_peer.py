"""An independent peer of the dynamics: the train built with sympy.physics.mechanics (Kane's method)
from rigid bodies, pin hitches and no-side-slip axles, its own code, none of the package's, and the
kernel's state derivative held to it on random states: 1 to 4 carts, hitches ahead of the axle
(a_k < 0), centres of mass beyond the axle (c_k < 0 or > l_k), both signs of the speed, steering
moving at its rate limit or not.

The peer's model (issue 14): coordinates x, y of the tractor's steered axle A_1 and each cart's
heading th_k; generalized speeds u_V (A_1's speed along its course th_1 + psi_1), u_s (A_1's speed
across it) and each yaw rate w_k. Nonholonomic constraints: u_s = 0 (the steered wheels do not slip
sideways) and v_Bk . n_k = 0 at every rear axle, which leaves u_V = V independent. The steering
angle psi_1(t) is a specified motion with the actuator's rate psi_1' (its own formula here). Loads:
the traction F_A1 along A_1's course (the constant law), the resistance at each B_k against its
axis, (f m g + ASABE draft) tanh(s'_Bk / v0). KanesMethod gives M u' = f over every speed (the dynamic equation of
u_V and the dependent speeds' acceleration constraints); its u_V' is compared with the kernel's
y'[V], and the other derivatives with their kinematic meaning.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from mta_sim_ros.physics import kernel, loader

GRAVITY = 9.80665
KMH = 3.6


def kane_model(n: int):
    """The symbolic train of n carts: (a function (params, state, psi, psi_rate) -> V', the symbols).

    Lengths l_k, hitch offsets a_k (B_k back to A_{k+1}), com offsets c_k (B_k forward to C_k),
    masses m_k, yaw inertias J_k, the traction F and the resistances R_k(s'_Bk) as symbols of a
    numeric evaluation (lambdify)."""
    t = me.dynamicsymbols._t
    x, y = me.dynamicsymbols("x y")
    th = me.dynamicsymbols(f"th1:{n + 1}")
    psi = me.dynamicsymbols("psi")
    uV, us = me.dynamicsymbols("uV us")
    w = me.dynamicsymbols(f"w1:{n + 1}")
    l = sp.symbols(f"l1:{n + 1}")
    a = sp.symbols(f"a1:{n + 1}")
    c = sp.symbols(f"c1:{n + 1}")
    m = sp.symbols(f"m1:{n + 1}")
    J = sp.symbols(f"J1:{n + 1}")
    F = sp.Symbol("F")
    R = sp.symbols(f"R1:{n + 1}")  # the resistance magnitude functions' values, set per state below

    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    frames = []
    for k in range(n):
        f = N.orientnew(f"E{k + 1}", "Axis", [th[k], N.z])
        f.set_ang_vel(N, w[k] * N.z)
        frames.append(f)
    course = N.orientnew("K", "Axis", [th[0] + psi, N.z])
    A = O.locatenew("A1", x * N.x + y * N.y)
    A.set_vel(N, uV * course.x + us * course.y)
    bodies, loads, constraints, axle_speeds = [], [], [us], []
    for k in range(n):
        f = frames[k]
        B = A.locatenew(f"B{k + 1}", -l[k] * f.x)
        B.v2pt_theory(A, N, f)
        C = B.locatenew(f"C{k + 1}", c[k] * f.x)
        C.v2pt_theory(A, N, f)
        constraints.append(B.vel(N).dot(f.y))  # no side slip at the axle
        speed = B.vel(N).dot(f.x)
        axle_speeds.append(speed)
        loads.append((B, -R[k] * f.x))
        bodies.append(me.RigidBody(f"cart{k + 1}", C, f, m[k], (me.inertia(f, 0, 0, J[k]), C)))
        A_next = B.locatenew(f"A{k + 2}", -a[k] * f.x)
        A_next.v2pt_theory(A, N, f)
        A = A_next
    A1 = O.locatenew("A1p", x * N.x + y * N.y)
    A1.set_vel(N, uV * course.x + us * course.y)
    loads.append((A1, F * course.x))
    kd = [x.diff(t) - (uV * sp.cos(th[0] + psi) - us * sp.sin(th[0] + psi)),
          y.diff(t) - (uV * sp.sin(th[0] + psi) + us * sp.cos(th[0] + psi))]
    kd += [th[k].diff(t) - w[k] for k in range(n)]
    km = me.KanesMethod(N, q_ind=[x, y, *th], u_ind=[uV], kd_eqs=kd, u_dependent=[us, *w],
                        velocity_constraints=constraints)
    km.kanes_equations(bodies, loads)
    psi_rate = sp.Symbol("psi_rate")
    values = [x, y, *th, psi, uV, us, *w]
    plain = sp.symbols(f"v0:{len(values)}")
    swap = {psi.diff(t): psi_rate, **dict(zip(values, plain))}
    # KanesMethod's M u' = f over every speed: the dynamic row of u_V and the acceleration
    # constraints of the dependent speeds (the time derivatives of the velocity constraints)
    mass = km.mass_matrix.subs(swap).tolist()
    forcing = km.forcing.subs(swap).tolist()
    params = (*l, *a, *c, *m, *J, F, *R)
    system = sp.lambdify((params, plain, psi_rate), (mass, forcing), "math")

    def accel(p, state, rate):
        matrix, rhs = system(p, state, rate)
        return float(np.linalg.solve(np.array(matrix, dtype=float), np.array(rhs, dtype=float).ravel())[0])

    # the dependent speeds from the constraints (linear in them): A us + sum B_k w_k + D uV = 0
    deps = [us, *w]
    matrix, rhs = sp.linear_eq_to_matrix(constraints, deps)
    solve_deps = sp.lambdify((params, plain), (matrix.subs(swap).tolist(), rhs.subs(swap).tolist()), "math")
    speeds = sp.lambdify((params, plain), [s.subs(swap) for s in axle_speeds], "math")
    return accel, solve_deps, speeds


def resistance(train, k: int, speed: float) -> float:
    """(f m g + sum of ASABE drafts F_i (A + B S + C S^2) W T, S = |speed| km/h) tanh(speed / v0)."""
    cart = train.carts[k]
    magnitude = sum(r.coefficient for r in train.rolling if r.cart == cart.name) * cart.mass * train.gravity
    S = abs(speed) * KMH
    for d in train.draft:
        if d.cart == cart.name:
            magnitude += d.soil_factor * (d.A + d.B * S + d.C * S * S) * d.width * d.depth
    return magnitude * math.tanh(speed / train.smoothing_speed)


def random_train(rng, n: int):
    carts = []
    for k in range(n):
        length = rng.uniform(1.5, 8.0)
        carts.append({"name": f"c{k}", "length": length,
                      "hitch_offset": rng.uniform(-0.6 * length, 2.0) if k < n - 1 else 0.0,
                      "com_offset": rng.choice([rng.uniform(-1.0, -0.1), rng.uniform(0.1, length),
                                                rng.uniform(length, length + 1.0)]),
                      "mass": rng.uniform(2e3, 2e4), "yaw_inertia": rng.uniform(5e3, 2e5),
                      "max_hitch_angle_deg": 170})
    draft = [{"cart": f"c{n - 1}", "A": rng.uniform(500, 3000), "B": rng.uniform(0, 50), "C": rng.uniform(0, 5),
              "soil_factor": 1.0, "width": rng.uniform(1, 12), "depth": 1.0}]
    data = {"name": "random", "carts": carts,
            "forces": {"traction": {"law": "constant", "force": rng.uniform(-5e4, 8e4)},
                       "rolling": [{"cart": f"c{k}", "coefficient": rng.uniform(0.02, 0.12)} for k in range(n)],
                       "draft": draft},
            "steering_actuator": {"time_constant": rng.uniform(0.05, 0.5), "max_rate": rng.uniform(0.2, 1.0),
                                  "max_angle_deg": 45},
            "smoothing_speed": rng.uniform(0.02, 0.2)}
    return loader.train_from_data(data, f"random train of {n}")


MODELS: dict = {}


@pytest.mark.parametrize("n", [1, 2, 3, pytest.param(4, marks=pytest.mark.slow)])
def test_the_kernel_state_derivative_equals_kanes_equations(n):
    if n not in MODELS:
        MODELS[n] = kane_model(n)
    accel, solve_deps, speeds = MODELS[n]
    rng = np.random.default_rng(20261201 + n)
    worst = 0.0
    for _ in range(12):
        train = random_train(rng, n)
        P = kernel.pack(train)
        V = rng.choice([-1.0, 1.0]) * rng.uniform(0.3, 6.0)
        psi1 = rng.uniform(-0.6, 0.6)
        heading = [rng.uniform(-math.pi, math.pi)]
        for _k in range(n - 1):
            heading.append(heading[-1] - rng.uniform(-0.8, 0.8))
        command = rng.uniform(-1.0, 1.0)
        y = np.array([rng.uniform(-50, 50), rng.uniform(-50, 50), *heading, psi1, V, 0.0])
        # the actuator: psi_1' = clip((clip(command) - psi_1) / tau, +-max_rate)
        act = train.actuator
        target = min(max(command, -act.max_angle), act.max_angle)
        rate = min(max((target - psi1) / act.time_constant, -act.max_rate), act.max_rate)
        cart = train.carts
        geometry = [k.length for k in cart] + [k.hitch_offset for k in cart] + [k.com_offset for k in cart]
        inertia = [k.mass for k in cart] + [k.yaw_inertia for k in cart]
        state = [y[0], y[1], *heading, psi1, V, 0.0, *([0.0] * n)]
        base = (*geometry, *inertia, train.traction.force, *([0.0] * n))
        matrix, rhs = solve_deps(base, state)
        deps = np.linalg.solve(np.array(matrix, dtype=float), np.array(rhs, dtype=float).ravel())
        state[n + 4:] = deps[:]  # us, w_1..w_n
        forces = [resistance(train, k, s) for k, s in enumerate(speeds(base, state))]
        expected = accel((*geometry, *inertia, train.traction.force, *forces), state, rate)
        # the check is sharp: the tractor's yaw inertia 1e-6 off moves the peer's V' past the bound
        planted = accel((*geometry, *inertia[:n], inertia[n] * (1 + 1e-6), *inertia[n + 1:],
                         train.traction.force, *forces), state, rate)
        assert abs(planted - expected) > 1e-10 * max(abs(expected), 1e-3) or abs(math.sin(psi1)) < 0.05
        dy = kernel.rhs_of(P, y, command, 0.0, kernel.max_rate_of(P))
        assert dy[n + 2] == pytest.approx(rate, rel=1e-15, abs=1e-15)
        assert abs(deps[0]) < 1e-9 * max(1.0, abs(V))  # the steered wheels do not slip
        np.testing.assert_allclose(dy[2:2 + n], deps[1:], rtol=1e-11, atol=1e-12)  # yaw rates
        assert dy[0] == pytest.approx(V * math.cos(heading[0] + psi1), rel=1e-14, abs=1e-12)
        relative = abs(dy[n + 3] - expected) / max(abs(expected), 1e-3)
        worst = max(worst, relative)
        assert relative < 1e-10, (n, dy[n + 3], expected)
    print(f"{n} carts: largest relative difference of V' {worst:.2e}")
