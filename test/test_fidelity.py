"""Fidelity levels (fidelity.py, model/kinematic.py, model/slip.py) against what must hold:
kinematic = dynamic when the speed is held exactly; the kinematic power balance; slip -> dynamic
as the cornering stiffness grows (error ~ 1/C); auto picks by its rules on both sides of each."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import trains

from mta_sim_ros.physics.slip import SlipModel, axle_stiffness, no_slip_tyre_forces
from mta_sim_ros.physics.spec import Needs, Table, Traction
from mta_sim_ros.run import fidelity
from mta_sim_ros.run.simulation import Simulation, run_scene, start_state

SINE = (tuple(np.linspace(0.0, 12.0, 49)), tuple(0.2 * np.sin(2 * math.pi * np.linspace(0.0, 12.0, 49) / 8.0)))
TURN = ((0.0, 1.0, 2.0), (0.0, 0.0, 0.2))


def record(scene, level, **kw):
    outs = []
    sim, err = run_scene(scene, on_output=outs.append, fidelity=level, **kw)
    assert err is None, err
    return outs, sim


def points(outs):
    return np.array([np.vstack((o.front[:1], o.axle)) for o in outs])


def pose_error(a, b) -> float:
    d = points(a) - points(b)
    return float(np.max(np.hypot(d[..., 0], d[..., 1])))


# -- kinematic = dynamic when the speed is held ----------------------------------------------
def test_kinematic_equals_dynamic_with_the_speed_held_exactly():
    """With the prescribed-speed law started at its set speed, V' = 0 in the dynamic level too:
    both integrate the same q' = G V with the same V, and the dynamic level's traction is the same
    inverse dynamics. Poses agree to the integrator's round-off, traction to round-off of F."""
    tr = trains.train(3, traction=trains.prescribed(3.0))
    sc = trains.scene(tr, table=SINE, duration=12.0, rate=50.0)
    kin, _ = record(sc, "kinematic")
    dyn, _ = record(sc, "dynamic")
    assert pose_error(kin, dyn) < 1e-9
    scale = max(abs(o.traction) for o in dyn)
    assert max(abs(a.traction - b.traction) for a, b in zip(kin, dyn)) < 1e-9 * scale
    assert max(abs(a.power - b.power) for a, b in zip(kin, dyn)) < 1e-9 * scale * 3.0


def governed(gain: float):
    """The test governor with kp x gain, critically damped (ki = kp^2 / (4 M), M = sum m_k)."""
    tr = trains.train(3)
    mass = sum(c.mass for c in tr.carts)
    kp = trains.GOVERNOR.kp * gain
    return dataclasses.replace(tr, traction=dataclasses.replace(trains.GOVERNOR, kp=kp, ki=kp * kp / (4 * mass)))


def test_kinematic_is_the_limit_of_a_governor_that_holds_speed():
    """The governor holds V at the set speed better as its gain grows (speed error of a PI loop
    with ki = kp^2/(4M) to a slow disturbance ~ 1/kp^2): the dynamic level tends to the kinematic
    one. Poses, speed and traction (inverse dynamics vs the governor's force) converge; each 4x
    in gain cuts the pose and speed errors at least 3x (1/kp would be 4x); the traction difference,
    M V' of the governor's response to the kinks of the rate-limited steering, at least 2x."""
    errs = []
    for gain in (1.0, 4.0, 16.0):
        sc = trains.scene(governed(gain), table=SINE, duration=12.0, rate=50.0, method="rk4", step=0.005)
        kin, _ = record(sc, "kinematic")
        dyn, _ = record(sc, "dynamic")
        traction = max(abs(a.traction - b.traction) for a, b in zip(kin, dyn))
        errs.append((pose_error(kin, dyn), max(abs(a.speed - b.speed) for a, b in zip(kin, dyn)), traction))
    for coarse, fine in zip(errs, errs[1:]):
        for c, f, factor in zip(coarse, fine, (3.0, 3.0, 2.0)):
            assert f < c / factor, errs
    # at the stiffest gain the traction agrees to 1 % of the resistances it balances
    resist = sum(o.resistance_power for o in kin) / sum(o.speed for o in kin)
    assert errs[-1][2] < 0.01 * resist, errs


def test_kinematic_power_balance():
    """F_A1 V - sum F_Bk s'_Bk = dT/dt along a kinematic run (speed ramp and steering): the
    inverse dynamics against T = 1/2 M V^2 differentiated by central differences, O(h^2)."""
    tr = trains.train(3)
    # steering held from the start (a held command has a kink in psi_1' at every tick, which a
    # central difference of T would average): the train bends from straight into the circle
    sc = dataclasses.replace(trains.scene(tr, table=((0.0,), (0.15,)), duration=8.0, rate=400.0, step=0.0025,
                                          steering=0.15), speed=Table((0.0, 8.0), (3.0, 2.0)))
    outs, _ = record(sc, "kinematic")
    T = np.array([o.kinetic_energy for o in outs])
    h = outs[1].t - outs[0].t
    dT = (T[2:] - T[:-2]) / (2 * h)
    applied = np.array([o.power - o.resistance_power for o in outs])[1:-1]
    inner = slice(10, -10)  # away from the start of the ramp (the first tick's V' = 0)
    scale = np.max(np.abs(applied[inner]))
    assert np.max(np.abs(applied[inner] - dT[inner])) < 1e-6 * scale


def test_kinematic_needs_a_commanded_speed():
    tr = trains.train(2, traction=Traction("constant", force=4e4))
    with pytest.raises(ValueError, match="does not command a speed"):
        Simulation(trains.scene(tr), fidelity="kinematic")


# -- slip -> dynamic -------------------------------------------------------------------------
def stiffer(tr, factor):
    front, rear = axle_stiffness(tr)
    return dataclasses.replace(tr, carts=tuple(dataclasses.replace(c, cornering_stiffness=factor * float(r))
                                               for c, r in zip(tr.carts, rear)))


@pytest.mark.slow
def test_slip_converges_to_dynamic_as_cornering_stiffness_grows():
    """Side slips are F_lat / C_alpha, so the slip level's departure from the no-slip paths falls
    like 1/C_alpha: each 10x in stiffness cuts the pose and hitch-angle errors 10x (within 7-13x)."""
    tr = trains.train(3)
    dyn, _ = record(trains.scene(tr, table=TURN, duration=8.0, rate=20.0), "dynamic")
    errs = []
    for factor in (3.0, 30.0, 300.0):
        slip, _ = record(trains.scene(stiffer(tr, factor), table=TURN, duration=8.0, rate=20.0), "slip")
        hitch = max(float(np.max(np.abs(a.hitch_angle - b.hitch_angle))) for a, b in zip(slip, dyn))
        errs.append((pose_error(slip, dyn), hitch))
    for coarse, fine in zip(errs, errs[1:]):
        for c, f in zip(coarse, fine):
            assert 7.0 < c / f < 13.0, errs


def test_slip_state_starts_moving_as_the_no_slip_one():
    """At t = 0 the slip level moves as the dynamic one (u = G V): same outputs of motion."""
    tr = trains.train(3)
    sc = trains.scene(tr, hitch_angles=(0.1, -0.05), steering=0.1)
    slip, dyn = Simulation(sc, fidelity="slip").outputs(), Simulation(sc, fidelity="dynamic").outputs()
    for name in ("front", "axle", "heading", "psi", "com_speed", "axle_speed", "yaw_rate"):
        np.testing.assert_allclose(getattr(slip, name), getattr(dyn, name), rtol=1e-12, atol=1e-12, err_msg=name)
    assert slip.kinetic_energy == pytest.approx(dyn.kinetic_energy, rel=1e-12)
    assert slip.traction == pytest.approx(dyn.traction, rel=1e-12)


def test_no_slip_tyre_forces_are_the_constraint_forces():
    """The slip level with the tyre forces that no_slip_tyre_forces returns added accelerates as the
    no-slip level: its residual vanishes (the least-squares system is consistent)."""
    tr = trains.train(3)
    sc = trains.scene(tr, hitch_angles=(0.2, -0.1), steering=0.15)
    model = SlipModel(tr)
    y = start_state(sc, model.dynamic)
    front, rear = no_slip_tyre_forces(model, y, 0.15, 3.0)
    # rebuild the no-slip acceleration from the slip equations plus these forces
    tm = model.dynamic.terms(y, 0.15, 3.0)
    from mta_sim_ros.physics.holonomic import HolonomicReduction

    heading = y[2:5]
    G, G_dot = HolonomicReduction.constraint_matrix(heading, 0.15, tm.chain, tm.steering_rate, 3.0)
    ys = model.from_dynamic_state(y)
    base = model.terms(ys, 0.15, 3.0).accel
    Mh = model._hol.mass_matrix(heading)
    course = heading[0] + 0.15
    Q = front * np.concatenate(([-math.sin(course), math.cos(course)], np.zeros(3)))
    N = np.stack((-np.sin(heading), np.cos(heading)), axis=1)
    for k in range(3):
        Q[:2] += rear[k] * N[k]
        Q[2:] += rear[k] * model._DB[k] * (N @ N[k])
    np.testing.assert_allclose(base + np.linalg.solve(Mh, Q), G * tm.acceleration + G_dot * 3.0, atol=1e-9)
    assert abs(front) + np.sum(np.abs(rear)) > 100.0  # a turn with bent hitches needs real side forces


@pytest.mark.slow
def test_slip_level_default_method_survives_low_speed():
    """At low speed the tyres' lateral damping C/sqrt(V^2 + v0^2) gives eigenvalues of several
    hundred 1/s, past RK4's stability limit 2.785/h at h = 0.01 s. At 0.1 m/s with bent hitches
    the default (stiff-capable) method stays on a tight Radau reference; RK4 at 0.01 s does not
    (it chatters, bounded only by the saturation of atan in the slip angle)."""
    tr = trains.train(3, traction=dataclasses.replace(trains.GOVERNOR, set_speed=0.1))
    sc = trains.scene(tr, duration=3.0, rate=50.0, speed=0.1, hitch_angles=(0.087, -0.087))
    tight = Simulation(sc, fidelity="slip", method="Radau", step=0.02)
    tight.rtol = tight.atol = 1e-10
    tight.reset()  # a fresh stepper with these tolerances
    ref = [tight.outputs()]
    while tight.ticks < 150:
        tight.advance(*tight.scheduled_inputs(tight.t))
        ref.append(tight.outputs())
    default, sim = record(sc, "slip")
    assert sim.method == "LSODA"
    rk4, _ = record(sc, "slip", method="rk4", step=0.01)
    assert pose_error(default, ref) < 1e-4
    assert pose_error(rk4, ref) > 1e-2


# -- auto ------------------------------------------------------------------------------------
def with_needs(sc, **needs):
    return dataclasses.replace(sc, needs=Needs(**needs))


def test_auto_without_needs_keeps_the_article_model_and_forcing_wins():
    sc = trains.scene(trains.train(3), table=TURN)
    assert fidelity.choose(sc).level == "dynamic"
    assert "no needs" in fidelity.choose(sc).reason
    assert fidelity.choose(sc, forced="slip").level == "slip"
    assert fidelity.choose(dataclasses.replace(sc, fidelity="kinematic")).level == "kinematic"
    with pytest.raises(ValueError):
        fidelity.choose(sc, forced="exact")


def test_auto_speed_rule_both_sides():
    """Straight at a commanded speed: prescribing the speed costs a distance error a M / ki (times
    GOVERNOR_MARGIN) on a ramp of slope a. A ramp predicted at 0.6x a 0.5 m tolerance sits under
    it (kinematic), one at 1.6x over it (dynamic). (An engine that holds the ramp's last speed: at
    trains.GOVERNOR's 250 kW it could not, test_a_speed_the_governor_cannot_hold_rules_out_kinematic.)"""
    tr = trains.train(3, traction=dataclasses.replace(trains.GOVERNOR, max_power=1e6))
    mass = sum(c.mass for c in tr.carts)
    ki = tr.traction.ki
    at_tolerance = 0.5 * ki / mass / fidelity.GOVERNOR_MARGIN  # the slope whose prediction is 0.5 m
    for slope, level in ((0.6 * at_tolerance, "kinematic"), (1.6 * at_tolerance, "dynamic")):
        sc = dataclasses.replace(trains.scene(tr, duration=20.0), speed=Table((0.0, 5.0), (3.0, 3.0 + 5 * slope)))
        choice = fidelity.choose(with_needs(sc, poses=0.5))
        assert choice.level == level, choice.reason


def test_auto_power_rule_both_sides():
    """Power asked: the kinematic level misses the governor's M V' while the speed changes; with
    the speed constant it is within the tolerance, with a ramp of 0.25 m/s^2 it is not."""
    tr = trains.train(3)
    flat = trains.scene(tr, duration=20.0)
    assert fidelity.choose(with_needs(flat, power=0.05)).level == "kinematic"
    ramp = dataclasses.replace(flat, speed=Table((0.0, 4.0), (3.0, 2.0)))
    assert fidelity.choose(with_needs(ramp, power=0.05)).level == "dynamic"


def test_auto_slip_rule_both_sides():
    """A turn whose predicted side-slip drift is under the pose tolerance stays no-slip; the same
    turn with a tolerance under the prediction (or much softer tyres) needs the slip level."""
    tr = trains.train(3)
    sc = trains.scene(tr, table=TURN, duration=20.0)
    drift = fidelity.estimate(sc)["dynamic"]["poses"]
    assert drift > 0
    assert fidelity.choose(with_needs(sc, poses=2 * drift)).level in ("kinematic", "dynamic")
    assert fidelity.choose(with_needs(sc, poses=0.5 * drift)).level == "slip"
    soft = dataclasses.replace(sc, train=stiffer(tr, 0.1))
    assert fidelity.choose(with_needs(soft, poses=2 * drift)).level == "slip"
    straight = trains.scene(tr, duration=20.0)
    assert fidelity.choose(with_needs(straight, poses=0.01)).level == "kinematic"


def test_auto_never_picks_kinematic_without_a_commanded_speed():
    """A constant force: no speed to prescribe, and none the predictions could read (the speed is what
    force and resistances make of it): auto, asked for an error, takes slip and says why."""
    tr = trains.train(2, traction=Traction("constant", force=4e4))
    sc = trains.scene(tr, duration=20.0)
    choice = fidelity.choose(with_needs(sc, poses=10.0))
    assert choice.level == "slip" and "constant sets a force, not a speed" in choice.reason, choice.reason


# -- where no prediction bounds the error: a towed train reversing ----------------------------------

def test_a_towed_train_reversing_has_no_bounded_prediction_and_auto_takes_slip():
    """Reversing, every hitch mode grows at |V| / l_k: the no-slip levels' predictions are inf (a
    bound, if a useless one) and auto, asked for any error, takes slip and says why. A tractor alone,
    or the same train forward, keeps its finite predictions."""
    from mta_sim_ros.config import resolve_config_path
    from mta_sim_ros.physics.loader import load_scene

    scene = load_scene(resolve_config_path("scenes/reversing.yaml"))
    assert scene.initial.speed < 0 and scene.train.n == 3
    assert "reverses a towed train" in fidelity.unbounded(scene)
    est = fidelity.estimate(scene)
    assert all(math.isinf(v) for level in ("kinematic", "dynamic") for v in est[level].values())
    choice = fidelity.choose(with_needs(scene, hitch_angles=0.5))
    assert choice.level == "slip" and "reverses a towed train, whose hitch modes grow" in choice.reason
    forward = dataclasses.replace(scene, initial=dataclasses.replace(scene.initial, speed=2.0),
                                  speed=Table((0.0,), (2.0,)))
    alone = dataclasses.replace(scene, train=trains.train(1), initial=dataclasses.replace(scene.initial, hitch_angles=()))
    for bounded in (forward, alone):
        assert fidelity.unbounded(bounded) == ""
        assert all(math.isfinite(v) for v in fidelity.estimate(bounded)["dynamic"].values())
    for force in (-2e4, 0.0, 1.5e5):  # a force, not a speed: whatever it makes of the speed is not an input
        pushed = dataclasses.replace(trains.scene(trains.train(1, traction=Traction("constant", force=force))))
        assert "constant sets a force, not a speed" in fidelity.unbounded(pushed)


@pytest.mark.slow
@pytest.mark.parametrize("name, carts", [("reversing", None), ("reversing", 2), ("straight_pass", None),
                                         ("headland_turn", 4)])
def test_no_level_is_measured_above_its_prediction(name, carts):
    """Each level's errors against slip (benchmarks/accuracy/fidelity.py's compare, which writes
    docs/fidelity.md) within its predictions, on shipped scenes and with generated trains, forward
    and reversing."""
    from benchmarks.accuracy.fidelity import compare
    from benchmarks.common import random_train

    from mta_sim_ros.config import resolve_config_path
    from mta_sim_ros.physics.loader import load_scene

    scene = load_scene(resolve_config_path(f"scenes/{name}.yaml"))
    if carts:
        scene = dataclasses.replace(scene, train=random_train(carts, np.random.default_rng(carts)),
                                    initial=dataclasses.replace(scene.initial, hitch_angles=()))
    rows, over, unverified = compare(scene, 1)
    assert over == [], over
    assert name == "reversing" or unverified == [], unverified  # forward, every run goes the whole way
    if name == "reversing":  # the dynamic level's row: no finite prediction bounds it
        assert all(cell.endswith("(inf)") for cell in rows[1][2:6]), rows[1]


def test_a_speed_the_governor_cannot_hold_rules_out_kinematic():
    """A set speed whose steady force (resistances and drafts) is over the governor's limit
    min(max_force, max_power / V): the dynamic level settles below it, so the kinematic level, which
    prescribes it, has no bounded prediction; auto says why. With power to spare, it has one."""
    tr = trains.train(3)
    fast = dataclasses.replace(trains.scene(tr, duration=30.0, speed=4.5), speed=Table((0.0,), (4.5,)))
    why = fidelity.unheld_speed(fast)
    assert why.startswith("the governor cannot hold 4.5 m/s: the steady force it needs")
    assert all(math.isinf(v) for v in fidelity.estimate(fast)["kinematic"].values())
    choice = fidelity.choose(with_needs(fast, speed=1.0))
    assert choice.level == "dynamic" and why in choice.reason
    outs, _ = record(fast, "dynamic")
    settled = [o.speed for o in outs if o.t >= 20.0]  # what the rule says: it levels off below the set speed
    assert max(settled) < 4.5 - 0.1 and max(settled) - min(settled) < 0.02, (min(settled), max(settled))
    strong = dataclasses.replace(fast, train=dataclasses.replace(tr, traction=dataclasses.replace(
        trains.GOVERNOR, max_power=1e6)))
    assert fidelity.unheld_speed(strong) == ""
    assert abs(record(strong, "dynamic")[0][-1].speed - 4.5) < 0.01

