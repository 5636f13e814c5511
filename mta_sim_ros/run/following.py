"""Whether a governor held its set speed, read off a run sample by sample. No ROS here.

The governor (physics/kernel/laws.py) drives V towards the set speed with a force it clips to
min(max_force, max_power / max(|V|, 0.1)) (spec.governor_limit). Where the force the speed needs
is over that limit (a grade, a deep implement, a speed past the engine's power), the train runs
slower than it was told and the set speed is not followed. ``GovernorWatch`` notes each sample the
governor is at its limit with the speed short of its set-point: a run's report says for how long
and by how much (summary.RunSummary), the node's /diagnostics says it while it lasts longer than
HOLD (an acceleration at full force, shorter than that, is the governor doing its job). The level
chooser predicts the same before a run from the scene's inputs (fidelity.unheld_speed).
"""
from __future__ import annotations

import math

from ..physics.spec import Traction, governor_limit

#: s the governor stays at its limit, the speed short, before the node's /diagnostics warns
HOLD = 5.0
#: relative: the force within this of the limit counts as at it (the clip returns the limit itself)
AT_LIMIT = 1e-9
#: m/s: a speed this close to its set-point is held, whatever the force
HELD = 1e-3


class GovernorWatch:
    """Sample by sample (``add``, an Outputs): the time the governor of ``traction`` spent at its
    limit with the speed short of its set-point, the longest such spell, the largest shortfall. A
    law other than the governor follows its set speed by construction (prescribed_speed, the
    kinematic level) or has none to follow (constant: spec.unfollowed_speed): the watch stays empty.
    ``prescribed``: the run is on the kinematic level, which prescribes the set speed and takes the
    force by inverse dynamics; there the watch notes the samples whose force is over the limit (a
    governor would have fallen short there)."""

    def __init__(self, traction: Traction, prescribed: bool = False):
        self.traction = traction
        self.prescribed = prescribed
        self.active = traction.law == "governor"
        self.total = 0.0  # s at the limit and short
        self.longest = 0.0  # s, the longest spell
        self.spell = 0.0  # s, the spell going on now (0 when not at the limit)
        self.shortfall = 0.0  # m/s, the largest |set-point| - |V| at the limit
        self.limit = math.nan  # N, the limit in the latest sample
        self.speed = self.setpoint = math.nan  # m/s, the latest sample's
        self.duration = 0.0
        self._t = math.nan

    def add(self, out) -> None:
        if not self.active:
            return
        dt = out.t - self._t if self._t == self._t else 0.0
        self._t = out.t
        self.duration += dt
        self.speed, self.setpoint = out.speed, out.speed_setpoint
        self.limit = governor_limit(self.traction, out.speed)
        short = math.copysign(1.0, out.speed_setpoint) * (out.speed_setpoint - out.speed)
        if self.prescribed:
            over = abs(out.traction) > self.limit * (1.0 + AT_LIMIT)
        else:
            over = abs(out.traction) >= self.limit * (1.0 - AT_LIMIT) and short > HELD
        if over:
            self.spell += dt
            self.total += dt
            self.longest = max(self.longest, self.spell)
            self.shortfall = max(self.shortfall, short)
        else:
            self.spell = 0.0

    def problem(self) -> str:
        """'' unless the governor has been at its limit, the speed short, for HOLD s or more up to the
        latest sample; then that, in one clause for /diagnostics."""
        if self.spell < HOLD:
            return ""
        if self.prescribed:
            return (f"the set speed {self.setpoint:g} m/s takes more force than the governor's limit min(max_force, "
                    f"max_power / |V|) = {self.limit:.4g} N for {self.spell:.1f} s (the kinematic level prescribes it)")
        return (f"the governor cannot hold the set speed {self.setpoint:g} m/s: at its limit min(max_force, "
                f"max_power / |V|) = {self.limit:.4g} N for {self.spell:.1f} s, the speed {self.speed:.3g} m/s")

    def row(self) -> str:
        """The run report's cell: '' when there is no governor."""
        if not self.active:
            return ""
        if self.total == 0.0:
            return "yes: the governor within its limit throughout"
        if self.prescribed:
            return (f"not by a governor: the force the kinematic level takes to prescribe it is over the governor's "
                    f"limit min(max_force, max_power / |V|) for {self.total:.1f} of {self.duration:.1f} s")
        return (f"{'no' if self.longest >= HOLD else 'yes, but for short spells'}: the governor at its limit "
                f"min(max_force, max_power / |V|) for {self.total:.1f} of {self.duration:.1f} s (longest {self.longest:.1f}"
                f" s), the speed up to {self.shortfall:.3g} m/s short of its set-point")
