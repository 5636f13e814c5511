"""The lateral force each no-slip axle gives (kernel.drawbar_pulls: cart[k, LAT], sc[FRONT_LAT])
against an independent derivation of the constraint forces, the axles' static loads against the
statics of the chain, and the grip margin (physics.loads, a sweep's min_grip_margin) against the
closed form of a train straight across a side slope: every axle 1 - tan(b) / mu.

no_slip_tyre_forces (physics/slip.py) finds the constraint forces another way: the slip level's
equations (Lagrange, the velocities free) at the no-slip level's state, least squares for the
multipliers that make its acceleration the no-slip one; the kernel solves Newton-Euler cart by
cart from the last forward.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import trains

from mta_sim_ros.physics import kernel, loader
from mta_sim_ros.physics.loads import grip_margins, static_axle_loads
from mta_sim_ros.physics.reader import SpecError
from mta_sim_ros.physics.slip import SlipModel, no_slip_tyre_forces
from mta_sim_ros.physics.terrain import Plane
from mta_sim_ros.run.batch import run_metrics

G = 9.80665


@pytest.mark.parametrize("n", [1, 2, 3, 5])
@pytest.mark.parametrize("terrain", [None, Plane(0.07, -0.15)])
def test_the_axles_lateral_forces_are_the_constraint_forces_found_another_way(n, terrain):
    """At random states (poses, hitch angles, steering, speeds forward and back) and inputs."""
    tr = dataclasses.replace(trains.train(n), terrain=terrain)
    slip = SlipModel(tr)
    model = slip.dynamic
    rng = np.random.default_rng(n)
    weight = sum(c.mass for c in tr.carts) * G
    for _ in range(20):
        y = trains.random_state(model, rng)
        command, v_set = rng.uniform(-0.5, 0.5), rng.uniform(0.0, 4.0)
        cart, sc = kernel.pulls_of(model.P, y, command, v_set, kernel.max_rate_of(model.P))
        front, rear = no_slip_tyre_forces(slip, y, command, v_set)
        assert sc[kernel.FRONT_LAT] == pytest.approx(front, abs=1e-12 * weight)
        np.testing.assert_allclose(cart[:, kernel.LAT], rear, rtol=0, atol=1e-12 * weight)


def test_static_axle_loads_are_the_statics_of_the_chain():
    """Tractor and trailer: the trailer's hitch carries V_2 = W_2 c_2 / l_2 and its axle the rest;
    the tractor's front axle (W_1 c_1 - V_2 a_1) / l_1 (V_2 hangs a_1 behind its rear axle). On a
    plane every load scales with cos(slope), and they add up to the weights."""
    tr = trains.train(2)
    t, c = tr.carts
    front, rear = static_axle_loads(tr)
    v2 = c.mass * G * c.com_offset / c.length
    assert rear[1] == pytest.approx(c.mass * G - v2, rel=1e-14)
    assert front == pytest.approx((t.mass * G * t.com_offset - v2 * t.hitch_offset) / t.length, rel=1e-14)
    assert front + rear[0] == pytest.approx(t.mass * G + v2, rel=1e-14)
    tilted = dataclasses.replace(trains.train(5), terrain=Plane(0.2, 0.1))
    f5, r5 = static_axle_loads(tilted)
    cos = 1 / math.sqrt(1 + 0.2 ** 2 + 0.1 ** 2)
    assert f5 + r5.sum() == pytest.approx(sum(k.mass for k in tilted.carts) * G * cos, rel=1e-14)
    level = static_axle_loads(trains.train(5))
    np.testing.assert_allclose(np.concatenate(([f5], r5)), cos * np.concatenate(([level[0]], level[1])), rtol=1e-14)


@pytest.mark.parametrize("cross", [0.1, 0.3])
def test_straight_across_a_side_slope_every_axle_s_grip_margin_is_1_less_tan_b_over_mu(cross):
    """At held speed straight along the contour of a side slope b, gravity across the carts,
    m g sin(b) at each C_k, spreads over the axles and hitches as its normal part m g cos(b) does
    (the same lever arms along the carts): each axle's lateral force is tan(b) times its static
    load, and its margin 1 - tan(b) / mu, 0 where tan(b) = mu."""
    mu = 0.45
    tr = dataclasses.replace(trains.train(3, traction=trains.prescribed(3.0)), terrain=Plane(0.0, cross),
                             lateral_friction=mu)
    model = SlipModel(tr).dynamic
    y = np.zeros(model.layout.size)
    y[model.layout.speed] = 3.0
    cart, sc = kernel.pulls_of(model.P, y, 0.0, 3.0, kernel.max_rate_of(model.P))
    front, rear = static_axle_loads(tr)
    assert sc[kernel.FRONT_LAT] == pytest.approx(cross * front, rel=1e-9)
    np.testing.assert_allclose(cart[:, kernel.LAT], cross * rear, rtol=1e-9)
    margins = grip_margins(tr, [sc[kernel.FRONT_LAT]], cart[None, :, kernel.LAT])
    np.testing.assert_allclose(margins, 1 - cross / mu, rtol=1e-9)
    got = run_metrics(trains.scene(tr, duration=4.0), fidelity="dynamic").metrics["min_grip_margin"]
    assert got == pytest.approx(1 - cross / mu, rel=1e-9)


def test_no_grip_margin_without_mu_or_at_the_slip_level():
    tr = dataclasses.replace(trains.train(2), terrain=Plane(0.0, 0.1))
    assert math.isnan(run_metrics(trains.scene(tr, duration=2.0), fidelity="dynamic").metrics["min_grip_margin"])
    gripping = dataclasses.replace(tr, lateral_friction=0.5)
    assert math.isnan(run_metrics(trains.scene(gripping, duration=2.0), fidelity="slip").metrics["min_grip_margin"])
    assert run_metrics(trains.scene(gripping, duration=2.0), fidelity="dynamic").metrics["min_grip_margin"] < 1


def test_an_unloaded_axle_that_must_hold_has_no_grip():
    """A trailer whose weight all sits on its hitch (c = l) leaves its axle unloaded: a lateral
    force there cannot be given (margin -inf); where none is needed the margin is 1."""
    tr = dataclasses.replace(trains.train(2), lateral_friction=0.5)
    heavy_front = dataclasses.replace(tr.carts[1], com_offset=tr.carts[1].length)
    tr = dataclasses.replace(tr, carts=(tr.carts[0], heavy_front))
    assert static_axle_loads(tr)[1][1] == pytest.approx(0.0, abs=1e-9)
    margins = grip_margins(tr, [0.0, 0.0], [[0.0, 0.0], [0.0, 10.0]])
    assert margins[0].tolist() == [1.0, 1.0, 1.0] and margins[1, 2] == -math.inf


@pytest.mark.parametrize("value", ["0", "-0.3", "2.5", ".nan", "high"])
def test_lateral_friction_out_of_range_is_one_line(value):
    text = open("config/trains/hillside_unit.yaml", encoding="utf-8").read()
    text = text.replace("name: hillside_unit\n", f"name: hillside_unit\nlateral_friction: {value}\n")
    with pytest.raises(SpecError) as err:
        loader.load_train_text(text, "t.yaml")
    message = str(err.value)
    assert "lateral_friction" in message and "\n" not in message


def test_an_adaptive_method_s_sweep_run_measures_the_same_forces():
    """A sweep's run with an adaptive method goes tick by tick (not the compiled whole run): its
    pulls and margins come from the same constraint forces at its states, equal to the fixed-step
    run's to the integrators' error."""
    tr = dataclasses.replace(trains.train(3), terrain=Plane(0.05, 0.15), lateral_friction=0.5)
    tractor = dataclasses.replace(tr.carts[0], track_width=1.9, com_height=1.1, hitch_height=0.5)
    tr = dataclasses.replace(tr, carts=(tractor,) + tr.carts[1:])
    sc = trains.scene(tr, table=((0.0, 2.0, 4.0), (0.0, 0.3, 0.3)), duration=8.0)
    fixed = run_metrics(sc, fidelity="dynamic").metrics
    adaptive = run_metrics(sc, fidelity="dynamic", method="RK45").metrics
    for name in ("min_grip_margin", "min_tip_margin", "hitch2_mean_pull_kN", "hitch3_max_pull_kN"):
        assert math.isfinite(adaptive[name]), name
        assert adaptive[name] == pytest.approx(fixed[name], rel=1e-4), name
