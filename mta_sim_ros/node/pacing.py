"""How a run keeps time with the wall clock. No ROS here.

A tick is due every ``period`` = tick / target wall seconds (target = the real-time factor asked
for; 0 = as fast as possible, period 0). The timer fires every ``timer_period`` = the period, but
at least every MAX_TIMER_PERIOD seconds, and each firing runs the ticks due then
(:meth:`Pacing.due`): the ones whose end the wall clock times the target has reached, so
simulated time never runs ahead of it, up to CATCH_UP of them. A firing that comes late (a busy
executor, a slow tick, the bag writer behind) is made up by the next ones, at most CATCH_UP - 1
ticks more each, instead of being lost for good (a ROS timer skips the firings it missed). A tiny
target (1e-12) is a timer every MAX_TIMER_PERIOD firing no tick for a long time, not a period no
timer can hold. Two figures say how well it keeps up, both measured on the injected steady
``clock`` from the latest restart (start, pause, resume, reset, a new target), so a pause does
not count:

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

#: the timer fires at least this often, s (commands are taken and the watchdog looks at each firing)
MAX_TIMER_PERIOD = 0.1
#: most ticks one firing runs: a lag is made up at up to this many times the target
CATCH_UP = 10
#: a tick whose end is due within this fraction of a tick counts as due (rounding)
DUE_SLACK = 1e-6


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
        self.timer_period = min(self.period, MAX_TIMER_PERIOD)
        self.restart(sim_time)

    def due(self, sim_time: float) -> int:
        """How many ticks the firing of now runs, the simulation being at ``sim_time``: 0 while
        paused, 1 at target 0, else the ticks whose end the wall clock has reached since the
        restart (0 to CATCH_UP)."""
        if self.paused:
            return 0
        if self.target <= 0:
            return 1
        behind = ((self.clock() - self.wall_start) * self.target - (sim_time - self.sim_start)) / self.tick
        return math.floor(min(float(CATCH_UP), max(0.0, behind + DUE_SLACK)))

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
