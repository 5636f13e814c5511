"""The kernels (model/kernel.py) against the readable reference, and compiled against plain Python.

- ``kernel.rhs`` equals the reference path (chain.chain + dynamics.Model.terms, algorithm 2) to the
  last bit for 1..5, 20 and 100 carts under every traction law, and the kinematic level's chain
  (``KinematicModel.reference_rhs``); algorithm 1 (holonomic.py) to round-off.
- ``kernel.outputs`` equals ``reference_outputs`` (cart_points, the chain, Terms, hitch angles and
  the guards' margin) field by field, and wraps hitch angles past pi as geometry.wrap_angle does.
- Every kernel entry compiled equals the same source run as plain Python, to the last bit.
- The packed constants are the train's, read back through the declaration.
- ``Simulation`` runs compiled by default, compiles when it is built (not in the first tick), and
  runs as plain Python when asked or when MTA_SIM_NO_JIT is set; a jackknife stops both paths
  at the same tick with the same message.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import trains
from child import python

from mta_sim_ros import jit
from mta_sim_ros.integrate import rk
from mta_sim_ros.integrate.tableau import TABLEAUX
from mta_sim_ros.physics import kernel
from mta_sim_ros.physics.dynamics import Model
from mta_sim_ros.physics.guards import ModelValidityError, jackknife_margin
from mta_sim_ros.physics.kinematic import KinematicModel
from mta_sim_ros.physics.loader import load_scene
from mta_sim_ros.physics.outputs import reference_outputs
from mta_sim_ros.physics.spec import Draft
from mta_sim_ros.run.simulation import NO_JIT_ENV, Simulation, run_scene

REPO = Path(__file__).resolve().parents[1]

LAWS = {
    "governor": trains.GOVERNOR,
    "governor, no power limit": trains.Traction("governor", set_speed=3.0, max_force=90000.0, kp=60000.0,
                                                ki=30000.0, windup_time=0.5),
    "constant": trains.Traction("constant", force=40000.0),
    "prescribed_speed": trains.prescribed(3.0),
    "prescribed_speed, accel limit": trains.Traction("prescribed_speed", set_speed=2.0, response_time=0.3,
                                                     max_accel=0.4),
}


def train(n: int, traction):
    """n carts cycling through the test carts; drafts on the last cart and, for n > 1, two more on
    cart 2 (several drafts on one cart, drafts on several carts)."""
    tr = trains.train(carts=[trains.CARTS[k % len(trains.CARTS)] for k in range(n)], traction=traction)
    if n > 1:
        extra = (Draft("cart2", A=46.0, B=2.8, C=0.0, soil_factor=1.0, width=20.0, depth=8.0),
                 Draft("cart2", A=3700.0, width=3.0))
        tr = dataclasses.replace(tr, draft=tr.draft + extra)
    return tr


def states(model, seed, count=20):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        y = trains.random_state(model, rng, steering=0.7, slow=True)
        yield y, rng.uniform(-1.0, 1.0), rng.uniform(-1, 4)  # commands past the actuator's max_angle too


def headland():
    return load_scene(REPO / "config" / "scenes" / "headland_turn.yaml")


# -- the equations against the reference ------------------------------------------------------------

@pytest.mark.parametrize("n", [1, 2, 3, 5, 20, 100])
@pytest.mark.parametrize("law", list(LAWS))
def test_kernel_rhs_equals_the_reference_path_bit_for_bit(n, law):
    model = Model(train(n, LAWS[law]))
    for y, command, v_set in states(model, 100 * n + len(law)):
        reference, _ = model.derivative(y, command, v_set)  # chain.chain + Terms
        fast = model.rhs(0.0, y, command, v_set)
        assert fast.dtype == reference.dtype and fast.shape == reference.shape
        np.testing.assert_array_equal(fast, reference)
        np.testing.assert_array_equal(kernel.rhs_of.py_func(model.P, y, command, v_set, kernel.max_rate_of(model.P)),
                                      reference)


@pytest.mark.parametrize("law", list(LAWS))
def test_a_rate_limit_held_as_an_input_is_the_reference_with_that_limit(law):
    """The steering rate limit is an input beside the state (ackermann_cmd's steering_angle_velocity):
    the kernel under a held limit equals the reference path under it, the actuator's rate is
    clipped to it, and the model's constants are not touched."""
    model = Model(train(3, LAWS[law]))
    packed = model.P.copy()
    for (y, command, v_set), rate in zip(states(model, 11 + len(law)), np.geomspace(1e-3, 5.0, 20)):
        reference, terms = model.derivative(y, command, v_set, rate)
        np.testing.assert_array_equal(model.rhs(0.0, y, command, v_set, rate), reference)
        act = model.train.actuator  # the actuator law of MODEL.md with the held limit in place of max_rate
        target = min(max(command, -act.max_angle), act.max_angle)
        assert terms.steering_rate == min(max((target - y[model.layout.steering]) / act.time_constant, -rate), rate)
    np.testing.assert_array_equal(model.P, packed)
    np.testing.assert_array_equal(model.P, kernel.pack(model.train))


@pytest.mark.parametrize("n", [1, 3, 5])
def test_kernel_rhs_equals_algorithm_1(n):
    """The holonomic equations reduced by G (holonomic.py) give the same y' to round-off."""
    for law in ("governor", "constant", "prescribed_speed"):
        a1, a2 = Model(train(n, LAWS[law]), algorithm=1), Model(train(n, LAWS[law]), algorithm=2)
        for y, command, v_set in states(a1, n, count=10):
            np.testing.assert_allclose(a2.rhs(0.0, y, command, v_set), a1.rhs(0.0, y, command, v_set),
                                       rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("n", [1, 2, 4])
def test_kinematic_kernel_equals_the_chain(n):
    model = KinematicModel(train(n, trains.GOVERNOR))
    for y, command, v_set in states(model, 7 * n):
        np.testing.assert_array_equal(model.rhs(0.0, y, command, v_set), model.reference_rhs(0.0, y, command, v_set))


def assert_outputs_equal(got, ref, rtol=0.0):
    for field in dataclasses.fields(ref):
        a, b = getattr(got, field.name), getattr(ref, field.name)
        if isinstance(b, np.ndarray):
            assert a.shape == b.shape, field.name
            np.testing.assert_allclose(a, b, rtol=rtol, atol=0.0, err_msg=field.name)
        else:
            assert a == pytest.approx(b, rel=rtol, abs=1e-300), field.name


@pytest.mark.parametrize("n", [1, 2, 3, 5, 20])
@pytest.mark.parametrize("law", list(LAWS))
def test_kernel_outputs_equal_the_reference_outputs(n, law):
    """Every field; the resistance power is a sum in another order (rtol 1e-14), the rest exact."""
    model = Model(train(n, LAWS[law]))
    rng = np.random.default_rng(n)
    for y, command, v_set in states(model, 7 * n + len(law)):
        t = rng.uniform(0, 100)
        ref = reference_outputs(model, t, y, command, v_set)
        got = model.outputs(t, y, command, v_set)
        assert got.resistance_power == pytest.approx(ref.resistance_power, rel=1e-13, abs=1e-9)
        got.resistance_power = ref.resistance_power
        assert_outputs_equal(got, ref)
        assert got.jackknife_margin == jackknife_margin(model, y)[0]


def test_kinematic_outputs_are_its_inverse_dynamics():
    """The kinematic level reports the traction that gives its prescribed ramp (model.terms)."""
    model = KinematicModel(train(3, trains.GOVERNOR))
    for y, command, v_set in states(model, 3):
        ref = reference_outputs(model, 1.0, y, command, v_set)
        got = model.outputs(1.0, y, command, v_set)
        got.resistance_power = pytest.approx(ref.resistance_power, rel=1e-13)
        assert got.traction == ref.traction and got.kinetic_energy == ref.kinetic_energy


def test_hitch_angles_past_pi_are_wrapped():
    sim = Simulation(headland(), fidelity="dynamic")
    first = sim.model.layout.heading.start
    sim.y[first + 1] = sim.y[first] - 3.5  # phi_2 = 3.5 rad
    assert sim.outputs().hitch_angle[0] == pytest.approx(3.5 - 2 * math.pi, abs=1e-15)
    assert sim.outputs().hitch_angle[0] == pytest.approx(
        reference_outputs(sim.model, 0.0, sim.y, 0.0, 3.0).hitch_angle[0], abs=1e-15)


# -- compiled against plain Python -----------------------------------------------------------------

needs_numba = pytest.mark.skipif(not jit.ENABLED, reason=f"compiled half of a comparison: {jit.NOTE}")


def test_numba_runs_here():
    """numba is a requirement (requirements.txt, package.xml): its absence is a failure here. The
    kernels' plain-Python life is tested by every comparison below and by the NO_JIT process."""
    assert jit.ENABLED, jit.NOTE


@needs_numba
@pytest.mark.parametrize("method", list(TABLEAUX))
@pytest.mark.parametrize("n", [1, 3, 5])
@pytest.mark.parametrize("split", [False, True])
def test_compiled_tick_equals_plain_python(method, n, split):
    model = Model(train(n, trains.GOVERNOR))
    T = TABLEAUX[method].packed
    for y, command, v_set in states(model, n, count=10):
        y[model.layout.speed] = abs(y[model.layout.speed]) + 0.5
        for step in (0.01, 0.004, 0.0031):  # 1, 3 and 4 steps per 10 ms tick
            args = (model.P, T, y, command, v_set, kernel.max_rate_of(model.P), 3.0, 3.01, step, split)
            a, b = rk.tick(*args), rk.tick.py_func(*args)
            np.testing.assert_array_equal(a[0], b[0])
            assert a[1:] == b[1:]


@needs_numba
@pytest.mark.parametrize("n", [1, 2, 5, 20])
def test_compiled_outputs_and_guards_equal_plain_python(n):
    model = Model(train(n, trains.GOVERNOR))
    rate = kernel.max_rate_of(model.P)
    for y, command, v_set in states(model, n):
        for a, b in zip(kernel.outputs_of(model.P, y, command, v_set, rate),
                        kernel.outputs_of.py_func(model.P, y, command, v_set, rate)):
            np.testing.assert_array_equal(a, b)
        assert kernel.margin_of(model.P, y) == kernel.margin_of.py_func(model.P, y)
        np.testing.assert_array_equal(kernel.switches_of(model.P, y, command, v_set),
                                      kernel.switches_of.py_func(model.P, y, command, v_set))
        assert kernel.release_of(model.P, y[n + 2], command, rate) == kernel.release_of.py_func(model.P, y[n + 2],
                                                                                                 command, rate)


@needs_numba
def test_headland_u_turn_compiled_equals_python_at_every_tick():
    scene = dataclasses.replace(headland(), duration=30.0)
    fast = Simulation(scene, fidelity="dynamic")
    slow = Simulation(scene, fidelity="dynamic", compiled=False)
    assert fast.compiled is True and slow.compiled is False
    ticks = int(math.floor(scene.duration / fast.tick + 1e-9))
    for _ in range(ticks):
        u = fast.scheduled_inputs(fast.t)
        np.testing.assert_array_equal(fast.advance(*u), slow.advance(*u))
    assert fast.stepper.nfev == slow.stepper.nfev and fast.kinks == slow.kinks
    assert_outputs_equal(fast.outputs(), slow.outputs())


# -- the packed constants -------------------------------------------------------------------------

def test_the_packed_constants_are_the_trains():
    tr = train(4, trains.GOVERNOR)
    P = kernel.pack(tr)
    assert P.shape == (kernel.HEAD_SIZE + kernel.CART_SIZE * tr.n + kernel.DRAFT_SIZE * len(tr.draft),)
    assert kernel.column(P, "length") == tuple(c.length for c in tr.carts)
    assert kernel.column(P, "lam") == tuple(c.hitch_offset / c.length for c in tr.carts)
    assert kernel.column(P, "mass") == tuple(c.mass for c in tr.carts)
    assert kernel.column(P, "max_hitch") == tuple(c.max_hitch_angle for c in tr.carts)
    rolling = [sum(r.coefficient * c.mass * tr.gravity for r in tr.rolling if r.cart == c.name) for c in tr.carts]
    assert kernel.column(P, "rolling") == tuple(rolling)
    # the drafts, grouped by cart in cart order, each where its cart says
    counts = kernel.column(P, "draft_count")
    assert sum(counts) == len(tr.draft)
    for k, cart in enumerate(tr.carts):
        first = int(kernel.column(P, "draft_first")[k])
        mine = [d for d in tr.draft if d.cart == cart.name]
        assert counts[k] == len(mine)
        for i, d in enumerate(mine):
            base = kernel.HEAD_SIZE + kernel.CART_SIZE * tr.n + kernel.DRAFT_SIZE * (first + i)
            assert tuple(P[base:base + kernel.DRAFT_SIZE]) == (d.soil_factor, d.A, d.B, d.C, d.width, d.depth)
    assert P[kernel.H.max_power] == tr.traction.max_power and P[kernel.H.law] == kernel.GOVERNOR
    # every field is declared with its meaning, once
    for fields in (kernel.HEAD, kernel.CART, kernel.DRAFT):
        names = [row[0] for row in fields.rows]
        assert len(set(names)) == len(names) == fields.size and all(fields.meaning.values())


# -- Simulation's choice of path --------------------------------------------------------------------

@needs_numba
def test_the_compiled_kernels_are_the_default_and_compile_at_construction():
    sim = Simulation(headland())
    assert sim.level == "dynamic" and sim.method == "rk4" and sim.compiled is True, sim.compiled_note
    signatures = len(rk.tick.signatures)
    sim.advance(0, 3)  # ints: converted, not a new specialization compiled in the tick
    sim.advance(np.float64(0.1), 3.0)
    assert len(rk.tick.signatures) == signatures
    assert sim.stepper.nfev == 2 * 4 * math.ceil(sim.tick / sim.stepper_step - 1e-9)


#: MTA_SIM_NO_JIT set once numba is loaded, in a process of its own (its own environment): the
#: compiled default gives way to it, an explicit request does not.
SET_AFTER_IMPORT = """
    import os, sys
    from mta_sim_ros import jit
    from mta_sim_ros.physics.loader import load_scene
    from mta_sim_ros.run.simulation import NO_JIT_ENV, Simulation
    scene = load_scene(sys.argv[1])
    os.environ[NO_JIT_ENV] = "1"
    env = Simulation(scene, fidelity="dynamic")
    assert env.compiled is False and NO_JIT_ENV in env.compiled_note, env.compiled_note
    if jit.ENABLED:
        assert Simulation(scene, fidelity="dynamic", compiled=True).compiled is True  # an explicit request wins
    print(jit.ENABLED)
"""


@pytest.mark.slow
def test_switches_keep_the_python_path():
    scene = headland()
    off = Simulation(scene, fidelity="dynamic", compiled=False)
    assert off.compiled is False and "compiled=False" in off.compiled_note
    assert Simulation(scene, fidelity="kinematic").compiled is jit.ENABLED  # the kinematic level has kernels
    assert Simulation(scene, fidelity="dynamic", algorithm=1).compiled is None  # the reference path
    assert Simulation(scene, fidelity="slip").compiled is None
    done = python(SET_AFTER_IMPORT, str(REPO / "config/scenes/headland_turn.yaml"))
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == str(jit.ENABLED)  # numba ran there as here


@pytest.mark.slow
def test_without_numba_the_same_source_runs_as_python():
    """MTA_SIM_NO_JIT=1 at import: numba is not even imported, and a run gives the compiled run's
    numbers to the last bit."""
    code = ("import sys, numpy as np; from mta_sim_ros.run.simulation import run_scene; "
            "from mta_sim_ros.physics.loader import load_scene; from mta_sim_ros import jit; "
            f"sim, err = run_scene(load_scene({str(REPO / 'config/scenes/headland_turn.yaml')!r}), fidelity='dynamic'); "
            "assert 'numba' not in sys.modules and not jit.ENABLED and sim.compiled is False; "
            "print(repr(sim.y.tolist()))")
    done = python(code, env={NO_JIT_ENV: "1"}, timeout=600)
    assert done.returncode == 0, done.stderr
    sim, err = run_scene(headland(), fidelity="dynamic")
    assert err is None and eval(done.stdout) == sim.y.tolist()


def test_a_jackknife_stops_both_paths_at_the_same_tick_with_the_same_message():
    """An impossible steady turn (test_physics): the kernel's screen hands the state near the
    limit to guards.check_state, which words the error."""
    tr = trains.train(3)
    sc = trains.scene(tr, table=((0.0, 1.0), (0.0, 0.45)), duration=120.0, rate=20.0)
    sim_a, err_a = run_scene(sc)
    sim_b, err_b = run_scene(sc, compiled=False)
    assert isinstance(err_a, ModelValidityError) and "jackknife" in str(err_a)
    assert str(err_a) == str(err_b) and err_a.time == err_b.time and err_a.cart == err_b.cart
    np.testing.assert_array_equal(sim_a.y, sim_b.y)


def test_a_non_finite_state_stops_the_run():
    for compiled in (None, False):
        sim = Simulation(headland(), fidelity="dynamic", compiled=compiled)
        y = sim.y.copy()
        y[sim.model.layout.governor] = math.inf
        sim.y = y
        with pytest.raises(ModelValidityError, match="non-finite"):
            sim.advance(0.0, 3.0)
        assert sim.ticks == 0
