"""A live run states its accuracy too (run/companion.py): a companion fed the same held inputs tick
by tick gives the estimate the offline run gives from its whole-scene companion; and where the
tolerance needs more steps than the wall clock's tick allows, the node says so and takes the most
that fit.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import trains
from test_accuracy import single_tractor_scene
from test_session import FakeClock, Log

from mta_sim_ros.node.params import PARAMS
from mta_sim_ros.node.run_session import RunSession
from mta_sim_ros.node.status import WARN
from mta_sim_ros.physics.loader import load_scene
from mta_sim_ros.run import accuracy
from mta_sim_ros.run.batch import run_trace
from mta_sim_ros.run.companion import BUDGET_SHARE, Companion, budget_steps
from mta_sim_ros.run.simulation import Simulation

REPO = Path(__file__).resolve().parents[1]


def live_estimate(scene, **options) -> float:
    """The scene's own inputs fed tick by tick to a run and its Companion, as the node feeds them."""
    sim = Simulation(scene, **options)
    companion = Companion(sim, dict(options, fidelity=sim.level, split_kinks=sim.split_kinks))
    while sim.ticks < round(scene.duration / sim.tick):
        sim.advance(*sim.scheduled_inputs(sim.t))
        companion.follow(sim, sim.outputs())
    return companion.error


@pytest.mark.parametrize("scene", ["kinks", "headland_turn", "lane_change", "single"])
def test_a_live_run_states_the_error_its_offline_run_states(scene):
    scene = single_tractor_scene(step=0.01) if scene == "single" else load_scene(
        REPO / "config" / "scenes" / f"{scene}.yaml")
    offline = accuracy.estimate(scene, run_trace(scene))
    # the same runs; the points differ in round-off only (from Outputs here, from the trace offline)
    assert live_estimate(scene) == pytest.approx(offline.error, rel=0, abs=1e-13)


def test_an_adaptive_runs_companion_runs_at_tighter_tolerances():
    scene = dataclasses.replace(load_scene(REPO / "config" / "scenes" / "kinks.yaml"), duration=3.0)
    sim = Simulation(scene, method="RK45")
    companion = Companion(sim, {"method": "RK45"})
    assert (companion.sim.rtol, companion.sim.atol) == (sim.rtol / accuracy.TIGHTER, sim.atol / accuracy.TIGHTER)
    assert companion.factor == 1.0
    slip = Simulation(scene, fidelity="slip")  # the slip level's own tolerances, not the scene's
    companion = Companion(slip, {"fidelity": "slip"})
    assert (companion.sim.rtol, companion.sim.atol) == (slip.rtol / accuracy.TIGHTER, slip.atol / accuracy.TIGHTER)


def test_the_budget_is_the_most_steps_whose_run_and_companion_fit():
    sim = Simulation(trains.scene(trains.train(2), rate=50.0, step=0.02 / 8))
    assert round(sim.tick / sim.stepper_step) == 8
    per_step = 1e-4  # s: 8 steps a tick, run and companion (3 x 8 steps) 2.4 ms
    cost = lambda steps: per_step * steps  # noqa: E731
    assert budget_steps(sim, 0.0, cost) == 8  # no wall clock (lockstep, as fast as possible)
    assert budget_steps(sim, 2.5e-3 / BUDGET_SHARE, cost) == 8  # it fits
    assert budget_steps(sim, 1.25e-3 / BUDGET_SHARE, cost) == 4
    assert budget_steps(sim, 1e-6, cost) == 1  # never fewer than one


class SlowClock(FakeClock):
    """A compute clock each reading of which is ``each`` s after the last: every timed tick slow."""

    def __init__(self, each: float):
        super().__init__()
        self.each = each

    def __call__(self) -> float:
        self.t += self.each
        return self.t


def session(tmp_path, compute_clock, tolerance):
    scene = tmp_path / "scene.yaml"
    train = REPO / "config" / "trains" / "default.yaml"
    scene.write_text(f"name: tight\ntrain: {train}\nduration: 4\ninitial: {{speed: 3.0}}\n"
                     "steering: {table: {time: [0, 1, 2], angle: [0, 0.3, -0.2]}}\npublish_rate: 50\n"
                     f"integrator: {{tolerance: {tolerance}}}\n")
    cfg = {p.name: p.default for p in PARAMS}
    cfg.update(scene_file=str(scene), bag_dir=str(tmp_path / "bags"), publish_rate=50.0, record=False)
    clock = FakeClock()
    return RunSession(cfg, clock=clock, publish=lambda msgs: None, log=Log(), background=False,
                      compute_clock=compute_clock, cpu_clock=clock)


def test_a_tolerance_the_tick_cannot_afford_is_said_and_the_best_step_taken(tmp_path):
    """Tolerance 1e-11 m needs many steps a tick; with every timed tick 0.1 s long (the clock) a
    20 ms tick at real-time factor 1 allows BUDGET_SHARE x 20 ms / (3 x 0.1 s / steps)."""
    s = session(tmp_path, SlowClock(0.1 * 20), 1e-11)  # 20 timed ticks between two readings: 0.1 s each
    try:
        wanted = round(s.sim.tick / accuracy.chosen_step(s.scene, rate=50.0, fidelity=s.sim.level))
        assert wanted > 3
        allowed = max(1, int(BUDGET_SHARE * 0.02 / (3 * 0.1 / wanted)))
        assert round(s.sim.tick / s.sim.stepper_step) == allowed < wanted
        state = s.diagnostics()
        assert state.level == WARN and "needs" in state.message and f"allows {allowed}" in state.message
        assert state.values["position_tolerance_m"] == 1e-11
    finally:
        s.close()


def test_a_tolerance_the_tick_affords_runs_as_chosen_and_is_quiet(tmp_path):
    s = session(tmp_path, FakeClock(), 1e-6)  # the timed ticks take no time
    try:
        assert s.sim.stepper_step == accuracy.chosen_step(s.scene, rate=50.0, fidelity=s.sim.level)
        for _ in range(200):
            s.tick()
        state = s.diagnostics()
        assert state.message == "running", state.message
        assert 0.0 < state.values["position_error_estimate_m"] < 1e-6
    finally:
        s.close()


def test_a_companion_that_cannot_run_says_so_and_the_run_goes_on():
    """A step at tick / (MAX_STEPS_PER_TICK - 1): its companion at half of it would take more
    steps a tick than a run may; the run still runs, and states no error rather than a number."""
    from mta_sim_ros.validate import MAX_STEPS_PER_TICK

    scene = dataclasses.replace(load_scene(REPO / "config" / "scenes" / "kinks.yaml"), duration=0.05)
    sim = Simulation(scene, step=0.01 / (MAX_STEPS_PER_TICK - 1))
    companion = Companion(sim, {"step": sim.step})
    assert companion.sim is None and "cannot run" in companion.line()
    sim.advance(*sim.scheduled_inputs(0.0))
    companion.follow(sim, sim.outputs())
    assert companion.error != companion.error  # NaN: not a number the bag would take for an estimate
    offline = accuracy.estimate(scene, run_trace(scene, step=sim.step), step=sim.step)
    assert offline.error != offline.error and "not estimated" in offline.line() and not offline.meets
