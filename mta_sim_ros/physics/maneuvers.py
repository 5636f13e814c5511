"""Named steering manoeuvres, expanded to a piecewise-linear table psi_cmd(t) (rad against s).

Each manoeuvre is a function of keyword parameters (all with defaults) that returns a
:class:`~mta_sim_ros.physics.spec.Table`: strictly increasing times, the command held constant
before the first and after the last point. Smooth shapes are sampled finely enough that linear
interpolation between the samples stays within ``TOLERANCE`` of the exact curve. Positive
steering turns left (REP-103).

``MANEUVERS`` registers them by name for the scene loader; :func:`expand` checks a parameter
dict, fills the parameters the scene knows (``speed``, ``wheelbase``) and checks the peak
steering against the actuator's limit. Faults raise :class:`ParamError`, which names the
parameter, so the loader can say where it sits in the file.
"""
from __future__ import annotations

import inspect
import math
from dataclasses import dataclass
from typing import Callable, Mapping, Optional

import numpy as np

from ..validate import MAX_TABLE, is_finite
from .spec import Table

# rad: largest gap between a sampled smooth shape and its linear interpolation (half the 1e-4
# rad budget, so round-off never pushes it over).
TOLERANCE = 5e-5

# s: the shortest period of a sampled shape (its curvature (2 pi / period)^2 stays in floating point)
SHORTEST = 1e-3

# Parameters a manoeuvre may leave to the scene: the loader fills them when not given.
SCENE_PARAMS = ("speed", "wheelbase")


class ParamError(ValueError):
    """A manoeuvre parameter breaks a rule: ``param: value must be rule``."""

    def __init__(self, param: str, value: object, rule: str):
        super().__init__(f"{param}: {value} must be {rule}")
        self.param, self.value, self.rule = param, value, rule


def _require(ok: bool, param: str, value: object, rule: str) -> None:
    if not ok:
        raise ParamError(param, value, rule)


def _table(time, value) -> Table:
    return Table(time=tuple(float(t) for t in time), value=tuple(float(v) for v in value))


def straight() -> Table:
    """Steering held at zero: a straight line."""
    return _table([0.0], [0.0])


def step(t0: float = 1.0, angle: float = 0.1, rise: float = 0.01) -> Table:
    """Steering jumps from 0 to ``angle`` (rad) at ``t0`` (s).

    A table needs increasing times, so the jump takes ``rise`` seconds; the default 0.01 s is
    far below the actuator's time constant, so the actuator sees a step.
    """
    _require(t0 >= 0, "t0", t0, ">= 0")
    _require(rise > 0, "rise", rise, "> 0")
    return _table([t0, t0 + rise], [0.0, angle])


def ramp(t0: float = 1.0, t1: float = 3.0, angle: float = 0.1) -> Table:
    """Steering rises linearly from 0 at ``t0`` to ``angle`` (rad) at ``t1`` (s), then held."""
    _require(t0 >= 0, "t0", t0, ">= 0")
    _require(t1 > t0, "t1", t1, f"> t0 = {t0}")
    return _table([t0, t1], [0.0, angle])


def sine(amplitude: float = 0.1, period: float = 6.0, t0: float = 1.0, cycles: float = 1.0) -> Table:
    """psi_cmd = amplitude sin(2 pi (t - t0) / period) for ``cycles`` periods from ``t0``, else 0.

    Sampled with step h such that the linear-interpolation error max|psi''| h^2 / 8 =
    amplitude (2 pi / period)^2 h^2 / 8 stays within TOLERANCE.
    """
    _require(t0 >= 0, "t0", t0, ">= 0")
    _require(period >= SHORTEST, "period", period, f"> 0 and at least {SHORTEST:g} s")
    _require(cycles > 0, "cycles", cycles, "> 0")
    omega = 2.0 * math.pi / period
    h = period / 16.0
    curvature = abs(amplitude) * omega**2  # 0 for a zero amplitude (or one that underflows)
    if curvature > 0.0:
        h = min(h, math.sqrt(8.0 * TOLERANCE / curvature))
    length = cycles * period
    samples = length / h + 1
    _require(samples <= MAX_TABLE, "cycles", cycles,
             f"fewer: {samples:.4g} samples of amplitude {amplitude:g} at step {h:.4g} s, more than the {MAX_TABLE} "
             f"entries a table may have")
    s = np.linspace(0.0, length, math.ceil(length / h) + 1)
    return _table(t0 + s, amplitude * np.sin(omega * s))


def slalom(amplitude: float = 0.15, period: float = 10.0, t0: float = 2.0, cycles: float = 3.0) -> Table:
    """Several periods of a sine steer (see :func:`sine`): the train weaves left and right."""
    return sine(amplitude=amplitude, period=period, t0=t0, cycles=cycles)


def lane_change(t0: float = 2.0, amplitude: float = 0.1, duration: float = 6.0) -> Table:
    """One full period of a sine steer from ``t0``: a left-then-right S (for amplitude > 0).

    For the kinematic bicycle th' = V sin(psi)/l the heading change over a full period is
    zero (sin psi is odd about the half period), so the heading returns to its start while the
    lateral position has moved by about V^2 amplitude duration^2 / (2 pi l) to the left.
    """
    _require(duration >= SHORTEST, "duration", duration, f"> 0 and at least {SHORTEST:g} s")
    return sine(amplitude=amplitude, period=duration, t0=t0, cycles=1.0)


def headland_turn(
    t0: float = 5.0,
    angle: float = 0.25,
    speed: Optional[float] = None,
    wheelbase: Optional[float] = None,
    turn_angle: float = math.pi,
    ramp_time: float = 2.0,
) -> Table:
    """A U-turn: steer in linearly to ``angle`` over ``ramp_time``, hold, steer out likewise.

    The hold is chosen so that the kinematic-bicycle heading rate th' = V sin(psi)/l
    (V = ``speed``, l = ``wheelbase``, both constant) integrates to ``turn_angle`` over the
    whole manoeuvre, ramps included. On a ramp psi = angle s/ramp_time, so each ramp turns
    (V/l) ramp_time (1 - cos angle)/angle, and the hold turns (V/l) hold sin(angle).
    A negative ``angle`` turns right. ``speed`` and ``wheelbase`` come from the scene (the
    speed command at t0 and the tractor's length) unless given.
    """
    _require(t0 >= 0, "t0", t0, ">= 0")
    _require(0 < abs(angle) < math.pi / 2, "angle", angle, "nonzero with |angle| < pi/2")
    _require(speed is not None and speed > 0, "speed", speed, "> 0 (a forward speed)")
    _require(wheelbase is not None and wheelbase > 0, "wheelbase", wheelbase, "> 0")
    _require(turn_angle > 0, "turn_angle", turn_angle, "> 0")
    _require(ramp_time > 0, "ramp_time", ramp_time, "> 0")
    a = abs(angle)
    ramps_turn = 2.0 * ramp_time * (1.0 - math.cos(a)) / a * speed / wheelbase
    _require(
        ramps_turn <= turn_angle,
        "ramp_time",
        ramp_time,
        f"shorter: the two ramps alone turn {ramps_turn:.4g} rad > turn_angle {turn_angle:.4g}",
    )
    hold = (turn_angle - ramps_turn) * wheelbase / (speed * math.sin(a))
    t_in, t_out = t0 + ramp_time, t0 + ramp_time + hold
    if hold > 0:
        return _table([t0, t_in, t_out, t_out + ramp_time], [0.0, angle, angle, 0.0])
    return _table([t0, t_in, t_in + ramp_time], [0.0, angle, 0.0])


@dataclass(frozen=True)
class Maneuver:
    """A registered manoeuvre: its table builder and which parameters are angles."""

    build: Callable[..., Table]
    peak: str = ""  # the parameter setting the largest |steering|, checked against max_angle
    angles: frozenset = frozenset()  # parameters in rad (the loader also takes NAME_deg)

    @property
    def defaults(self) -> dict:
        """Parameter name -> default value, from the builder's signature."""
        return {name: p.default for name, p in inspect.signature(self.build).parameters.items()}


MANEUVERS: dict[str, Maneuver] = {
    "straight": Maneuver(straight),
    "step": Maneuver(step, "angle", frozenset({"angle"})),
    "ramp": Maneuver(ramp, "angle", frozenset({"angle"})),
    "sine": Maneuver(sine, "amplitude", frozenset({"amplitude"})),
    "slalom": Maneuver(slalom, "amplitude", frozenset({"amplitude"})),
    "lane_change": Maneuver(lane_change, "amplitude", frozenset({"amplitude"})),
    "headland_turn": Maneuver(headland_turn, "angle", frozenset({"angle", "turn_angle"})),
}


def expand(
    name: str,
    params: Mapping[str, float],
    *,
    speed_at: Optional[Callable[[float], float]] = None,
    wheelbase: Optional[float] = None,
    max_angle: float = math.pi / 2,
) -> Table:
    """The steering table of manoeuvre ``name`` with ``params`` (rad, s, m, m/s).

    A manoeuvre parameter named ``speed`` that is not given becomes ``speed_at(t0)``, the
    scene's speed command when the manoeuvre starts; ``wheelbase`` becomes the given tractor
    length. Raises KeyError for an unknown name and ParamError for a bad parameter or a
    table whose largest |steering| exceeds ``max_angle``.
    """
    maneuver = MANEUVERS[name]
    defaults = maneuver.defaults
    for key, value in params.items():
        _require(key in defaults, key, value, f"a parameter of {name}: one of {', '.join(defaults) or '(none)'}")
        _require(_is_finite_number(value), key, value, "a finite number")
    kwargs = dict(params)
    if "wheelbase" in defaults and "wheelbase" not in kwargs:
        kwargs["wheelbase"] = wheelbase
    if "speed" in defaults and "speed" not in kwargs and speed_at is not None:
        kwargs["speed"] = speed_at(kwargs.get("t0", defaults.get("t0", 0.0)))
    peak_rule = f"within the steering actuator's max_angle {max_angle:.4g} rad"
    if maneuver.peak:  # before building: the peak sets how finely a curve is sampled
        peak_value = kwargs.get(maneuver.peak, defaults[maneuver.peak])
        _require(abs(peak_value) <= max_angle, maneuver.peak, peak_value, peak_rule)
    table = maneuver.build(**kwargs)
    if maneuver.peak:
        largest = max(abs(v) for v in table.value)
        _require(largest <= max_angle, maneuver.peak, peak_value, peak_rule)
    return table


_is_finite_number = is_finite
