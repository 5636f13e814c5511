"""Linear stability of the fixed-step methods: the largest step that keeps a decaying mode decaying.

A mode y' = -r y (r > 0, a pole of the model at -r 1/s) stepped with step h is multiplied per step
by the method's stability function R(z) at z = -r h, derived from its tableau (``tableau.py``;
Euler 1 + z, Heun 1 + z + z^2/2, RK4 1 + z + z^2/2 + z^3/6 + z^4/24). It decays while
|R(-r h)| < 1, i.e. while r h is below the method's real-axis stability limit (2 for Euler and
Heun, about 2.785 for RK4). Past it the numerical solution grows every step whatever the physics
does: garbage, not a less accurate answer.

Adaptive solvers need no such limit: the explicit ones (RK45, DOP853) shorten their steps until
the error estimate (and so the stability) is met; LSODA switches to BDF; Radau and BDF are
stable for any decaying mode.
"""
from __future__ import annotations

from ..validate import steps_per_tick
from .tableau import TABLEAUX

#: each fixed-step method's real-axis stability limit, from its tableau
REAL_AXIS_LIMIT = {name: tab.real_axis_limit for name, tab in TABLEAUX.items()}
SAFETY = 0.9  # sub-steps are at most this share of the limit: |R| stays clearly below 1


class UnstableStepError(ValueError):
    """A fixed step is past the stability limit of a mode of the model."""


def stability_function(method: str, z: complex) -> complex:
    """R(z) of a fixed-step method: the factor one step applies to y' = lambda y, z = lambda h."""
    if method not in TABLEAUX:
        raise ValueError(f"method: {method!r} has no fixed stability function (one of {tuple(TABLEAUX)})")
    return TABLEAUX[method].stability_function(z)


def effective_step(step: float, tick: float) -> float:
    """The step a FixedStep really takes over one tick: the tick split in ceil(tick / step) parts."""
    return tick / steps_per_tick(tick, step)


def stable_step(method: str, step: float, tick: float, modes, safety: float = SAFETY):
    """(step to use, note). ``modes`` is a list of (rate r in 1/s, what it is), e.g. from
    ``model.guards.fast_modes``. For an adaptive method, or when the effective step keeps every
    mode inside the stability region, the step is returned unchanged and the note is None.
    Otherwise the step is cut to ``safety`` x the limit of the fastest mode and the note says why."""
    if method not in REAL_AXIS_LIMIT or not modes:
        return step, None
    rate, what = max(modes)
    h = effective_step(step, tick)
    limit = REAL_AXIS_LIMIT[method] / rate
    if h < safety * limit:
        return step, None
    new = safety * limit
    note = (f"{method} with step {h:.4g} s is unstable for this model: {what} decays at "
            f"{rate:.4g} 1/s, and {method} is stable only for step < {REAL_AXIS_LIMIT[method]:.4g} / {rate:.4g} 1/s "
            f"= {limit:.4g} s (its real-axis stability limit); sub-stepping at "
            f"{effective_step(new, tick):.4g} s ({steps_per_tick(tick, new)} steps per {tick:.4g} s tick)")
    return new, note


#: steps per actuator time constant when the steering follows the actuator's closed form: the train
#: is stepped under psi_1(t), which moves like exp(-t / tau) after each command, and the quadrature
#: of that needs the step to resolve tau (docs/benchmarks/kinks.md measures the error against it)
RESOLUTION = 2


def resolved_step(step: float, tick: float, time_constant: float, per: int = RESOLUTION):
    """(step to use, note): at most time_constant / ``per``, so that the stepped train follows the
    actuator's exponential to the accuracy of the method; the note says why (None if unchanged)."""
    limit = time_constant / per
    if effective_step(step, tick) <= limit * (1 + 1e-12):
        return step, None
    note = (f"step {effective_step(step, tick):.4g} s is longer than the steering actuator's time constant "
            f"{time_constant:g} s / {per}; sub-stepping at {effective_step(limit, tick):.4g} s "
            f"({steps_per_tick(tick, limit)} steps per {tick:.4g} s tick) so that the train follows the "
            f"actuator's motion")
    return limit, note
