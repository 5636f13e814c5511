"""The compiled tick (model/compiled.py, numba) against the Python reference path.

- ``compiled.rhs`` equals ``Model.rhs`` (algorithm 2) for random states of 1..5 (and 20) carts
  under every traction law, drafts on several carts, governor with and without a power limit;
  ``CompiledModel.tick`` equals ``FixedStep.advance`` for euler, heun and rk4. Tolerance 1e-12
  relative (libm may differ between machines); here they agree to the last bit.
- A whole scene (the headland U-turn, the default train) run compiled and in Python agrees to
  1e-12 relative at every tick; a jackknife stops both at the same tick with the same message.
- ``Simulation`` uses the compiled tick by default (so it cannot silently fall back), compiles
  when it is built (not in the first tick), and keeps the Python path with ``compiled=False``,
  ``MTA_SIM_NO_JIT=1``, adaptive methods and the other fidelity levels.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

# No importorskip: numba is a requirement (requirements.txt, package.xml), so a missing numba is a
# failure here, not a silently skipped module. (The Python path without numba is covered by
# test_switches_keep_the_python_path below: MTA_SIM_NO_JIT, compiled=False.)
import numba  # noqa: E402

NUMBA_VERSION = numba.__version__

from mta_sim_ros.integrate.steppers import FixedStep  # noqa: E402
from mta_sim_ros.model import compiled  # noqa: E402
from mta_sim_ros.model.dynamics import Model  # noqa: E402
from mta_sim_ros.model.guards import ModelValidityError  # noqa: E402
from mta_sim_ros.model.loader import load_scene  # noqa: E402
from mta_sim_ros.model.spec import Draft  # noqa: E402
from mta_sim_ros.sim import NO_JIT_ENV, Simulation, run_scene  # noqa: E402

import trains  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
RTOL = 1e-12

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
    import dataclasses

    tr = trains.train(carts=[trains.CARTS[k % len(trains.CARTS)] for k in range(n)], traction=traction)
    if n > 1:
        extra = (Draft("cart2", A=46.0, B=2.8, C=0.0, soil_factor=1.0, width=20.0, depth=8.0),
                 Draft("cart2", A=3700.0, width=3.0))
        tr = dataclasses.replace(tr, draft=tr.draft + extra)
    return tr




def assert_close(a, b, rtol=RTOL):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype == np.float64
    if not a.size:
        return
    scale = np.maximum(np.abs(b), 1.0)
    worst = float(np.max(np.abs(a - b) / scale))
    assert worst <= rtol, f"compiled and Python differ by {worst:.3g} (relative)"


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 20])
@pytest.mark.parametrize("law", list(LAWS))
def test_compiled_rhs_equals_the_python_rhs(n, law):
    model = Model(train(n, LAWS[law]))
    cm = compiled.CompiledModel(model)
    rng = np.random.default_rng(100 * n + len(law))
    for _ in range(30):
        y = trains.random_state(model, rng, steering=0.7, slow=True)
        command, v_set = rng.uniform(-1.0, 1.0), rng.uniform(-1, 4)  # past the actuator's max_angle too
        assert_close(cm.rhs(y, command, v_set), model.rhs(0.0, y, command, v_set))


@pytest.mark.parametrize("method", ["euler", "heun", "rk4"])
@pytest.mark.parametrize("n", [1, 3, 5])
def test_compiled_tick_equals_the_python_stepper(method, n):
    model = Model(train(n, trains.GOVERNOR))
    cm = compiled.CompiledModel(model)
    rng = np.random.default_rng(n)
    for step in (0.01, 0.004, 0.0031):  # 1, 3 and 4 steps per 10 ms tick
        stepper = FixedStep(method, step)
        stepper.attach(cm)
        for _ in range(10):
            y = trains.random_state(model, rng, steering=0.7, slow=True)
            y[model.layout.speed] = abs(y[model.layout.speed]) + 0.5
            command, v_set = rng.uniform(-0.5, 0.5), rng.uniform(1, 4)
            t0 = rng.uniform(0, 100)
            ref = stepper.advance(lambda t, yy: model.rhs(t, yy, command, v_set), t0, y, t0 + 0.01)
            got, clear = stepper.advance_held(t0, y, t0 + 0.01, command, v_set)
            assert_close(got, ref)
            assert isinstance(clear, bool)


@pytest.mark.parametrize("n", [1, 2, 3, 5, 20])
@pytest.mark.parametrize("law", list(LAWS))
def test_compiled_outputs_equal_the_python_outputs(n, law):
    """CompiledModel.outputs (the node's tick) equals sim.evaluate_outputs field by field, at
    random states, speeds through 0 and commands past the actuator's limits."""
    import dataclasses

    from mta_sim_ros.sim import evaluate_outputs

    model = Model(train(n, LAWS[law]))
    cm = compiled.CompiledModel(model)
    rng = np.random.default_rng(7 * n + len(law))
    for _ in range(20):
        y = trains.random_state(model, rng, steering=0.7, slow=True)
        command, v_set, t = rng.uniform(-1.0, 1.0), rng.uniform(-1, 4), rng.uniform(0, 100)
        got, ref = cm.outputs(t, y, command, v_set), evaluate_outputs(model, t, y, command, v_set)
        assert got is not None
        for field in dataclasses.fields(ref):
            a, b = getattr(got, field.name), getattr(ref, field.name)
            if isinstance(b, np.ndarray):
                assert_close(a, b)
            else:
                assert a == pytest.approx(b, rel=RTOL, abs=1e-300), field.name


def test_compiled_outputs_leave_a_hitch_angle_past_pi_to_python():
    """A hitch angle outside [-pi, pi] (the Python path wraps it) makes the compiled outputs step
    aside (None); Simulation.outputs then gives the Python path's wrapped angle."""
    sim = Simulation(headland(), fidelity="dynamic")
    first = sim.model.layout.heading.start
    sim.y[first + 1] = sim.y[first] - 3.5  # phi_2 = 3.5 rad
    assert sim.compiled and sim._compiled.outputs(sim.t, sim.y, 0.0, 3.0) is None
    assert sim.outputs().hitch_angle[0] == pytest.approx(3.5 - 2 * math.pi)


def headland():
    return load_scene(REPO / "config" / "scenes" / "headland_turn.yaml")


def test_headland_u_turn_compiled_equals_python_at_every_tick():
    scene = headland()
    fast = Simulation(scene, fidelity="dynamic")
    slow = Simulation(scene, fidelity="dynamic", compiled=False)
    assert fast.compiled and not slow.compiled
    ticks = int(math.floor(scene.duration / fast.tick + 1e-9))
    worst = 0.0
    for _ in range(ticks):
        u = fast.scheduled_inputs(fast.t)
        a, b = fast.advance(*u), slow.advance(*u)
        worst = max(worst, float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1.0))))
    assert worst <= RTOL, worst
    assert fast.stepper.nfev == slow.stepper.nfev
    assert fast.stepper.compiled_ticks == ticks and slow.stepper.compiled_ticks == 0
    oa, ob = fast.outputs(), slow.outputs()
    assert_close(oa.axle, ob.axle)
    assert oa.power == pytest.approx(ob.power, rel=RTOL)


def test_the_compiled_tick_is_the_default():
    """Simulation of a shipped scene, no options: the dynamic level with rk4 runs compiled, every
    tick through the compiled stepper (a silent fall-back to Python would fail here)."""
    scene = headland()
    sim = Simulation(scene)
    assert sim.level == "dynamic" and sim.method == "rk4"
    assert sim.compiled, sim.compiled_note
    assert isinstance(sim.stepper, FixedStep) and isinstance(sim.stepper.compiled, compiled.CompiledModel)
    assert "compiled rk4 tick" in sim.compiled_note
    for _ in range(5):
        sim.advance(*sim.scheduled_inputs(sim.t))
    assert sim.stepper.compiled_ticks == 5
    assert sim.stepper.nfev == 5 * 4 * math.ceil(sim.tick / sim.stepper_step - 1e-9)
    sim.reset()  # a fresh stepper, still compiled
    assert sim.stepper.compiled is not None and sim.stepper.compiled_ticks == 0


def test_compiled_at_construction_not_in_the_first_tick():
    sim = Simulation(headland(), fidelity="dynamic")
    assert sim.compile_time > 0.0
    signatures = len(compiled._tick.signatures)
    sim.advance(0, 3)  # ints: converted, not a new specialization compiled in the tick
    sim.advance(np.float64(0.1), 3.0)
    assert len(compiled._tick.signatures) == signatures


def test_switches_keep_the_python_path(monkeypatch):
    scene = headland()
    off = Simulation(scene, fidelity="dynamic", compiled=False)
    assert not off.compiled and off.stepper.compiled is None and "compiled=False" in off.compiled_note
    adaptive = Simulation(scene, fidelity="dynamic", method="RK45")
    assert not adaptive.compiled and "no compiled form" in adaptive.compiled_note
    with pytest.raises(ValueError, match="no compiled path"):
        Simulation(scene, fidelity="dynamic", method="RK45", compiled=True)
    kinematic = Simulation(scene, fidelity="kinematic")
    assert not kinematic.compiled
    algorithm_1 = Simulation(scene, fidelity="dynamic", algorithm=1)
    assert not algorithm_1.compiled
    monkeypatch.setenv(NO_JIT_ENV, "1")
    env = Simulation(scene, fidelity="dynamic")
    assert not env.compiled and NO_JIT_ENV in env.compiled_note
    assert Simulation(scene, fidelity="dynamic", compiled=True).compiled  # an explicit request wins
    for sim in (off, env):
        sim.advance(0.1, 3.0)
        assert sim.stepper.compiled_ticks == 0


def test_a_jackknife_stops_both_paths_at_the_same_tick_with_the_same_message():
    """test_physics' impossible steady turn: the compiled screen hands the state near the limit to
    guards.check_state, which words the error."""
    tr = trains.train(3)
    sc = trains.scene(tr, table=((0.0, 1.0), (0.0, 0.45)), duration=120.0, rate=20.0)
    sim_a, err_a = run_scene(sc)
    sim_b, err_b = run_scene(sc, compiled=False)
    assert sim_a.compiled and not sim_b.compiled
    assert isinstance(err_a, ModelValidityError) and "jackknife" in str(err_a)
    assert str(err_a) == str(err_b) and err_a.time == err_b.time and err_a.cart == err_b.cart
    assert_close(sim_a.y, sim_b.y)


def test_a_non_finite_state_stops_the_compiled_run():
    sim = Simulation(headland(), fidelity="dynamic")
    y = sim.y.copy()
    y[sim.model.layout.governor] = math.inf
    sim.y = y
    with pytest.raises(ModelValidityError, match="non-finite"):
        sim.advance(0.0, 3.0)
    assert sim.ticks == 0
