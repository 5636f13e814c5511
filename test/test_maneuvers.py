"""Steering manoeuvres: table shape, sampling accuracy, and the kinematic-bicycle physics they aim at.

The kinematic bicycle (MODEL.md, n = 1): th' = V sin(psi)/l, x' = V cos th, y' = V sin th
(A_1's heading differs from th by psi, which does not change the heading integral).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mta_sim_ros.physics import loader, maneuvers
from mta_sim_ros.physics.maneuvers import MANEUVERS, ParamError, expand

CONFIG = Path(__file__).resolve().parent.parent / "config"
DT = 1e-3  # s, fine trapezoid grid


def sampled(table, t_end: float, dt: float = DT) -> tuple[np.ndarray, np.ndarray]:
    """The table's piecewise-linear function on a fine grid from 0 to t_end."""
    t = np.arange(0.0, t_end + dt / 2, dt)
    return t, np.interp(t, table.time, table.value)


def trapezoid(y: np.ndarray, t: np.ndarray) -> float:
    return float(np.sum((y[1:] + y[:-1]) * np.diff(t)) / 2)


def heading_change(table, speed, wheelbase: float, t_end: float) -> float:
    """Integral of th' = V sin(psi)/l over [0, t_end]; ``speed`` is a number or a function of t."""
    t, psi = sampled(table, t_end)
    v = speed(t) if callable(speed) else speed
    return trapezoid(v * np.sin(psi) / wheelbase, t)


def bicycle_path(table, speed: float, wheelbase: float, t_end: float):
    """(t, heading, lateral position y) of the kinematic bicycle, cumulative trapezoids."""
    t, psi = sampled(table, t_end)
    rate = speed * np.sin(psi) / wheelbase
    heading = np.concatenate([[0.0], np.cumsum((rate[1:] + rate[:-1]) * DT / 2)])
    vy = speed * np.sin(heading)
    y = np.concatenate([[0.0], np.cumsum((vy[1:] + vy[:-1]) * DT / 2)])
    return t, heading, y


def all_default_tables():
    for name in MANEUVERS:
        yield name, expand(name, {}, speed_at=lambda t: 3.0, wheelbase=3.0)


# --------------------------------------------------------------------------- every manoeuvre


@pytest.mark.parametrize("name, table", list(all_default_tables()), ids=list(MANEUVERS))
def test_table_is_monotone_finite_and_bounded(name, table):
    time, value = np.array(table.time), np.array(table.value)
    assert len(time) == len(value) >= 1
    assert np.all(np.diff(time) > 0)
    assert np.all(np.isfinite(time)) and np.all(np.isfinite(value))
    peak = MANEUVERS[name].peak
    bound = abs(MANEUVERS[name].defaults[peak]) if peak else 0.0
    assert np.max(np.abs(value)) <= bound + 1e-12
    assert value[0] == 0.0


@pytest.mark.parametrize("name", ["sine", "slalom", "lane_change"])
@pytest.mark.parametrize("amplitude", [0.05, 0.3, 0.6])
def test_smooth_shapes_interpolate_within_1e4_rad(name, amplitude):
    """Linear interpolation between samples stays within 1e-4 rad of A sin(2 pi (t - t0)/T)."""
    key = "duration" if name == "lane_change" else "period"
    params = {"amplitude": amplitude, "t0": 1.0, key: 4.0}
    table = expand(name, params)
    cycles = 1.0 if name == "lane_change" else MANEUVERS[name].defaults["cycles"]
    t = np.linspace(1.0, 1.0 + 4.0 * cycles, 200_001)
    exact = amplitude * np.sin(2 * math.pi * (t - 1.0) / 4.0)
    assert np.max(np.abs(np.interp(t, table.time, table.value) - exact)) < 1e-4


def test_amplitude_beyond_the_actuator_is_refused():
    with pytest.raises(ParamError) as info:
        expand("slalom", {"amplitude": -0.8}, max_angle=0.7)
    assert info.value.param == "amplitude" and "max_angle" in info.value.rule


def test_unknown_parameter_is_named():
    with pytest.raises(ParamError) as info:
        expand("lane_change", {"amplitde": 0.1})
    assert info.value.param == "amplitde"
    assert "t0, amplitude, duration" in info.value.rule


def test_non_number_parameter_is_refused():
    with pytest.raises(ParamError, match="a finite number"):
        expand("step", {"angle": float("nan")})


def test_registered_angle_params_exist():
    for maneuver in MANEUVERS.values():
        assert maneuver.angles <= set(maneuver.defaults)
        assert not maneuver.peak or maneuver.peak in maneuver.angles


# --------------------------------------------------------------------------- simple shapes


def test_straight_is_zero():
    assert maneuvers.straight().value == (0.0,)


def test_step_and_ramp_reach_and_hold_the_angle():
    step = maneuvers.step(t0=2.0, angle=0.2)
    assert np.interp([0.0, 1.99, 2.5, 100.0], step.time, step.value) == pytest.approx([0, 0, 0.2, 0.2])
    ramp = maneuvers.ramp(t0=1.0, t1=3.0, angle=-0.2)
    assert np.interp([0.5, 2.0, 9.0], ramp.time, ramp.value) == pytest.approx([0.0, -0.1, -0.2])
    with pytest.raises(ParamError, match="t1"):
        maneuvers.ramp(t0=3.0, t1=3.0)


# --------------------------------------------------------------------------- lane change


@pytest.mark.parametrize("amplitude, duration", [(0.1, 6.0), (-0.12, 8.0), (0.05, 12.0)])
def test_lane_change_returns_heading_and_steering_to_zero(amplitude, duration):
    """A full sine period: the integral of psi is 0, sin psi is odd about the half period, so the
    heading change is 0; the steering ends at 0; the tractor moves sideways towards the first
    steer, about V^2 A T^2 / (2 pi l) for small angles."""
    V, l, t0 = 3.0, 3.0, 2.0
    table = maneuvers.lane_change(t0=t0, amplitude=amplitude, duration=duration)
    t_end = t0 + duration + 1.0
    assert table.value[-1] == pytest.approx(0.0, abs=1e-12)
    assert table.time[0] == t0 and table.time[-1] == pytest.approx(t0 + duration)
    t, psi = sampled(table, t_end)
    assert trapezoid(psi, t) == pytest.approx(0.0, abs=1e-6)
    _, heading, y = bicycle_path(table, V, l, t_end)
    peak_heading = np.max(np.abs(heading))
    assert abs(heading[-1]) < 1e-6 * peak_heading
    small_angle = V**2 * amplitude * duration**2 / (2 * math.pi * l)
    assert y[-1] == pytest.approx(small_angle, rel=0.05)
    assert np.sign(y[-1]) == np.sign(amplitude)


# --------------------------------------------------------------------------- headland turn


@pytest.mark.parametrize(
    "angle, speed, wheelbase, turn_angle, ramp_time",
    [
        (0.25, 2.0, 3.0, math.pi, 2.0),
        (-0.25, 2.0, 3.0, math.pi, 2.0),
        (0.5, 3.0, 2.5, math.pi, 1.0),
        (0.2, 1.5, 3.0, math.pi / 2, 3.0),
        (0.6, 2.0, 3.0, 2 * math.pi, 0.5),
    ],
)
def test_headland_turn_heading_change_equals_turn_angle(angle, speed, wheelbase, turn_angle, ramp_time):
    table = maneuvers.headland_turn(
        t0=5.0, angle=angle, speed=speed, wheelbase=wheelbase, turn_angle=turn_angle, ramp_time=ramp_time
    )
    turned = heading_change(table, speed, wheelbase, table.time[-1] + 1.0)
    assert turned == pytest.approx(math.copysign(turn_angle, angle), rel=1e-3)
    assert table.value[0] == table.value[-1] == 0.0
    assert max(table.value, key=abs) == angle
    assert table.time[1] - table.time[0] == pytest.approx(ramp_time)


def test_headland_turn_with_ramps_that_turn_too_much_is_refused():
    with pytest.raises(ParamError) as info:
        maneuvers.headland_turn(angle=0.5, speed=3.0, wheelbase=3.0, turn_angle=0.1, ramp_time=2.0)
    assert info.value.param == "ramp_time"


def test_headland_turn_needs_a_forward_speed():
    with pytest.raises(ParamError) as info:
        maneuvers.headland_turn(speed=-1.0, wheelbase=3.0)
    assert info.value.param == "speed"


def test_expand_takes_speed_at_t0_and_the_wheelbase_from_the_scene():
    asked = []

    def speed_at(t):
        asked.append(t)
        return 2.0

    table = expand("headland_turn", {"t0": 7.0}, speed_at=speed_at, wheelbase=3.0)
    assert asked == [7.0]
    assert heading_change(table, 2.0, 3.0, table.time[-1] + 1) == pytest.approx(math.pi, rel=1e-3)
    given = expand("headland_turn", {"t0": 7.0, "speed": 4.0, "wheelbase": 2.0}, speed_at=speed_at, wheelbase=3.0)
    assert asked == [7.0]
    assert heading_change(given, 4.0, 2.0, given.time[-1] + 1) == pytest.approx(math.pi, rel=1e-3)


def test_shipped_headland_scene_turns_the_tractor_around():
    """The main scene, with its speed table, turns the kinematic bicycle by pi."""
    scene = loader.load_scene(CONFIG / "scenes" / "headland_turn.yaml")
    table, speed = scene.steering, scene.speed
    turned = heading_change(
        table, lambda t: np.interp(t, speed.time, speed.value), scene.train.carts[0].length, scene.duration
    )
    assert turned == pytest.approx(math.pi, rel=1e-3)
