"""A live run's accuracy: a companion simulation fed the same held inputs, tick by tick. No ROS.

An offline run states its error from a companion run of the whole scene (``accuracy.estimate``).
A run steered live (the node) does not know its inputs ahead, so its companion runs beside it: the
same scene at half the step (a fixed-step method; at a thousandth of rtol and atol for an adaptive
one), advanced after every tick with the command, set-point, rate limit and implement state the
run held. The estimate is the same figure as offline (SAFETY x the Richardson factor x the largest
distance between the two runs' points so far), so a node run and ``mta run`` of the same inputs
state the same error.

``budget_steps`` is the other half of a live run's accuracy: how many steps a tick the wall clock
allows, where the tolerance asks for more.
"""
from __future__ import annotations

import math

import numpy as np

from ..integrate import IntegrationError
from ..physics.guards import ModelValidityError
from ..validate import InputError
from .accuracy import SAFETY, companion
from .simulation import Simulation

#: the share of a tick's wall period the run and its companion may take together
BUDGET_SHARE = 0.5


def points(out) -> np.ndarray:
    """A_k, B_k and the last rear hitch of an Outputs (the points of accuracy.points)."""
    return np.vstack([out.front, out.axle, out.rear_hitch[None]])


class Companion:
    """The companion of ``sim`` (a Simulation as the run built it) and the error estimate so far."""

    def __init__(self, sim: Simulation, options: dict):
        extra, self.factor, self.how = companion(sim, dict(options))
        extra.setdefault("fidelity", sim.level)
        self.tolerance = sim.scene.integrator.tolerance
        self.distance = 0.0
        self.stopped = ""  # why there is no estimate (the companion stopped or cannot run), "" while it follows
        try:
            self.sim: Simulation | None = Simulation(sim.scene, **extra)
        except InputError as err:  # its half step past validate.MAX_STEPS_PER_TICK: the run goes on without
            self.sim, self.stopped = None, f"no error estimate: the companion cannot run ({err})"

    @property
    def error(self) -> float:
        """The estimated largest position error of the run so far, m; NaN once the companion has
        stopped (or could not run): the rest of the run is not covered."""
        return math.nan if self.stopped else SAFETY * self.factor * self.distance

    def follow(self, run: Simulation, out) -> None:
        """Advance one tick holding what ``run`` held over its last tick, and compare the points
        with ``out``, the run's Outputs now."""
        if self.stopped:
            return
        self.sim.set_rate_limit(run.rate_limit)
        self.sim.set_lowered(run.lowered)
        try:
            self.sim.advance(run.command, run.v_set)
        except (ModelValidityError, IntegrationError) as err:
            self.stopped = f"the estimate stopped at t = {self.sim.t:.3f} s: the companion run stopped ({err})"
            return
        d = float(np.max(np.linalg.norm(points(out) - points(self.sim.outputs()), axis=1)))
        if not math.isfinite(d):
            self.stopped = f"the estimate stopped at t = {self.sim.t:.3f} s: a point of a run is not finite"
            return
        self.distance = max(self.distance, d)

    def reset(self) -> None:
        if self.sim is None:
            return  # it cannot run: still no estimate
        self.sim.reset()
        self.distance = 0.0
        self.stopped = ""

    def line(self) -> str:
        if self.stopped:
            return self.stopped
        verdict = "within" if self.error <= self.tolerance else "OVER"
        return (f"estimated position error so far {self.error:.2g} m, {verdict} the tolerance {self.tolerance:g} m "
                f"({self.how})")


def budget_steps(sim: Simulation, period: float, seconds_per_tick) -> int:
    """Steps a tick of ``sim`` may take when a tick's wall period is ``period`` s (0: no budget) and
    its stepper takes ``seconds_per_tick(steps)`` s a tick: the most whose run and companion (twice
    the steps) fit in BUDGET_SHARE of the period, at least 1; the steps it takes now if they fit."""
    steps = max(1, round(sim.tick / sim.stepper_step))
    if period <= 0.0:
        return steps
    budget = BUDGET_SHARE * period
    if 3.0 * seconds_per_tick(steps) <= budget:
        return steps
    per_step = seconds_per_tick(steps) / steps
    return max(1, min(steps, int(budget / (3.0 * per_step))))


def tick_seconds(sim: Simulation, clock, repeat: int = 20):
    """seconds_per_tick(steps) of ``budget_steps`` for ``sim``: ``repeat`` ticks of its kernel from
    its state at ``steps`` equal steps, timed on ``clock``."""
    from ..integrate.steppers import FixedStep

    def seconds(steps: int) -> float:
        stepper = FixedStep(sim.method, sim.tick / steps, sim.split_kinks)
        y = np.ascontiguousarray(sim.y, dtype=np.float64)
        start = clock()
        for _ in range(repeat):
            stepper.tick(sim.model.P, y, 0.0, sim.tick, sim.command, sim.v_set, sim.max_rate, bool(sim.compiled))
        return (clock() - start) / repeat

    return seconds
