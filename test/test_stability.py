"""Unstable integrator configurations never give garbage, and the accuracy benchmark's metrics.

The stiff-actuator scene (steering time constant tau = 5 ms) with rk4 at a 40 ms step, the
actuator stepped like the rest (split_kinks off), is past rk4's real-axis stability limit
h < 2.785 tau: the bare stepper's steering mode grows every step. A Simulation either refuses it
(substep=False) with an error naming method, step and reason, or sub-steps and stays with a tight
reference. With kinks split (the default) the steering follows the actuator's closed form: its
mode is not stepped, so it limits no step, and the step is only cut to resolve tau.
"""
from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from benchmarks.runs import (
    final_error,
    heading_error,
    hitch_points,
    position_error,
    power_error,
    simulation,
    with_tolerances,
)
from benchmarks.accuracy.work_precision import crossing
from mta_sim_ros.integrate import make_stepper
from mta_sim_ros.integrate.stability import (
    REAL_AXIS_LIMIT,
    UnstableStepError,
    effective_step,
    stability_function,
    stable_step,
)
from mta_sim_ros.physics.guards import fast_modes
from mta_sim_ros.physics.loader import load_scene

CONFIG = Path(__file__).resolve().parents[1] / "config"
RATE = 25.0  # Hz: a 40 ms tick lets the fixed step pass the actuator's limit


@pytest.fixture(scope="module")
def stiff():
    scene = load_scene(CONFIG / "scenes" / "stiff_actuator.yaml")
    return dataclasses.replace(scene, duration=10.0)  # into the first slalom swing


def held_run(sim, ticks):
    """States after each tick under the scene's own held commands."""
    out = []
    for _ in range(ticks):
        sim.advance(*sim.scheduled_inputs(sim.t))
        out.append(sim.y.copy())
    return np.array(out)


def bare_run(scene, method, step, ticks):
    """The same ticks with the bare stepper: no stability guard."""
    ref_sim = simulation(scene, method="DOP853", rate=RATE)  # model, start state and inputs only
    model, y = ref_sim.model, ref_sim.y.copy()
    stepper = make_stepper(method, step)
    tick = ref_sim.tick
    out = []
    for i in range(ticks):
        c, v = ref_sim.scheduled_inputs(i * tick)
        y = stepper.advance(lambda t, yy: model.rhs(t, yy, c, v), i * tick, y, (i + 1) * tick)
        out.append(y.copy())
    return np.array(out)


@pytest.fixture(scope="module")
def reference(stiff):
    sim = simulation(with_tolerances(stiff, 1e-11, 1e-11), method="DOP853", rate=RATE)
    return sim, held_run(sim, int(stiff.duration * RATE))


def points(sim, Y):
    L = sim.model.layout
    tr = sim.scene.train
    return hitch_points([c.length for c in tr.carts], [c.hitch_offset for c in tr.carts],
                        Y[:, L.x], Y[:, L.y], Y[:, L.heading])


# -- the stability limit itself ------------------------------------------------------------------
@pytest.mark.parametrize("method", ["euler", "heun", "rk4"])
def test_real_axis_limit_is_where_the_step_factor_reaches_one(method):
    """|R(-x)| = 1 at the limit: below it a decaying mode decays, above it it grows."""
    x = REAL_AXIS_LIMIT[method]
    assert abs(abs(stability_function(method, -x)) - 1.0) < 1e-9
    assert abs(stability_function(method, -0.99 * x)) < 1.0
    assert abs(stability_function(method, -1.01 * x)) > 1.0
    # and everywhere between 0 and the limit the mode decays
    assert all(abs(stability_function(method, -z)) < 1.0 for z in np.linspace(1e-3, 0.999 * x, 200))


def test_effective_step_splits_the_tick_evenly():
    assert effective_step(0.04, 0.04) == pytest.approx(0.04)
    assert effective_step(0.015, 0.04) == pytest.approx(0.04 / 3)
    assert effective_step(0.01, 0.04) == pytest.approx(0.01)


def test_fast_modes_put_the_stiff_actuator_first(stiff):
    rate, what = max(fast_modes(stiff.train))
    assert rate == pytest.approx(1.0 / stiff.train.actuator.time_constant)
    assert "actuator" in what


def test_stable_configurations_are_left_alone(stiff):
    modes = fast_modes(stiff.train)
    # rk4 at the node's 10 ms: h / tau = 2 < 2.785
    assert stable_step("rk4", 0.01, 0.01, modes) == (0.01, None)
    # adaptive solvers control their own steps
    assert stable_step("RK45", 0.04, 0.04, modes) == (0.04, None)
    # the default train's 0.2 s hydraulic actuator allows rk4 steps up to 0.56 s
    default = load_scene(CONFIG / "scenes" / "headland_turn.yaml")
    assert stable_step("rk4", 0.04, 0.04, fast_modes(default.train)) == (0.04, None)


def test_a_stable_configuration_runs_with_its_own_step(stiff):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no stability warning
        sim = simulation(stiff, method="rk4", step=0.01, rate=100.0, split_kinks=False)
    assert sim.stability_note is None and sim.stepper.step == 0.01


def test_the_actuator_in_closed_form_limits_no_step(stiff, reference):
    """rk4 at 40 ms with kinks split: no stability problem to refuse (substep=False runs), the
    step cut to tau / 2 only to resolve the actuator's motion, and the run on the reference."""
    ref_sim, ref = reference
    sim = simulation(stiff, method="rk4", step=0.04, rate=RATE, substep=False)
    assert sim.exact_actuator and sim.stepper_step == pytest.approx(stiff.train.actuator.time_constant / 2)
    assert "time constant" in sim.stability_note and "unstable" not in sim.stability_note
    Y = held_run(sim, len(ref))
    assert position_error(points(sim, Y), points(ref_sim, ref)) < 1e-6


# -- the unstable configuration -------------------------------------------------------------------
def test_the_bare_stepper_is_garbage_there(stiff, reference):
    """The premise: rk4 at 40 ms (h / tau = 8) without the guard leaves the solution."""
    ref_sim, ref = reference
    Y = bare_run(stiff, "rk4", 0.04, len(ref))  # the actuator stepped like the rest
    L = ref_sim.model.layout
    bad_steering = np.max(np.abs(Y[:, L.steering] - ref[:, L.steering]))
    assert not np.all(np.isfinite(Y)) or bad_steering > 0.01


def test_unstable_step_is_refused_with_method_step_and_reason(stiff):
    with pytest.raises(UnstableStepError) as info:
        simulation(stiff, method="rk4", step=0.04, rate=RATE, substep=False, split_kinks=False)
    text = str(info.value)
    for word in ("rk4", "0.04 s", "2.785", "steering actuator", "0.005", "unstable"):
        assert word in text, (word, text)


def test_unstable_step_is_sub_stepped_to_the_reference(stiff, reference):
    """Warned, then sub-stepped inside the stability region: every hitch point stays within 1 cm
    of the reference and the steering follows it (the bare stepper's chatter is gone)."""
    ref_sim, ref = reference
    with pytest.warns(RuntimeWarning, match=r"rk4 .*unstable.*sub-stepping"):
        sim = simulation(stiff, method="rk4", step=0.04, rate=RATE, split_kinks=False)
    h = effective_step(sim.stepper.step, sim.tick)
    assert h * max(fast_modes(stiff.train))[0] < REAL_AXIS_LIMIT["rk4"]
    Y = held_run(sim, len(ref))
    assert np.all(np.isfinite(Y))
    L = sim.model.layout
    assert np.max(np.abs(Y[:, L.steering] - ref[:, L.steering])) < 1e-3
    assert position_error(points(sim, Y), points(ref_sim, ref)) < 0.01


@pytest.mark.parametrize("method,step", [("euler", 0.01), ("heun", 0.01)])
def test_euler_and_heun_at_the_nodes_tick_sit_on_their_limit(stiff, method, step):
    """h / tau = 2 is exactly the limit 2 of Euler and Heun: not stable (the mode would not decay)."""
    modes = fast_modes(stiff.train)
    new, note = stable_step(method, step, 0.01, modes)
    assert note is not None and new < step
    assert abs(stability_function(method, -effective_step(new, 0.01) / stiff.train.actuator.time_constant)) < 1.0


# -- the benchmark's error metrics ------------------------------------------------------------------
def test_hitch_points_of_a_straight_and_a_turned_train():
    lengths, offsets = [3.0, 5.0, 6.0], [1.5, 1.5, 0.0]
    p = hitch_points(lengths, offsets, [10.0], [2.0], [[0.0, 0.0, 0.0]])[0]
    assert np.allclose(p, [[10, 2], [5.5, 2], [-1.0, 2], [-7.0, 2]])
    # all carts at 90 deg: the points line up along -y
    p = hitch_points(lengths, offsets, [0.0], [0.0], [[math.pi / 2] * 3])[0]
    assert np.allclose(p, [[0, 0], [0, -4.5], [0, -11.0], [0, -17.0]], atol=1e-12)
    # a rigid rotation of every heading rotates the points about A_1 and keeps their distances
    h = np.array([[0.3, 0.1, -0.2]])
    a = hitch_points(lengths, offsets, [0.0], [0.0], h)[0]
    b = hitch_points(lengths, offsets, [0.0], [0.0], h + 1.0)[0]
    rot = np.array([[math.cos(1.0), -math.sin(1.0)], [math.sin(1.0), math.cos(1.0)]])
    assert np.allclose(b, a @ rot.T)


def test_position_errors_take_the_largest_distance():
    ref = np.zeros((3, 2, 2))
    pts = ref.copy()
    pts[1, 1] = [3.0, 4.0]  # 5 m in the middle
    pts[2, 0] = [0.0, 1.0]  # 1 m at the end
    assert position_error(pts, ref) == pytest.approx(5.0)
    assert final_error(pts, ref) == pytest.approx(1.0)


def test_heading_error_wraps():
    assert heading_error([[2 * math.pi - 0.01]], [[0.0]]) == pytest.approx(0.01)
    assert heading_error([[0.2, -0.5]], [[0.0, 0.0]]) == pytest.approx(0.5)


def test_power_error_is_relative_to_the_peak_reference_power():
    assert power_error([100.0, 190.0], [100.0, 200.0]) == pytest.approx(0.05)
    assert power_error([-100.0, 0.0], [-200.0, 0.0]) == pytest.approx(0.5)


def test_crossing_interpolates_a_power_law_exactly():
    costs = [1.0, 2.0, 4.0, 8.0]
    errors = [c ** -4 for c in costs]  # order 4 in the cost
    assert crossing(costs, errors, 3.0 ** -4) == pytest.approx(3.0)
    assert crossing(costs, errors, 1e-9) is None
    assert crossing(costs, errors, 10.0) == 1.0  # the cheapest already meets it
