"""The train's margins at one state of a run (docs/terrain.md): each cart's static rollover
margin, the tractor's longitudinal tip margin and each no-slip axle's grip margin, the last two
from the level's constraint forces (kernel.drawbar_pulls). What ``mta run``'s report and the
node's /diagnostics state; a sweep takes the same quantities from its trace (batch.metrics)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..physics import kernel
from ..physics.loads import grip_margins, static_axle_loads
from ..physics.terrain import Stance


@dataclass(frozen=True)
class Margins:
    rollover: float  # the smallest of the carts with track_width and com_height (NaN: none gives them)
    rollover_cart: str
    tip: float  # the tractor's (NaN: not known, Stance.tip_margins)
    grip: float  # the smallest of the no-slip axles (NaN: no lateral_friction, or no constraint forces)
    grip_axle: str
    drift_modelled: bool = True  # fidelity slip can run this ground (not a height grid)

    def problems(self) -> list[str]:
        """What is past a limit, one phrase each (none when every margin is positive or unknown)."""
        out = []
        if self.rollover < 0:
            out.append(f"rollover margin {self.rollover:.2f} of {self.rollover_cart}: its uphill wheels lift")
        if self.tip < 0:
            out.append(f"tip margin {self.tip:.2f}: the tractor's front wheels lift")
        if self.grip < 0:
            out.append(f"grip margin {self.grip:.2f} at {self.grip_axle}: it needs more lateral force than "
                       "friction gives, so the no-slip model does not hold " + (
                           "(fidelity slip models the drift)" if self.drift_modelled else
                           "(the slip level, which models the drift, takes a plane only)"))
        return out


def axle_names(train) -> list[str]:
    """The no-slip axles, in grip_margins' column order."""
    return [f"{train.carts[0].name}'s front axle"] + [f"{c.name}'s axle" for c in train.carts]


def constraint_forces(level, y, command: float, v_set: float, max_rate: float | None = None, compiled: bool = True):
    """(cart n x OUT, scalars) of kernel.pulls_of at state y of a level: the drawbar pulls
    (PULL), the axles' lateral forces (LAT, FRONT_LAT); None for a level without them (the slip
    level, whose tyre forces are its own, and algorithm 1's reference path). ``compiled`` False:
    the kernel as plain Python (the same numbers)."""
    if not level.has_kernel:
        return None
    run = kernel.pulls_of if compiled else kernel.pulls_of.py_func
    return run(level.P_outputs, np.ascontiguousarray(y, dtype=np.float64), float(command),
               float(level.output_input(y, v_set)), kernel.max_rate_of(level.P, max_rate))


class MarginGauge:
    """The margins of a train's states, its Stance and static axle loads built once. What the
    train cannot know (no track and height, no lateral_friction, no tip margin) costs nothing:
    ``at`` computes the constraint forces only for a margin that needs them."""

    def __init__(self, train):
        self.train = train
        self.stance = Stance(train)
        self.axles = axle_names(train)
        self.loads = static_axle_loads(train)
        self.needs_forces = train.lateral_friction is not None or (self.stance.tip is not None and self.stance.tows)

    def at(self, level, y, command: float, v_set: float, max_rate: float | None = None,
           compiled: bool = True) -> Margins:
        state = np.asarray(y, dtype=float)
        heading, a1 = state[level.layout.heading], (state[0], state[1])  # A_1 (a height grid's stance)
        rollover, cart = math.nan, ""
        if self.stance.measured.any():
            margins = self.stance.margins(heading, a1)
            if not np.isnan(margins).all():  # the state is finite
                k = int(np.nanargmin(margins))
                rollover, cart = float(margins[k]), self.stance.names[k]
        forces = constraint_forces(level, y, command, v_set, max_rate, compiled) if self.needs_forces else None
        pull, grip, axle = math.nan, math.nan, ""
        if forces is not None:
            out, sc = forces
            pull = float(out[0, kernel.PULL])
            grips = grip_margins(self.train, [sc[kernel.FRONT_LAT]], out[None, :, kernel.LAT], self.loads)[0]
            if not np.isnan(grips).all():
                j = int(np.nanargmin(grips))
                grip, axle = float(grips[j]), self.axles[j]
        tip = float(self.stance.tip_margins(heading, pull, a1)) if self.stance.tip is not None else math.nan
        return Margins(rollover, cart, tip, grip, axle, self.train.relief is None)
