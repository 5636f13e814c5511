"""Commands as a receiver holds them: validated, clamped, with their receipt time. No ROS here.

The node takes every steering and speed command through a :class:`CommandInput`; ``mta replay
--resimulate`` applies the same rule (:func:`hold`) to a node bag's recorded commands, so the
re-simulation holds exactly what the node held.
"""
from __future__ import annotations

import math
import time
from typing import Callable

#: Largest speed set-point the node accepts, m/s (either sign); beyond it the value is clamped.
SPEED_LIMIT = 50.0


def hold(x: float, low: float, high: float) -> tuple[float | None, str]:
    """The value to hold after receiving x, or None if x is refused, and what was wrong ('' if nothing)."""
    if not math.isfinite(x):
        return None, "not finite"
    if not low <= x <= high:
        return min(max(x, low), high), f"outside [{low:.4g}, {high:.4g}]; clamped"
    return x, ""


def command_ranges(scene) -> dict[str, tuple[float, float]]:
    """The accepted range of each command topic for a scene."""
    max_angle = scene.train.actuator.max_angle
    return {"steering_angle": (-max_angle, max_angle), "speed_setpoint": (-SPEED_LIMIT, SPEED_LIMIT)}


class CommandInput:
    """The latest command on one topic, with its receipt time on a steady wall ``clock``
    (seconds; injectable so that tests set the time instead of sleeping) and what was wrong."""

    def __init__(self, value: float, low: float, high: float, name: str,
                 clock: Callable[[], float] = time.monotonic):
        self.value, self.low, self.high, self.name = value, low, high, name
        self.clock = clock
        self.received = clock()
        self.count = 0
        self.rejected = 0
        self.clamped = 0
        self.last_problem = ""

    def take(self, x: float) -> float | None:
        """Validate a received value; returns the value held from now on, or None if rejected.
        ``last_problem`` says what is wrong with the last value received, so it clears when a
        good one follows (the counts keep the history)."""
        self.count += 1
        value, problem = hold(x, self.low, self.high)
        if value is None:
            self.rejected += 1
            self.last_problem = f"{self.name}: {x} is {problem}; kept {self.value:.4g}"
            return None
        self.last_problem = ""
        if problem:
            self.clamped += 1
            self.last_problem = f"{self.name}: {x:.4g} {problem}"
        self.value = value
        self.received = self.clock()
        return value

    def age(self) -> float:
        """Seconds since the last accepted command (since construction before the first)."""
        return self.clock() - self.received
