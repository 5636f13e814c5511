"""Commands as the node holds them (mta_sim_ros.node.commands), and a reset that really starts over."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from mta_sim_ros.node.commands import SPEED_LIMIT, CommandInput, command_ranges, hold
from mta_sim_ros.physics.loader import load_scene
from mta_sim_ros.run.simulation import Simulation

SCENE = Path(__file__).resolve().parents[1] / "config" / "scenes" / "lane_change.yaml"


@pytest.mark.parametrize("x, expected, problem", [
    (0.1, 0.1, ""),
    (-0.5, -0.5, ""),  # the range's end is inside
    (0.7, 0.5, "clamped"),
    (-9.0, -0.5, "clamped"),
    (math.nan, None, "not finite"),
    (math.inf, None, "not finite"),
    (-math.inf, None, "not finite"),
])
def test_hold_refuses_non_finite_and_clamps_to_the_range(x, expected, problem):
    value, why = hold(x, -0.5, 0.5)
    assert value == expected
    assert (problem in why) and (bool(why) == bool(problem))


def test_command_input_counts_and_keeps_the_last_good_value():
    inp = CommandInput(0.0, -0.5, 0.5, "steering_angle")
    assert inp.take(0.2) == 0.2
    assert inp.take(math.nan) is None and inp.value == 0.2
    assert "steering_angle" in inp.last_problem and "nan" in inp.last_problem
    assert inp.take(3.0) == 0.5 and inp.value == 0.5
    assert (inp.count, inp.rejected, inp.clamped) == (3, 1, 1)


def test_ranges_come_from_the_scene():
    scene = load_scene(str(SCENE))
    ranges = command_ranges(scene)
    a = scene.train.actuator.max_angle
    assert ranges["steering_angle"] == (-a, a)
    assert ranges["speed_setpoint"] == (-SPEED_LIMIT, SPEED_LIMIT)


@pytest.mark.parametrize("method", ["rk4", "RK45", "LSODA"])
def test_a_run_after_reset_repeats_the_first_exactly(method):
    """An adaptive stepper remembers its last step size; reset must forget it, or the second run
    starts with another step and differs."""
    scene = load_scene(str(SCENE))
    scene = dataclasses.replace(scene, duration=3.0)
    sim = Simulation(scene, method=method)

    def run() -> np.ndarray:
        states = []
        while sim.t < scene.duration - 1e-9:
            sim.advance(*sim.scheduled_inputs(sim.t))
            states.append(sim.y.copy())
        return np.array(states)

    first = run()
    sim.reset()
    second = run()
    assert first.shape == second.shape
    assert np.array_equal(first, second)
