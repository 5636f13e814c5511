"""Commands as a receiver holds them: validated, clamped, with their receipt time. No ROS here.

The node takes every steering and speed command through a :class:`CommandInput`, and holds what
all its command topics set in a :class:`HeldCommands`; ``mta replay
--resimulate`` applies the same rule (:func:`hold`) to a node bag's recorded commands, so the
re-simulation holds exactly what the node held.

Four command sources, one rule (:class:`Setting`: what one received message sets):

* ``steering_angle`` (Float64): the steering command psi_cmd, rad; the actuator's own rate limit;
* ``speed_setpoint`` (Float64): the speed set-point, the model's V (the speed of A_1, the front
  axle: what the governor and the prescribed-speed law regulate), m/s;
* ``cmd_vel`` (Twist, or TwistStamped with the parameter cmd_vel_stamped: its twist;
  :func:`twist_setting`): linear.x = v, the speed of the tractor's rear axle
  B_1 (base_link), angular.z = omega, the yaw rate; the bicycle relation of the tractor
  (docs/model.md: th'_1 = V sin psi_1 / l_1, s'_B1 = V cos psi_1, so omega = v tan psi_1 / l_1)
  gives psi_cmd = atan(l_1 omega / v) and V = v / cos psi_cmd (psi_cmd after clamping);
* ``ackermann_cmd`` (AckermannDriveStamped, :func:`ackermann_setting`): steering_angle = psi_cmd,
  speed = v of B_1 as for cmd_vel (V = v / cos psi_cmd), steering_angle_velocity = the rate
  limit of the steering actuator while this command holds (0 = the actuator's own).

and one for the implement: ``implement_lowered`` (Bool): lowered (true, the scene's start) or
lifted (false: the implement cart's draft off, run.simulation.Simulation.set_lowered).

The latest accepted message of any source sets what it sets, and only that: a steering command
(steering_angle, cmd_vel with v != 0, ackermann_cmd) sets psi_cmd together with its rate limit
(the actuator's own for the first two), a speed command (speed_setpoint, cmd_vel, ackermann_cmd)
sets V. A refused message (a non-finite field it uses) sets nothing; a value out of range is
clamped (psi_cmd to +-max_angle, V to +-SPEED_LIMIT, the rate to (0, max_rate]).

A train whose traction law follows no speed (law constant: physics.spec.unfollowed_speed) holds
its force whatever V is set: the first speed command of a run makes ``ignored_speed`` the line
that says so (the node logs it once and shows it in /diagnostics for the rest of the run), and
``speed_ignored`` counts them.
"""
from __future__ import annotations

import dataclasses
import math
import time
from typing import Callable

from ..messages.decode import (TWIST_STAMPED_TYPE, CommandDecodeError, decode_ackermann, decode_bool, decode_twist,
                               decode_twist_stamped)
from ..physics.spec import unfollowed_speed

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
        self.set(value)
        return value

    def set(self, value: float) -> None:
        """Hold ``value`` (already validated) from now: a message of another source set it."""
        self.value = value
        self.received = self.clock()

    def age(self) -> float:
        """Seconds since the last accepted command (since construction before the first)."""
        return self.clock() - self.received


@dataclasses.dataclass
class Setting:
    """What one received command sets (None: leaves it as it is): the steering command psi_cmd
    (rad) with the actuator rate limit that goes with it (rad/s; None = the actuator's own), the
    speed set-point V (m/s); ``problem`` says what was wrong ('' if nothing), ``refused`` that
    the message sets nothing."""

    steering: float | None = None
    rate: float | None = None
    speed: float | None = None
    problem: str = ""
    refused: bool = False
    lowered: bool | None = None  # the implement lowered (implement_lowered)


def _refused(topic: str, fields: dict[str, float]) -> Setting | None:
    bad = [f"{k} = {v}" for k, v in fields.items() if not math.isfinite(v)]
    if bad:
        return Setting(problem=f"{topic}: {', '.join(bad)} is not finite; refused, kept the last command",
                       refused=True)
    return None


def _steer_and_speed(psi: float, v: float, max_angle: float, problems: list[str]) -> Setting:
    """psi_cmd clamped to +-max_angle, and V = v / cos(psi_cmd) (rear-axle speed v, the tractor
    on the bicycle relation) clamped to +-SPEED_LIMIT."""
    steering, why = hold(psi, -max_angle, max_angle)
    if why:
        problems.append(f"steering {psi:.4g} rad {why}")
    V = v / math.cos(steering)
    speed, why = hold(V, -SPEED_LIMIT, SPEED_LIMIT)
    if why:
        problems.append(f"speed {V:.4g} m/s {why}")
    return Setting(steering=steering, speed=speed)


def twist_setting(v: float, omega: float, wheelbase: float, max_angle: float) -> Setting:
    """What a cmd_vel (linear.x = v, the rear axle's speed, m/s; angular.z = omega, rad/s) sets,
    for a tractor of ``wheelbase`` l_1 whose steering reaches +-max_angle.

    v != 0: psi_cmd = atan(l_1 omega / v), the bicycle relation (atan, not atan2: in reverse,
    v < 0, a left yaw rate is a right steering angle, and |psi_cmd| < 90 deg), clamped to
    +-max_angle; V = v / cos(psi_cmd), so that B_1 runs at v once the steering has settled.
    v = 0: no steering gives a yaw rate at standstill (the wheels do not slip sideways), so the
    message sets the speed (0) and leaves the steering command as it is (the session holds it
    afresh: a controller talking at standstill is not a lost one for the watchdog)."""
    refused = _refused("cmd_vel", {"linear.x": v, "angular.z": omega})
    if refused:
        return refused
    if v == 0.0:
        return Setting(speed=0.0)
    problems: list[str] = []
    s = _steer_and_speed(math.atan(wheelbase * omega / v), v, max_angle, problems)
    s.problem = "cmd_vel: " + "; ".join(problems) if problems else ""
    return s


def ackermann_setting(steering_angle: float, steering_angle_velocity: float, speed: float,
                      max_angle: float, max_rate: float) -> Setting:
    """What an ackermann_cmd sets: psi_cmd = steering_angle clamped to +-max_angle; V = speed /
    cos(psi_cmd) (speed is the rear axle's, as for cmd_vel); the rate limit = |steering_angle_velocity|
    clamped to max_rate, the actuator's own (a commanded rate can slow the steering, not drive the
    cylinder past its limit), or the actuator's own when it is 0 (the message's "as fast as
    possible"). acceleration and jerk are not used: the traction law has its own dynamics."""
    refused = _refused("ackermann_cmd", {"steering_angle": steering_angle,
                                         "steering_angle_velocity": steering_angle_velocity, "speed": speed})
    if refused:
        return refused
    problems: list[str] = []
    s = _steer_and_speed(steering_angle, speed, max_angle, problems)
    if steering_angle_velocity != 0.0:
        rate = abs(steering_angle_velocity)
        if rate > max_rate:
            problems.append(f"steering_angle_velocity {steering_angle_velocity:.4g} rad/s beyond the actuator's "
                            f"{max_rate:.4g}; clamped")
            rate = max_rate
        s.rate = rate
    s.problem = "ackermann_cmd: " + "; ".join(problems) if problems else ""
    return s


class MessageInput:
    """The counts of one message command topic (cmd_vel, ackermann_cmd), as CommandInput keeps
    them for a Float64 one: received, refused, clamped, and what was wrong with the last one."""

    def __init__(self, name: str):
        self.name = name
        self.count = self.rejected = self.clamped = 0
        self.last_problem = ""

    def take(self, setting: Setting) -> Setting:
        self.count += 1
        self.rejected += setting.refused
        self.clamped += bool(setting.problem) and not setting.refused
        self.last_problem = setting.problem
        return setting


class HeldCommands:
    """What a run holds of its commands, by the rule above: the steering command and speed
    set-point the next tick holds (``steering``, ``speed``), the steering's rate limit
    (``rate_limit``; None: the actuator's own), and for each source what it received and what was
    wrong. ``message_types``: the message command topics taken (topic -> type; cmd_vel, and
    ackermann_cmd where installed); ``clock``: steady wall seconds (each command's age)."""

    def __init__(self, scene, v_set: float, message_types: dict[str, str], clock: Callable[[], float]):
        ranges = command_ranges(scene)
        self.steering = CommandInput(scene.initial.steering, *ranges["steering_angle"], "steering_angle", clock)
        self.speed = CommandInput(v_set, *ranges["speed_setpoint"], "speed_setpoint", clock)
        self.floats = {"steering_angle": self.steering, "speed_setpoint": self.speed}
        self.message_types = message_types
        self.messages = {t: MessageInput(t) for t in message_types}
        self.wheelbase, self.actuator = scene.train.carts[0].length, scene.train.actuator
        self.rate_limit: float | None = None
        self.lowered = True  # the implement (implement_lowered): lowered until commanded
        self.unfollowed = unfollowed_speed(scene.train.traction)  # '': the traction law follows V
        self.ignored_speed, self.speed_ignored = "", 0

    def _speed_taken(self, topic: str) -> None:
        """A speed command from ``topic`` was held: counted, and said, when the law ignores it."""
        if self.unfollowed:
            self.speed_ignored += 1
            self.ignored_speed = self.ignored_speed or (
                f"{topic}: speed commands are ignored: the train's {self.unfollowed}")

    def take(self, topic: str, x: float) -> str:
        """A Float64 command received on ``topic`` (steering_angle, speed_setpoint): held if
        valid, clamped to its range, or refused; returns what was wrong ('' if nothing)."""
        inp = self.floats[topic]
        held = inp.take(x)
        if held is not None and topic == "steering_angle":
            self.rate_limit = None  # the rate limit goes with the steering command: the actuator's own
        elif held is not None:
            self._speed_taken(topic)
        return inp.last_problem if held != x else ""  # refused or clamped

    def take_message(self, topic: str, data: bytes) -> str:
        """A command message received on ``topic`` (cmd_vel, ackermann_cmd) as its CDR bytes:
        what it sets (twist_setting, ackermann_setting) is held, clamped, or it is refused;
        returns what was wrong ('' if nothing)."""
        try:
            if topic == "cmd_vel":
                decode = decode_twist_stamped if self.message_types[topic] == TWIST_STAMPED_TYPE else decode_twist
                setting = twist_setting(*decode(data), self.wheelbase, self.steering.high)
            elif topic == "implement_lowered":
                setting = Setting(lowered=decode_bool(data))
            else:
                setting = ackermann_setting(*decode_ackermann(data), self.steering.high, self.actuator.max_rate)
        except CommandDecodeError as err:
            setting = Setting(problem=f"{topic}: {err}; refused", refused=True)
        self.messages[topic].take(setting)
        if setting.steering is not None:
            self.steering.set(setting.steering)
            self.rate_limit = setting.rate
        elif not setting.refused and topic != "implement_lowered":  # cmd_vel at v = 0 holds the steering as it
            self.steering.set(self.steering.value)  # is: a fresh command for the watchdog
        if setting.speed is not None:
            self.speed.set(setting.speed)
            self._speed_taken(topic)
        if setting.lowered is not None:
            self.lowered = setting.lowered
        return setting.problem

    def restart(self, steering: float, speed: float) -> None:
        """A new run holding ``steering`` and ``speed``: its own commands, no problem yet."""
        self.steering.value, self.speed.value = steering, speed
        self.steering.last_problem = self.speed.last_problem = ""
        for inp in self.messages.values():
            inp.last_problem = ""
        self.rate_limit = None
        self.lowered = True
        self.ignored_speed, self.speed_ignored = "", 0

    def problems(self) -> list[str]:
        """What was wrong with the last command of each source ('' where nothing)."""
        return [self.steering.last_problem, self.speed.last_problem, *(m.last_problem for m in self.messages.values()),
                self.ignored_speed]
