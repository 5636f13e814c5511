"""How a run keeps time with the wall clock. No ROS here.

The tick timer fires every ``period`` = tick / target seconds (target = the real-time factor
asked for; 0 = as fast as possible, period 0). Two figures say how well it keeps up, both
measured on the injected steady ``clock`` from the latest restart (start, pause, resume, reset,
a new target), so a pause does not count:

* the real-time factor: simulated seconds per wall second over the last ``window`` seconds
  (timing.RealTimeFactor). It is sampled when measured (the 1 Hz diagnostics), not every
  tick: the figure is the same and the tick pays nothing for it;
* the lag: how far simulated time trails the wall clock times the target. Slow ticks make the
  simulation fall behind, they never skip physics. 0 while paused or at target 0.
"""
from __future__ import annotations

import math
from typing import Callable

from .timing import RealTimeFactor


class Pacing:
    def __init__(self, tick: float, target: float, clock: Callable[[], float], sim_time: float = 0.0,
                 window: float = 5.0):
        self.tick, self.clock, self.window = tick, clock, window
        self.paused = False
        self.set_target(target, sim_time)

    def set_target(self, target: float, sim_time: float) -> None:
        """A new real-time factor to keep (its period applies to the timer made from now on)."""
        self.target = target
        self.period = self.tick / target if target > 0 else 0.0
        self.restart(sim_time)

    def restart(self, sim_time: float) -> None:
        """Measure afresh from now, when the simulation is at ``sim_time``."""
        self.rtf = RealTimeFactor(self.window, clock=self.clock)
        self.rtf.update(sim_time)
        self.wall_start, self.sim_start = self.clock(), sim_time

    def pause(self, paused: bool, sim_time: float) -> None:
        """Paused or running from now; either way the measurement restarts."""
        self.paused = paused
        self.restart(sim_time)

    def measure(self, sim_time: float) -> tuple[float, float]:
        """(real-time factor, lag in s) now that the simulation is at ``sim_time``; the factor is
        0 until wall time has passed since the restart."""
        self.rtf.update(sim_time)
        rtf = self.rtf.value
        lag = 0.0 if self.paused else (self.clock() - self.wall_start) * self.target - (sim_time - self.sim_start)
        return (0.0 if math.isnan(rtf) else rtf), max(0.0, lag)
