"""The physics core against things that cannot drift: closed forms, balance laws, invariances,
and the agreement of the article's two algorithms (MODEL.md, "Facts to test against")."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import trains
from scipy.integrate import solve_ivp

from mta_sim_ros.physics.dynamics import Model
from mta_sim_ros.physics.geometry import cart_points
from mta_sim_ros.physics.guards import jackknife_margin
from mta_sim_ros.physics.holonomic import HolonomicReduction
from mta_sim_ros.physics.steady import SteadyStateError, steady_circle
from mta_sim_ros.run.simulation import Simulation, run_scene

# Trains for the closed-form checks: n = 1..5, the 4th cart is hitched in front of its axle.
TRAINS = {n: trains.train(n) for n in range(1, 6)}
NEGATIVE_OFFSET = trains.train(carts=[trains.CARTS[0], (4.0, -0.8, 1.0, 5000.0, 20000.0), trains.CARTS[2]])




# -- algorithm 1 = algorithm 2 --------------------------------------------------------------
@pytest.mark.parametrize("n", [1, 2, 3, 5])
@pytest.mark.parametrize("law", ["governor", "constant", "prescribed_speed"])
def test_holonomic_reduction_equals_direct_differentiation(n, law):
    """[8] (holonomic equations reduced by G) and [7] (differentiation by the pseudo-velocity)
    give the same mass, velocity term, traction and acceleration to round-off."""
    traction = {
        "governor": trains.GOVERNOR,
        "constant": trains.Traction("constant", force=40000.0),
        "prescribed_speed": trains.prescribed(3.0),
    }[law]
    tr = trains.train(n, traction=traction)
    alg1, alg2 = Model(tr, algorithm=1), Model(tr, algorithm=2)
    rng = np.random.default_rng(n)
    for _ in range(20):
        y = trains.random_state(alg2, rng)
        command, v_set = rng.uniform(-0.6, 0.6), rng.uniform(-3, 3)
        t1, t2 = alg1.terms(y, command, v_set), alg2.terms(y, command, v_set)
        scale = max(abs(t2.velocity_term), t2.mass * 1e-3)
        assert t1.mass == pytest.approx(t2.mass, rel=1e-12)
        assert abs(t1.velocity_term - t2.velocity_term) < 1e-10 * scale
        assert abs(t1.traction - t2.traction) < 1e-10 * max(abs(t2.traction), 1.0)
        assert abs(t1.acceleration - t2.acceleration) < 1e-10 * max(abs(t2.acceleration), scale / t2.mass)


def test_force_structural_matrix_equals_velocity_coefficient():
    """W_P of a force at B_k along e_k: G^T J_Bk^T e_k (algorithm 1) = kapB_k (algorithm 2)."""
    tr = TRAINS[5]
    model = Model(tr)
    hol = HolonomicReduction(tr)
    rng = np.random.default_rng(7)
    for _ in range(10):
        y = trains.random_state(model, rng)
        ch = model.terms(y, 0.0, 0.0).chain
        np.testing.assert_allclose(hol.resistance_projection(list(y), ch), ch.kapB, rtol=1e-12, atol=1e-14)


# -- kinematics against positions, differentiated exactly by complex step ------------------
def point_velocities(tr, y, qdot):
    """Velocities of A_k, B_k, C_k: d(position)/dq . q' with the Jacobian by complex step
    (exact to round-off, independent of the chain's formulas)."""
    n = tr.n
    q = np.asarray(y[: n + 2], dtype=float)
    h = 1e-30
    pert = cart_points(tr, q[0] + 1j * h * qdot[0], q[1] + 1j * h * qdot[1], q[2:] + 1j * h * qdot[2:])
    return {key: pert[key].imag / h for key in ("A", "B", "C")}


def independent_kinetic_energy(tr, y, qdot) -> float:
    """T = sum 1/2 m |v_C|^2 + 1/2 J th'^2 from the bodies' own velocities."""
    v = point_velocities(tr, y, qdot)
    m = np.array([c.mass for c in tr.carts])
    J = np.array([c.yaw_inertia for c in tr.carts])
    return 0.5 * float(m @ (v["C"] ** 2).sum(axis=1) + J @ qdot[2:] ** 2)


@pytest.mark.parametrize("n", [1, 3, 5])
def test_no_side_slip_and_element_speeds(n):
    """q' = G V satisfies the rolling constraints: v_Bk along e_k, v_A1 along the steered wheel;
    s'_Bk, s'_Ck and V_k from the chain equal the speeds of the points themselves."""
    tr = TRAINS[n]
    model = Model(tr)
    rng = np.random.default_rng(11 + n)
    for _ in range(10):
        y = trains.random_state(model, rng)
        dy = model.rhs(0.0, y, 0.0, 0.0)
        qdot = dy[: n + 2]
        v = point_velocities(tr, y, qdot)
        out = model.outputs(0.0, y, 0.0, 0.0)
        th = y[model.layout.heading]
        e = np.stack((np.cos(th), np.sin(th)), axis=1)
        normal = np.stack((-np.sin(th), np.cos(th)), axis=1)
        speed_scale = abs(y[model.layout.speed]) + 1e-3
        np.testing.assert_allclose((v["B"] * normal).sum(axis=1), 0.0, atol=1e-12 * speed_scale)
        np.testing.assert_allclose((v["B"] * e).sum(axis=1), out.axle_speed, rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(np.hypot(*v["C"].T), np.abs(out.com_speed), rtol=1e-12, atol=1e-13)
        course = th[0] + y[model.layout.steering]
        assert abs(-v["A"][0, 0] * math.sin(course) + v["A"][0, 1] * math.cos(course)) < 1e-12 * speed_scale
        assert independent_kinetic_energy(tr, y, qdot) == pytest.approx(out.kinetic_energy, rel=1e-12)


def test_outputs_jackknife_margin_is_the_guards_at_any_speed():
    """A level's outputs take psi_k from the chain it walked at the state's speed V; the guard walks
    it at V = 0. psi_k is geometry (headings and psi_1), so the margins agree exactly."""
    rng = np.random.default_rng(11)
    for n in (2, 3, 5):
        model = Model(TRAINS[n])
        for _ in range(50):
            y = trains.random_state(model, rng, spread=0.8)
            out = model.outputs(0.0, y, 0.1, 3.0)
            assert out.jackknife_margin == jackknife_margin(model, y)[0]


# -- power balance ----------------------------------------------------------------------------
@pytest.mark.parametrize("law", ["governor", "constant"])
def test_power_balance_along_a_manoeuvre(law):
    """F_A1 V - sum F_Bk s'_Bk = dT/dt: integrated along a slalom with steering-rate changes,
    the work of the applied forces equals the change of the bodies' own kinetic energy."""
    traction = trains.GOVERNOR if law == "governor" else trains.Traction("constant", force=45000.0)
    tr = trains.train(3, traction=traction)
    model = Model(tr)
    sc = trains.scene(tr, speed=2.5)
    y0 = Simulation(sc).y

    def command(t):
        return 0.25 * math.sin(0.6 * t) + 0.1 * math.sin(1.7 * t)

    def augmented(t, z):
        dy, tm = model.derivative(z[:-1], command(t), 3.0)
        V = z[model.layout.speed]
        applied = tm.traction * V - sum(f * kb * V for f, kb in zip(tm.resistance, tm.chain.kapB))
        return np.append(dy, applied)

    sol = solve_ivp(augmented, (0, 20), np.append(y0, 0.0), method="DOP853", rtol=1e-12, atol=1e-12,
                    dense_output=False, t_eval=np.linspace(0, 20, 41))
    assert sol.success
    n = tr.n
    energies = []
    for i, t in enumerate(sol.t):
        y = sol.y[:-1, i]
        qdot = model.rhs(t, y, command(t), 3.0)[: n + 2]
        energies.append(independent_kinetic_energy(tr, y, qdot))
    work = sol.y[-1]
    # the scale of the exchange: the kinetic energy and the work of every force involved
    scale = max(energies) + np.max(np.abs(work)) + 1.0
    assert np.max(np.abs(np.array(energies) - energies[0] - work)) < 1e-8 * scale
    # and at every instant the equation's own dT/dt is the applied power
    for i in range(0, len(sol.t), 5):
        applied, dT = model.power_balance(sol.y[:-1, i], command(sol.t[i]), 3.0)
        assert dT == pytest.approx(applied, rel=1e-10, abs=1e-6)


# -- steady circles -------------------------------------------------------------------------
def settle_on_circle(tr, steering, distance=1500.0, speed=5.0):
    sc = trains.scene(dataclasses.replace(tr, traction=trains.prescribed(speed)),
                      table=((0.0,), (steering,)), duration=distance / speed, rate=0.2,
                      method="DOP853", step=5.0, rtol=1e-12, atol=1e-12, steering=steering)
    sim, err = run_scene(sc)
    assert err is None, err
    return sim


@pytest.mark.parametrize("tr", [*TRAINS.values(), NEGATIVE_OFFSET], ids=[*map(str, TRAINS), "negative_offset"])
@pytest.mark.parametrize("steering", [0.12, -0.2])
def test_train_settles_on_the_closed_form_circles(tr, steering):
    """Starting straight, the train settles on concentric circles of the closed-form radii."""
    expected = steady_circle(tr, steering)
    sim = settle_on_circle(tr, steering)
    out = sim.outputs()
    # centre of the circles: the tractor's instantaneous centre of rotation, exact at any time
    th1 = out.heading[0]
    centre = out.axle[0] + expected.R_B[0] * np.array([-math.sin(th1), math.cos(th1)]) * math.copysign(1, steering)
    R_A = np.hypot(*(out.front - centre).T)
    R_B = np.hypot(*(out.axle - centre).T)
    R_C = np.hypot(*(out.com - centre).T)
    np.testing.assert_allclose(R_A, expected.R_A, rtol=1e-8)
    np.testing.assert_allclose(R_B, expected.R_B, rtol=1e-8)
    np.testing.assert_allclose(R_C, expected.R_C, rtol=1e-8)
    np.testing.assert_allclose(out.hitch_angle, expected.hitch_angles, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(out.psi, expected.psi, rtol=1e-8)


def test_steady_circle_that_cannot_exist_is_refused_and_the_run_jackknifes():
    """R_A{k+1} <= l_{k+1}: no steady state. The closed form says so, naming the cart, and a run
    held at that steering stops at the jackknife with the outputs up to it intact."""
    tr = TRAINS[3]
    with pytest.raises(SteadyStateError, match="cart3"):
        steady_circle(tr, 0.45)  # R_A2 = 6.4 m > l_2 = 5 m, but R_A3 = 4.25 m < l_3 = 6 m
    seen = []
    sc = trains.scene(tr, table=((0.0, 1.0), (0.0, 0.45)), duration=120.0, rate=20.0)
    sim, err = run_scene(sc, on_output=seen.append)
    assert err is not None and "jackknife" in str(err) and err.cart in ("cart2", "cart3")
    assert "no steady turn exists" in str(err) and "cart3" in str(err)
    assert 1.0 < err.time < 120.0
    assert seen[-1].t == pytest.approx(err.time - sim.tick) and all(np.isfinite(o.power) for o in seen)


# -- n = 1 is the kinematic bicycle ------------------------------------------------------------
def test_single_cart_is_the_kinematic_bicycle():
    """th' = V sin(psi_1) / l_1; at constant steering and speed A_1 runs on a circle of radius
    l_1 / sin(psi_1) about the centre fixed by the start pose."""
    tr = trains.train(1, traction=trains.prescribed(4.0))
    psi, V, l = 0.3, 4.0, tr.carts[0].length
    sc = trains.scene(tr, table=((0.0,), (psi,)), duration=12.0, rate=1.0, method="DOP853", step=1.0,
                      rtol=1e-12, atol=1e-12, steering=psi, speed=V, heading=0.4, x=2.0, y=-1.0)
    seen = []
    _, err = run_scene(sc, on_output=seen.append)
    assert err is None
    R = l / math.sin(psi)
    for out in seen:
        th = 0.4 + V * math.sin(psi) / l * out.t
        assert out.heading[0] == pytest.approx(th, abs=1e-9)
        assert out.yaw_rate[0] == pytest.approx(V * math.sin(psi) / l, rel=1e-12)
        # A_1 moves along th + psi on a circle; centre = A_1 + R * left normal of its velocity
        start_course = 0.4 + psi
        centre = np.array([2.0, -1.0]) + R * np.array([-math.sin(start_course), math.cos(start_course)])
        expected = centre + R * np.array([math.sin(th + psi), -math.cos(th + psi)])
        np.testing.assert_allclose(out.front[0], expected, atol=1e-8)


# -- integrator orders ------------------------------------------------------------------------
def final_error(method, step, reference):
    sc = trains.scene(trains.train(3), table=STEERING, duration=8.0, rate=10.0, method=method, step=step,
                      speed=2.5)
    sim, err = run_scene(sc)
    assert err is None
    return np.max(np.abs(sim.y[: sim.model.layout.n + 2] - reference[: sim.model.layout.n + 2]))


STEERING = (tuple(np.arange(0, 8.01, 0.1)), tuple(0.2 * np.sin(0.8 * np.arange(0, 8.01, 0.1))))


@pytest.mark.parametrize("method,order,steps", [
    ("euler", 1, [0.1 / 8, 0.1 / 16, 0.1 / 32, 0.1 / 64]),
    ("heun", 2, [0.1 / 2, 0.1 / 4, 0.1 / 8, 0.1 / 16]),
    ("rk4", 4, [0.1, 0.1 / 2, 0.1 / 4, 0.1 / 8]),
])
def test_error_slope_matches_the_method_order(method, order, steps):
    """Against a DOP853 reference at rtol = 1e-13 under the same held commands, the error falls
    as step^order (the right-hand side is smooth between ticks: no rate limit, no saturation)."""
    ref_scene = trains.scene(trains.train(3), table=STEERING, duration=8.0, rate=10.0, method="DOP853",
                             step=0.1, rtol=1e-13, atol=1e-13, speed=2.5)
    ref, err = run_scene(ref_scene)
    assert err is None
    errors = [final_error(method, h, ref.y) for h in steps]
    slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert abs(slope - order) < 0.15 * order, (errors, slope)


# -- invariance under rigid motions of the start pose -----------------------------------------
def test_rigid_motion_of_the_start_pose_moves_the_result_and_nothing_else():
    tr = TRAINS[3]
    base = dict(table=((0.0, 2.0, 6.0, 10.0), (0.0, 0.25, -0.15, 0.0)), duration=12.0, rate=20.0,
                method="rk4", step=0.01)
    a = trains.scene(tr, **base)
    angle, shift = 2.1, np.array([120.0, -45.0])
    b = trains.scene(tr, **base, x=shift[0], y=shift[1], heading=angle)
    sim_a, _ = run_scene(a)
    sim_b, _ = run_scene(b)
    oa, ob = sim_a.outputs(), sim_b.outputs()
    rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    for key in ("front", "axle", "com"):
        np.testing.assert_allclose(getattr(oa, key) @ rot.T + shift, getattr(ob, key), atol=1e-9)
    np.testing.assert_allclose(oa.heading + angle, ob.heading, atol=1e-12)
    for key in ("hitch_angle", "com_speed", "axle_speed", "yaw_rate"):
        np.testing.assert_allclose(getattr(oa, key), getattr(ob, key), rtol=1e-9, atol=1e-12)
    assert ob.power == pytest.approx(oa.power, rel=1e-9)
    assert ob.kinetic_energy == pytest.approx(oa.kinetic_energy, rel=1e-9)


# -- forward decay, reverse growth of the hitch angle --------------------------------------------
@pytest.mark.parametrize("speed", [2.0, -1.0])
def test_hitch_angle_decays_forward_and_grows_in_reverse(speed):
    """Tractor straight, one trailer: psi_2 = phi and phi' = -V sin(phi) / l_2, whose solution is
    tan(phi/2) = tan(phi0/2) exp(-V t / l_2): decay forward, growth in reverse (jackknife)."""
    tr = trains.train(2, traction=trains.prescribed(speed))
    phi0, l2 = 0.1, tr.carts[1].length
    duration = 6.0 if speed > 0 else 10.0
    sc = trains.scene(tr, duration=duration, rate=2.0, method="DOP853", step=0.5, rtol=1e-12, atol=1e-12,
                      speed=speed, hitch_angles=(phi0,))
    seen = []
    _, err = run_scene(sc, on_output=seen.append)
    assert err is None
    for out in seen:
        expected = 2 * math.atan(math.tan(phi0 / 2) * math.exp(-speed * out.t / l2))
        assert out.hitch_angle[0] == pytest.approx(expected, rel=1e-8)
    final = seen[-1].hitch_angle[0]
    assert (final < phi0 / 5) if speed > 0 else (final > 3 * phi0)
