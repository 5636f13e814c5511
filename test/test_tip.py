"""The tractor's longitudinal tip margin (physics.terrain.tip_margin, a sweep's min_tip_margin)
against the statics of a tractor on a grade with its drawbar load, and the drawbar's load along
the tractor's axis (kernel.drawbar_pulls' cart[0, PULL]) against Newton-Euler on the cart behind
on the steady circles.

The closed forms (docs/terrain.md): moments about the rear wheels' contact line give the front
axle's load N_f L = m g (cos(a) c -+ sin(a) h) - P h_d heading up (down) a grade a with the pull P
at the hitch height h_d; the margin is N_f over the load m g c / L standing on the level.
"""
from __future__ import annotations

import dataclasses
import math

import pytest
import trains

from mta_sim_ros.physics import kernel, loader
from mta_sim_ros.physics.reader import SpecError
from mta_sim_ros.physics.steady import steady_circle
from mta_sim_ros.physics.terrain import Plane
from mta_sim_ros.run.batch import run_metrics
from mta_sim_ros.run.simulation import Simulation, initial_state

G = 9.80665
C, H, HD = 1.3, 1.1, 0.5  # the test tractor's com_offset (trains.CARTS), com_height, hitch_height


def measured(n: int, hitch_height: float | None = HD, terrain=None):
    """trains.train(n) whose tractor gives com_height H (and track), and hitch_height when it tows."""
    tr = trains.train(n)
    tractor = dataclasses.replace(tr.carts[0], track_width=1.9, com_height=H,
                                  hitch_height=hitch_height if n > 1 else None)
    return dataclasses.replace(tr, carts=(tractor,) + tr.carts[1:], terrain=terrain)


def margin_of(tr, duration: float = 6.0, fidelity: str = "dynamic", **initial) -> float:
    result = run_metrics(trains.scene(tr, duration=duration, **initial), fidelity=fidelity)
    assert result.verdict == "ok", result.reason
    return result.metrics["min_tip_margin"]


@pytest.mark.parametrize("grade", [0.1, 0.3, -0.2])
def test_a_lone_tractor_up_and_down_a_grade_tips_at_tan_a_of_c_over_h(grade):
    """No pull: heading up the grade a (heading 0), margin = cos a - (h / c) sin a, 0 at
    tan a = c / h; heading down it (heading pi) the weight moves forward: cos a + (h / c) sin a."""
    a = math.atan(grade)
    for heading, sign in ((0.0, -1.0), (math.pi, 1.0)):
        got = margin_of(measured(1, terrain=Plane(grade, 0.0)), heading=heading)
        assert got == pytest.approx(math.cos(a) + sign * H / C * math.sin(a), abs=1e-12)


def drawbar_moment(tr, cos: float = 1.0) -> float:
    """V_2 a_1: the cart behind the tractor rests V_2 on its drawbar, a_1 behind its rear axle.
    Cart 2 on its axle and hitch, with cart 3 (if any) resting V_3 = W_3 c_3 / l_3 on cart 2's rear
    hitch a_2 behind its axle: V_2 = (W_2 c_2 - V_3 a_2) / l_2, the weights W_k = m_k g cos(slope)."""
    t, c2 = tr.carts[0], tr.carts[1]
    v3 = tr.carts[2].mass * G * cos * tr.carts[2].com_offset / tr.carts[2].length if tr.n > 2 else 0.0
    assert tr.n <= 3
    return (c2.mass * G * cos * c2.com_offset - v3 * c2.hitch_offset) / c2.length * t.hitch_offset


@pytest.mark.parametrize("n", [2, 3])
def test_on_the_level_the_drawbar_pull_at_steady_speed_unloads_the_front_axle(n):
    """Straight at the governor's steady 3 m/s: the drawbar carries the resistances behind it
    (Newton on the carts behind), sum F_Bk for k >= 2, and the margin is 1 - (P h_d + V_2 a_1) /
    (m g c), the cart behind resting V_2 on the drawbar a_1 behind the rear axle."""
    tr = measured(n)
    sim = Simulation(trains.scene(tr))
    cart, _ = kernel.pulls_of(sim.model.P, initial_state(trains.scene(tr), sim.model), 0.0, 3.0,
                              kernel.max_rate_of(sim.model.P))
    pull = sum(cart[k, kernel.RES] for k in range(1, n))
    assert cart[0, kernel.PULL] == pytest.approx(pull, rel=1e-12) and pull > 10e3
    assert margin_of(tr) == pytest.approx(1 - (pull * HD + drawbar_moment(tr)) / (tr.carts[0].mass * G * C), rel=1e-9)


def test_standing_the_margin_is_the_static_front_axle_load_and_a_heavy_drawbar_lifts_it():
    """No pull: the margin is the front axle's static load (loads.static_axle_loads, the chain's
    statics) over a lone tractor's, m g c / l, less on a grade the weight's part along the ground
    at h, m g R20 h / l, which the static loads leave out. A 20 t cart resting all its weight on
    the drawbar (c_2 = l_2) lifts the front wheels: both below 0."""
    from mta_sim_ros.physics.loads import static_axle_loads
    from mta_sim_ros.physics.terrain import PlaneFrame, Stance

    for plane in (Plane(0.0, 0.0), Plane(0.1, -0.2)):
        tr = measured(3, terrain=plane)
        t = tr.carts[0]
        margin = float(Stance(tr).tip_margins([[0.0, 0.0, 0.0]], [0.0])[0])
        along = t.mass * G * PlaneFrame.of(plane).x[2] * H / t.length  # heading 0: R20 is the x axis's rise
        assert margin * t.mass * G * C / t.length == pytest.approx(static_axle_loads(tr)[0] - along, rel=1e-12)
    tr = measured(2)
    heavy = dataclasses.replace(tr.carts[1], mass=20000.0, com_offset=tr.carts[1].length)
    tr = dataclasses.replace(tr, carts=(tr.carts[0], heavy))
    t = tr.carts[0]
    margin = float(Stance(tr).tip_margins([[0.0, 0.0]], [0.0])[0])
    assert margin == pytest.approx(1 - 20000.0 * t.hitch_offset / (t.mass * C), rel=1e-12) and margin < 0
    assert static_axle_loads(tr)[0] == pytest.approx(margin * t.mass * G * C / t.length, rel=1e-12)


def test_up_a_grade_the_pull_adds_the_weight_of_the_carts_behind():
    """Straight up a 12 % grade at 3 m/s held (prescribed speed: V' = 0 throughout): the pull is each cart's resistance plus its
    m g sin a (Newton on the carts behind), and the margin falls by both the tractor's own weight
    moving back and that pull: cos a - (h / c) sin a - (P h_d + V_2 a_1) / (m g c)."""
    grade = 0.12
    a = math.atan(grade)
    tr = dataclasses.replace(measured(3, terrain=Plane(grade, 0.0)), traction=trains.prescribed(3.0))
    sc = trains.scene(tr)
    sim = Simulation(sc)
    cart, _ = kernel.pulls_of(sim.model.P, initial_state(sc, sim.model), 0.0, 3.0, kernel.max_rate_of(sim.model.P))
    pull = sum(cart[k, kernel.RES] + c.mass * G * math.sin(a) for k, c in enumerate(tr.carts) if k > 0)
    got = margin_of(tr)
    expect = math.cos(a) - H / C * math.sin(a) - (pull * HD + drawbar_moment(tr, math.cos(a))) / (tr.carts[0].mass * G * C)
    assert got == pytest.approx(expect, rel=1e-6)
    lower = dataclasses.replace(tr, carts=(dataclasses.replace(tr.carts[0], hitch_height=0.25),) + tr.carts[1:])
    assert margin_of(lower) - got == pytest.approx(pull * (HD - 0.25) / (tr.carts[0].mass * G * C), rel=1e-6)


@pytest.mark.parametrize("psi", [0.25, -0.2])
def test_the_drawbar_load_along_the_tractor_in_a_steady_turn(psi):
    """Tractor and one cart on their steady circles (angular speed W about O on the cart's axle
    line, R_B2 from it, signed > 0 in a left turn): the cart's centre of mass C (c ahead of B) has a_C = -W^2 (C - O), whose
    part across the cart is W^2 R_B2; the moments about C and Newton across the cart give the
    hitch's lateral force h_n = m c W^2 R_B2 / l (its pull along the cart h_e: test_sweep_metrics).
    The drawbar's load along the tractor, phi = th_1 - th_2: h_e cos(phi) + h_n sin(phi)."""
    tr = measured(2)
    circle = steady_circle(tr, psi)
    sc = trains.scene(tr, table=((0.0,), (psi,)), steering=psi, hitch_angles=tuple(circle.hitch_angles))
    sim = Simulation(sc)
    cart, _ = kernel.pulls_of(sim.model.P, initial_state(sc, sim.model), psi, 3.0, kernel.max_rate_of(sim.model.P))
    towed = tr.carts[1]
    w = 3.0 / circle.R_A[0]
    r_b = math.copysign(circle.R_B[1], psi)  # O is left of the cart (n side) in a left turn
    h_n = towed.mass * towed.com_offset * w ** 2 * r_b / towed.length
    phi = circle.hitch_angles[0]
    assert abs(phi) > 0.1
    assert cart[0, kernel.PULL] == pytest.approx(cart[1, kernel.PULL] * math.cos(phi) + h_n * math.sin(phi),
                                                 rel=1e-9)


def test_the_margin_is_not_claimed_where_it_is_not_known():
    """NaN: a towing tractor without hitch_height, one without com_height, and the slip level
    (its tyre forces take the place of the constraint forces the pull comes from)."""
    assert math.isnan(margin_of(measured(2, hitch_height=None)))
    assert math.isnan(margin_of(trains.train(2)))
    assert math.isnan(margin_of(measured(2), fidelity="slip"))
    assert not math.isnan(margin_of(measured(2)))


@pytest.mark.parametrize("value, words", [(0.6, "not given on the last cart"), (-0.5, "hitch_height"),
                                          (".nan", "hitch_height")])
def test_hitch_height_on_the_last_cart_or_not_a_length_is_one_line(value, words):
    text = open("config/trains/hillside_unit.yaml", encoding="utf-8").read()
    text = text.replace("    com_height: 0.9\n", f"    com_height: 0.9\n    hitch_height: {value}\n")
    assert f"hitch_height: {value}" in text
    with pytest.raises(SpecError) as err:
        loader.load_train_text(text, "t.yaml")
    message = str(err.value)
    assert words in message and "\n" not in message and "carts[2]" in message
