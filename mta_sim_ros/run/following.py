"""Whether a governor held its set speed, read off a run sample by sample. No ROS here.

The governor (physics/kernel/laws.py) drives V towards the set speed with a force it clips to
min(max_force, max_power / max(|V|, 0.1)) (laws.limit_of). Where the force the speed needs is past
that limit, the train leaves its set speed: slower where it cannot pull enough (a grade, a deep
implement, a speed past the engine's power), faster where it cannot brake enough (downhill). A
sample counts when the force is at the limit and pushes the way the speed's error asks (the error
v_set - V and F_A1 of one sign: the governor is doing all it can) with the speed more than HELD off.
``GovernorWatch`` keeps how long, the longest spell and how far the speed fell short of or ran over
its set-point: a run's report says it (summary.RunSummary), the node's /diagnostics says it while
a spell lasts longer than HOLD (an acceleration at full force, shorter than that, is the governor
doing its job). The level chooser predicts it before a run from the scene's inputs
(fidelity.unheld_speed, for the pull on a plane: up its fall line).

On the kinematic level, which prescribes the set speed and takes the force by inverse dynamics,
the watch counts the samples whose force is past the limit instead: a governor would have left
the set speed there.
"""
from __future__ import annotations

import math

from ..physics.kernel import NATURAL, limit_of
from ..physics.spec import Traction

#: s the governor stays at its limit, the speed off its set-point, before the node's /diagnostics warns
HOLD = 5.0
#: relative: the force within this of the limit counts as at it (the clip returns the limit itself)
AT_LIMIT = 1e-9
#: m/s: a speed this close to its set-point is held, whatever the force
HELD = 1e-3
#: a run's last speed this close to its set-point (relative, at least CLOSE_FLOOR m/s) has reached it
CLOSE, CLOSE_FLOOR = 0.01, 0.01


class GovernorWatch:
    """Sample by sample (``add``, an Outputs): the time the governor of ``traction`` spent at its
    limit unable to hold the set speed (module docstring), the longest such spell, and the largest
    |v_set - V| then with V behind the set-point (short of it, the way it points) and past it (over
    it). A law other than the governor follows
    its set speed by construction (prescribed_speed) or has none to follow (constant:
    spec.unfollowed_speed): the watch stays empty. ``prescribed``: the run is on the kinematic level
    (module docstring)."""

    def __init__(self, traction: Traction, prescribed: bool = False):
        self.traction = traction
        self.prescribed = prescribed
        self.active = traction.law == "governor"
        self.total = 0.0  # s at the limit, unable to hold the speed
        self.longest = 0.0  # s, the longest spell
        self.spell = 0.0  # s, the spell going on now (0 when there is none)
        self.shortfall = 0.0  # m/s, the largest |v_set - V| in a spell, V behind v_set
        self.excess = 0.0  # m/s, the largest |v_set - V| in a spell, V past v_set
        self.limit = math.nan  # N, the limit in the latest sample
        self.speed = self.setpoint = math.nan  # m/s, the latest sample's
        self.duration = 0.0
        self._t = math.nan
        # (t, |v_set - V|) sampled once every HOLD s, the latest and the one before: is the gap closing?
        # (two numbers kept, not every sample: the node's tick calls add)
        self._mark = self._earlier = (math.nan, math.nan)
        self._next_mark = -math.inf

    def add(self, out) -> None:
        if not self.active:
            return
        dt = out.t - self._t if self._t == self._t else 0.0
        self._t = out.t
        self.duration += dt
        self.speed, self.setpoint = out.speed, out.speed_setpoint
        if out.t >= self._next_mark:
            self._earlier, self._mark = self._mark, (out.t, abs(out.speed_setpoint - out.speed))
            self._next_mark = out.t + HOLD
        law = self.traction
        self.limit = limit_of(law.max_force, law.max_power, out.speed, NATURAL, NATURAL)
        error = out.speed_setpoint - out.speed
        if self.prescribed:
            unheld = abs(out.traction) > self.limit * (1.0 + AT_LIMIT)
        else:
            unheld = abs(out.traction) >= self.limit * (1.0 - AT_LIMIT) and error * out.traction > 0.0 and \
                abs(error) > HELD
        if not unheld:
            self.spell = 0.0
            return
        self.spell += dt
        self.total += dt
        self.longest = max(self.longest, self.spell)
        if self.prescribed:
            return
        if error * out.speed_setpoint > 0.0:  # behind the set-point, the way it points
            self.shortfall = max(self.shortfall, abs(error))
        else:  # past it (a set-point of 0: any speed is past it)
            self.excess = max(self.excess, abs(error))

    def problem(self) -> str:
        """'' unless the governor has been unable to hold the set speed for HOLD s or more up to the
        latest sample; then that, in one clause for /diagnostics."""
        if self.spell < HOLD:
            return ""
        if self.prescribed:
            return (f"the set speed {self.setpoint:g} m/s takes more force than the governor's limit min(max_force, "
                    f"max_power / abs(V)) = {self.limit:.4g} N for {self.spell:.1f} s (the kinematic level prescribes it)")
        return (f"the governor cannot hold the set speed {self.setpoint:g} m/s: at its limit min(max_force, "
                f"max_power / abs(V)) = {self.limit:.4g} N for {self.spell:.1f} s, the speed {self.speed:.3g} m/s")

    def row(self) -> str:
        """The run report's cell: '' when there is no governor. "yes" where the governor never was at
        its limit and the run ends at its set-point; "yes, but for short spells" where each spell at
        the limit was shorter than HOLD and the speed came back; "no" where one lasted HOLD; "not by
        the end" where the run ends off its set-point (CLOSE), in a spell shorter than HOLD or with
        the governor within its limit (a start off the set speed: the gains kp, ki set how fast)."""
        if not self.active:
            return ""
        end = "" if self.prescribed else self.end_gap()
        if self.total == 0.0:
            return f"not by the end: the governor within its limit throughout{end}" if end else \
                "yes: the governor within its limit throughout"
        verdict = "no" if self.longest >= HOLD else \
            "not by the end" if end or self.spell > 0.0 else "yes, but for short spells"
        spells = f"{seconds(self.total)} of {seconds(self.duration)} s (longest {seconds(self.longest)} s)"
        if self.prescribed:
            return (f"{verdict} (the kinematic level prescribes it): the force it takes over the governor's limit "
                    f"min(max_force, max_power / abs(V)) for {spells}")
        off = [f"{v:.3g} m/s {word} its set-point" for v, word in ((self.shortfall, "short of"), (self.excess, "over"))
               if v > 0.0]
        return (f"{verdict}: the governor at its limit min(max_force, max_power / abs(V)) for {spells}, the speed up "
                f"to {' and up to '.join(off)}" + ("" if self.spell > 0.0 else end))

    def end_gap(self) -> str:
        """'' where the latest speed is within CLOSE of its set-point, else the clause saying how far
        off it is (the way it points: short of it, or over it)."""
        error = self.setpoint - self.speed
        if not abs(error) > max(CLOSE * abs(self.setpoint), CLOSE_FLOOR):
            return ""
        word = "short of" if error * self.setpoint > 0.0 else "over"
        # against the mark HOLD to 2 HOLD s back (the latest may be this very sample), else the first
        t_then, then = self._earlier if self._earlier[0] == self._earlier[0] else self._mark
        trend = "closing in" if abs(error) < then else "drifting from it"
        return (f"; the speed ends {abs(error):.3g} m/s {word} its set-point, {trend} over its last "
                f"{self._t - t_then:.1f} s")


def seconds(t: float) -> str:
    """A duration for the report: 0.1 s steps, two digits below that (a spell of one tick is not 0.0)."""
    return f"{t:.1f}" if t >= 0.1 else f"{t:.2g}"
