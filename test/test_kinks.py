"""Kinks: where the right-hand side is not smooth, the steppers split the step (integrate/steppers.py,
model/kernel.py ``advance``), and each method keeps its order.

- The actuator's release time in closed form is where the actuator law (test/laws.py) leaves its
  rate limit; each switching function changes sign exactly where its force law (test/laws.py:
  the laws as docs/model.md states them) changes branch; a held branch equals the law where the law is on it.
- On kinks.yaml (a light tractor, a heavy cart, steering steps whose rate limit lets go inside a
  step, speed steps that drive the governor through its force and power limits), against a DOP853
  reference at rtol = atol = 1e-12 that also splits: every fixed method's error falls with its
  order when splitting and not when stepping across; the default (rk4, 0.01 s) is within 1e-6 m;
  the adaptive methods' error control no longer accepts steps across a kink.
- Where no kink is met, splitting changes nothing, to the last bit.
- A release within 1e-15 s of a tick's start or end (before, on, after either): every method takes
  the tick on the branch the actuator is on, against the actuator's own solution and a reference
  that does not split (issue 21).
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import laws
import trains

from mta_sim_ros.integrate.tableau import TABLEAUX
from laws import steering_rate

from mta_sim_ros.physics import kernel
from mta_sim_ros.physics.dynamics import Model
from mta_sim_ros.physics.loader import load_scene
from mta_sim_ros.run.simulation import Simulation

REPO = Path(__file__).resolve().parents[1]
TARGET = 1e-6  # m, the default method against the reference (the target)


def kinks_scene(duration=12.0, step=0.01):
    """kinks.yaml at a fixed step (the orders are measured at 10 and 5 ms; None: its tolerance's)."""
    scene = load_scene(REPO / "config" / "scenes" / "kinks.yaml")
    return dataclasses.replace(scene, duration=duration, integrator=dataclasses.replace(scene.integrator, step=step))


def with_tolerance(scene, tol):
    return dataclasses.replace(scene, integrator=dataclasses.replace(scene.integrator, rtol=tol, atol=tol))


def hitch_points(scene, **options):
    """A_k of every cart and the last rear hitch, after every tick of the scene's held inputs."""
    sim = Simulation(scene, fidelity="dynamic", **options)
    points = []
    for _ in range(int(math.floor(scene.duration / sim.tick + 1e-9))):
        sim.advance(*sim.scheduled_inputs(sim.t))
        out = sim.outputs()
        points.append(np.vstack([out.front, out.rear_hitch[None]]))
    return np.array(points), sim


def distance(a, b) -> float:
    return float(np.max(np.linalg.norm(a - b, axis=2)))


@pytest.fixture(scope="module")
def reference():
    points, sim = hitch_points(with_tolerance(kinks_scene(), 1e-12), method="DOP853", split_kinks=True)
    # the scene does what it says: inside ticks, the rate limit lets go after each of the 3 steering
    # steps, and the governor meets or leaves a limit 4 times (force limit, power limit, and back)
    assert sim.kinks >= 3 + 4, sim.kinks
    return points


# -- the pieces against the laws ----------------------------------------------------------------------

def test_actuator_release_is_where_the_rate_limit_lets_go():
    act = trains.train(2).actuator
    P = kernel.pack(trains.train(2))
    rng = np.random.default_rng(0)
    for _ in range(200):
        psi0, command = rng.uniform(-0.8, 0.8, 2)
        t = kernel.release_of.py_func(P, psi0, command, act.max_rate)
        target = min(max(command, -act.max_angle), act.max_angle)
        if not math.isfinite(t):  # never limited: the law is linear from the start
            assert abs(steering_rate(act, psi0, command)) <= act.max_rate
            continue
        sign = math.copysign(1.0, target - psi0)
        # in the limited phase psi_1 moves at max_rate exactly
        assert steering_rate(act, psi0 + sign * act.max_rate * t * (1 - 1e-9), command) == sign * act.max_rate
        assert abs(steering_rate(act, psi0 + sign * act.max_rate * t * (1 + 1e-6) + 1e-12, command)) < act.max_rate


LAWS = {
    "governor": trains.GOVERNOR,
    "governor, force limit only": trains.Traction("governor", set_speed=3.0, max_force=60000.0, kp=60000.0, ki=3e4),
    "prescribed, accel limit": trains.Traction("prescribed_speed", set_speed=2.0, response_time=0.3, max_accel=0.4),
}


@pytest.mark.parametrize("law", list(LAWS))
def test_switching_functions_change_sign_where_the_law_changes_branch(law):
    tr = trains.train(3, LAWS[law])
    model = Model(tr)
    rng = np.random.default_rng(len(law))
    i_sat, i_limit, i_floor, i_accel, i_speed = kernel.switch_layout(model.P)
    for _ in range(300):
        y = trains.random_state(model, rng, slow=True)
        v_set = rng.uniform(-1, 5)
        g = kernel.switches_of.py_func(model.P, y, 0.1, v_set)
        V, z = y[model.layout.speed], y[model.layout.governor]
        if tr.traction.law == "governor":
            force, _ = laws.governor(tr.traction, V, v_set, z)
            u = tr.traction.kp * (v_set - V) + z
            assert (g[i_sat] > 0) == (force != u)  # saturated: the force is the limit, not u
            limit = laws.traction_limit(tr.traction, V)
            if i_limit >= 0:
                assert (g[i_limit] > 0) == (limit < tr.traction.max_force)
            if i_floor >= 0:
                assert (g[i_floor] > 0) == (abs(V) > 0.1)
        else:
            a = laws.prescribed_acceleration(tr.traction, V, v_set)
            assert (g[i_accel] > 0) == (a != (v_set - V) / tr.traction.response_time)
        # the draft grows with speed (B != 0): the sign of each such cart's axle speed is a switch
        speeds = model.terms(y, 0.1, v_set).chain.kapB
        assert g[i_speed:].tolist() == [speeds[-1] * V]  # the only cart with a draft here


@pytest.mark.parametrize("law", list(LAWS))
def test_held_branches_are_the_law_where_it_is_on_them(law):
    """Held on the branches the state is on, the right-hand side is the law's, to the last bit;
    held on the other branch it is the smooth extension of that branch (governor: the limit, or u)."""
    model = Model(trains.train(3, LAWS[law]))
    rng = np.random.default_rng(7)
    for _ in range(100):
        y = trains.random_state(model, rng, slow=True)
        command, v_set = rng.uniform(-0.8, 0.8), rng.uniform(-1, 5)
        limited = abs(steering_rate(model.train.actuator, y[model.layout.steering], command)) == model.train.actuator.max_rate
        mode = kernel.mode_of.py_func(model.P, y, command, v_set, limited)
        rate = model.train.actuator.max_rate
        np.testing.assert_array_equal(kernel.held_rhs_of.py_func(model.P, y, command, v_set, rate, mode),
                                      kernel.rhs_of.py_func(model.P, y, command, v_set, rate))


def test_a_held_governor_branch_is_the_smooth_extension():
    tr = trains.train(3, trains.GOVERNOR)
    model = Model(tr)
    y = trains.random_state(model, np.random.default_rng(1))
    y[model.layout.speed], y[model.layout.governor] = 3.0, 1e3  # far from saturation
    y[model.layout.steering] = 0.0  # the actuator at rest on its linear branch
    mode = kernel.mode_of.py_func(model.P, y, 0.0, 3.0, False)
    i_sat = kernel.switch_layout(model.P)[0]
    assert mode[1 + i_sat] == kernel.LOW
    mode[1 + i_sat] = kernel.HIGH  # held saturated: F_A1 = +limit although u is far below it
    rate = tr.actuator.max_rate
    held = kernel.held_rhs_of.py_func(model.P, y, 0.0, 3.0, rate, mode)
    natural = kernel.rhs_of.py_func(model.P, y, 0.0, 3.0, rate)
    mass = model.terms(y, 0.0, 3.0).mass
    limit = laws.traction_limit(tr.traction, 3.0)
    assert (held - natural)[model.layout.speed] == pytest.approx((limit - 1e3) / mass, rel=1e-12)


# -- the kink test: every method, before and after ----------------------------------------------------

@pytest.mark.parametrize("method", list(TABLEAUX))
def test_every_fixed_method_keeps_its_order_across_kinks(method, reference):
    order = TABLEAUX[method].order
    split = [distance(hitch_points(kinks_scene(), method=method, step=h)[0], reference) for h in (0.01, 0.005)]
    across = distance(hitch_points(kinks_scene(), method=method, split_kinks=False)[0], reference)
    assert math.log2(split[0] / split[1]) == pytest.approx(order, abs=0.25), split
    if order >= 2:  # (Euler's own first-order error hides the kinks)
        assert split[0] < across, (split[0], across)
    if order >= 3:  # by more than an order of magnitude
        assert split[0] < across / 20, (split[0], across)


def test_stepping_across_the_kinks_loses_rk4_its_order(reference):
    errors = [distance(hitch_points(kinks_scene(), method="rk4", step=h, split_kinks=False)[0], reference)
              for h in (0.01, 0.005)]
    assert math.log2(errors[0] / errors[1]) < 3.0, errors


def test_the_default_method_meets_the_target_on_the_kinks_scene(reference):
    points, sim = hitch_points(kinks_scene(step=None))  # the scene as shipped: its tolerance chooses the step
    assert sim.method == "rk4" and sim.step == 0.01 and sim.split_kinks  # one step a 100 Hz tick meets it
    assert distance(points, reference) < TARGET


@pytest.mark.parametrize("method", ["RK45", "DOP853"])
def test_adaptive_error_control_no_longer_accepts_a_step_across_a_kink(method, reference):
    scene = with_tolerance(kinks_scene(), 1e-8)
    split = distance(hitch_points(scene, method=method)[0], reference)
    across = distance(hitch_points(scene, method=method, split_kinks=False)[0], reference)
    assert split < across / 100 and split < 1e-9, (split, across)


def test_the_steering_is_the_actuators_closed_form():
    """With kinks split, psi_1 after every tick is the actuator's exact motion (kernel.actuator_psi)
    from the tick's start, not a stepped approximation of it: equal to an independent DOP853
    solution of psi_1' = actuator(psi_1, command) alone (test/laws.py) at rtol 1e-12."""
    from scipy.integrate import solve_ivp

    scene = kinks_scene(duration=8.0)
    sim = Simulation(scene, fidelity="dynamic")
    act, i = scene.train.actuator, sim.model.layout.steering
    worst = 0.0
    for _ in range(int(scene.duration / sim.tick)):
        command, v_set = sim.scheduled_inputs(sim.t)
        psi0 = sim.y[i]
        exact = solve_ivp(lambda t, p: [steering_rate(act, p[0], command)], (0.0, sim.tick), [psi0],
                          method="DOP853", rtol=1e-12, atol=1e-14).y[0, -1]
        sim.advance(command, v_set)
        worst = max(worst, abs(sim.y[i] - exact))
    assert worst < 1e-11, worst


# -- a release on a tick's boundary ---------------------------------------------------------------------
# The actuator's rate limit letting go within round-off of a tick's start or end: every method must
# take the tick on the branch the actuator is on for all of it but that round-off (issue 21).

EDGE_RATE = 10  # Hz: a tick of 0.1 s, ten of the scene's 10 ms steps, so that a missed release shows
EDGE_COMMAND = 0.4  # rad, inside max_angle: the actuator turns left towards it
EDGE_TOL = 1e-12  # the adaptive methods' rtol = atol here
#: where the release falls, as (tick's end: 0 start, 1 end, offset s)
EDGES = {"start-1e-15": (0, -1e-15), "start": (0, 0.0), "start+1e-15": (0, 1e-15),
         "end-1e-15": (1, -1e-15), "end": (1, 0.0), "end+1e-15": (1, 1e-15)}
ADAPTIVE = ["RK45", "DOP853", "LSODA", "BDF", "Radau"]


def edge_sim(method, tol=EDGE_TOL, **options):
    scene = with_tolerance(kinks_scene(duration=1.0), tol)
    return Simulation(scene, fidelity="dynamic", method=method, rate=EDGE_RATE, **options)


def edge_state(sim, edge):
    """The scene's start with psi_1 set so that, with EDGE_COMMAND held, the rate limit lets go
    at ``edge`` (EDGES) from the tick's start (before it: not rate-limited at the start): the
    limited actuator moves at max_rate until target - psi_1 = tau max_rate."""
    act = sim.scene.train.actuator
    end, offset = EDGES[edge]
    release = end * sim.tick + offset
    y = sim.y.copy()
    y[sim.model.layout.steering] = EDGE_COMMAND - act.max_rate * (act.time_constant + release)
    return y, release


def edge_tick(sim, y):
    """One tick from y holding EDGE_COMMAND and the scene's set-point: (psi_1, the hitch points)."""
    sim.y = y.copy()
    sim.advance(EDGE_COMMAND, sim.scheduled_inputs(sim.t)[1])
    out = sim.outputs()
    return sim.y[sim.model.layout.steering], np.vstack([out.front, out.rear_hitch[None]])


def exact_steering(act, psi0, tick):
    """psi_1 after the tick: psi_1' = actuator law (test/laws.py) alone, DOP853 at rtol 1e-12."""
    from scipy.integrate import solve_ivp

    return solve_ivp(lambda t, p: [steering_rate(act, p[0], EDGE_COMMAND)], (0.0, tick), [psi0],
                     method="DOP853", rtol=1e-12, atol=1e-14).y[0, -1]


def edge_reference(edge):
    """The tick stepped across the release (no splitting: no release logic to share a bug with),
    DOP853 at rtol = atol = 1e-13 and steps of at most 2 ms (not the 10 ms of the methods held to
    it): the release is within 1e-15 s of an end, so the law is smooth over all of the tick but that."""
    sim = edge_sim("DOP853", tol=1e-13, split_kinks=False, step=0.002)
    return edge_tick(sim, edge_state(sim, edge)[0])


def test_the_edge_states_let_go_where_they_say():
    """The placed state is on the branch its release says (the test law, test/laws.py), and the
    kernel's closed form puts the release there to round-off."""
    sim = edge_sim("rk4")
    act = sim.scene.train.actuator
    for edge in EDGES:
        y, release = edge_state(sim, edge)
        psi0 = y[sim.model.layout.steering]
        limited = steering_rate(act, psi0, EDGE_COMMAND) == act.max_rate
        found = kernel.release_of.py_func(sim.model.P, psi0, EDGE_COMMAND, act.max_rate)
        if release < 0.0:
            assert not limited and found == math.inf, (edge, found)
        elif release > 0.0:
            assert limited and found == pytest.approx(release, abs=2e-16), (edge, found)
        else:
            assert found == math.inf or abs(found) < 2e-16, (edge, found)


@pytest.mark.parametrize("edge", list(EDGES))
@pytest.mark.parametrize("method", ADAPTIVE)
def test_an_adaptive_method_meets_a_release_on_a_tick_boundary(method, edge):
    """psi_1 after the tick is the actuator's own solution and the train is where the reference
    puts it. At rtol = atol = 1e-12 each step's error is below ~1e-12 of the state, a tick takes
    tens of steps: 1e-9 (rad, m) leaves room for any of the five; a tick held on the wrong
    branch is off by ~1e-2 rad and ~8e-4 m."""
    sim = edge_sim(method)
    y, _ = edge_state(sim, edge)
    psi, points = edge_tick(sim, y)
    exact = exact_steering(sim.scene.train.actuator, y[sim.model.layout.steering], sim.tick)
    _, reference = edge_reference(edge)
    assert abs(psi - exact) < 1e-9, (psi, exact)
    assert distance(points[None], reference[None]) < 1e-9


@pytest.mark.parametrize("edge", list(EDGES))
@pytest.mark.parametrize("method", list(TABLEAUX))
def test_a_fixed_method_meets_a_release_on_a_tick_boundary(method, edge):
    """psi_1 after the tick is the actuator's solution to the reference's ~1e-13 (rk_step takes
    psi_1 from its closed form, so this holds on either branch); the train is within the method's
    own error of the reference: the error at step h is (y_h - y_h/2) / (1 - 2^-p) to leading order,
    bounded here by 3 |y_h - y_h/2| (p >= 1). A tick held on the wrong branch (the same at either
    step) is ~2e-4 m off, far past that for heun to rk38; euler's own error (~7e-4 m) hides it."""
    sims = [edge_sim(method, step=h) for h in (0.01, 0.005)]
    y, _ = edge_state(sims[0], edge)
    (psi, points), (_, finer) = (edge_tick(sim, y) for sim in sims)
    exact = exact_steering(sims[0].scene.train.actuator, y[sims[0].model.layout.steering], sims[0].tick)
    _, reference = edge_reference(edge)
    assert abs(psi - exact) < 1e-11, (psi, exact)
    own = distance(points[None], finer[None])
    assert distance(points[None], reference[None]) <= 3.0 * own + 1e-12, own


def test_a_whole_run_meets_a_release_on_a_tick_boundary_as_a_tick_does():
    """The whole-run path (run/whole.py: sweeps, run/batch.py) steps a tick with the release at
    either end to the same bits as Simulation.advance, which the test above holds to the physics."""
    from mta_sim_ros.run import whole

    sim = edge_sim("rk4")
    model, stepper = sim.model, sim.stepper
    for edge in EDGES:
        y, _ = edge_state(sim, edge)
        v_set = sim.scheduled_inputs(0.0)[1]
        trace = np.empty((2, whole.TRACE_HEAD + whole.TRACE_CART * model.layout.n))
        y1, ticks, _, _ = whole.run(model.P, model.P_outputs, stepper.tableau.packed, y, np.array([EDGE_COMMAND]),
                                    np.array([v_set]), np.array([sim.max_rate]), sim.tick, stepper.step,
                                    stepper.split_kinks, 0, trace)
        sim.ticks = 0
        edge_tick(sim, y)
        assert ticks == 1
        np.testing.assert_array_equal(y1, sim.y, err_msg=edge)
