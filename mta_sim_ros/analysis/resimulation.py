"""A bag re-simulated (``mta replay --resimulate``; no ROS): the run rebuilt from the bag's own
metadata record ``mta_sim_ros`` (the scene and train files as read, method, step, rate), the
recorded commands fed into a fresh ``Simulation`` tick by tick, and the re-simulated outputs
(hitch_poses, cart_velocities, traction_power, applied_steering) compared with the recorded ones
at every tick.

The tick starting at t_k holds the last steering_angle and speed_setpoint message with log_time <=
t_k, as both ``mta run`` and the node stamp them; a node bag's commands go through the node's own
checks (non-finite refused, out of range clamped; commands.py), cmd_vel, ackermann_cmd and
implement_lowered through its rule for each, and the watchdog's records are the steering the node
held. Topics may carry a namespace (matched by their last name component); a node bag's time may be
offset after a reset (metadata ``clock_offset``). The same method and step give every value exactly
(``identical``).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from ..bag import read_messages, summary
from ..messages.topics import WATCHDOG_TOPIC
from ..node.commands import Setting, ackermann_setting, command_ranges, hold, twist_setting
from ..node.runlog import RECORD, recorded_options, recorded_scene
from ..physics.spec import INTEGRATOR_METHODS as METHODS
from ..validate import MAX_TICKS, fail, is_finite, show, step_floor
from .bagdata import last_component, run_record

#: Outputs compared (last name component of the topic).
OUTPUTS = ("hitch_poses", "cart_velocities", "traction_power", "applied_steering")
#: Commands fed into the re-simulation.
COMMANDS = ("steering_angle", "speed_setpoint", "cmd_vel", "ackermann_cmd", "implement_lowered", WATCHDOG_TOPIC)


@dataclass
class Deviation:
    """How far one re-simulated output lands from the recorded one."""

    largest: float = 0.0  # largest |re-simulated - recorded| over every numeric field and tick
    where: str = ""  # in which field (e.g. poses[2].position.y)
    t: float = math.nan  # at which log time, s
    compared: int = 0  # messages compared
    mismatches: list[str] = field(default_factory=list)  # stamps, names, sizes, messages off the ticks

    def add(self, diff: float, where: str, t: float) -> None:
        if diff > self.largest or (math.isnan(diff) and not math.isnan(self.largest)):
            self.largest, self.where, self.t = diff, where, t


@dataclass
class Resimulation:
    bag: str
    scene: str
    method: str
    step: float
    tick: float
    recorded_method: str
    recorded_step: float
    ticks: int = 0
    outputs: dict[str, Deviation] = field(default_factory=dict)
    stopped: str = ""  # the error that stopped the re-simulation before the bag's end
    not_compared: int = 0  # recorded outputs after that
    notes: list[str] = field(default_factory=list)

    @property
    def identical(self) -> bool:
        return (not self.stopped and not self.not_compared and bool(self.outputs)
                and all(d.compared and d.largest == 0.0 and not d.mismatches for d in self.outputs.values()))


class ResimulationError(Exception):
    """The bag cannot be re-simulated (no metadata, files that do not load, ...)."""


def topics_by_name(bag: str, names) -> dict[str, str]:
    """Recorded topic for each wanted last name component (a namespace prefix is allowed)."""
    found: dict[str, list[str]] = {}
    for topic in summary(bag):
        found.setdefault(last_component(topic), []).append(topic)
    out = {}
    for name in names:
        topics = found.get(name, [])
        if len(topics) > 1:
            raise ResimulationError(f"several topics end in {name}: {', '.join(sorted(topics))}")
        if topics:
            out[name] = topics[0]
    return out


def _flatten(value, path: str = ""):
    """(path, value) of every leaf of a plain-dict message, lists indexed."""
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _flatten(v, f"{path}.{k}" if path else k)
    elif isinstance(value, (list, tuple)):
        yield f"{path}#len", len(value)
        for i, v in enumerate(value):
            yield from _flatten(v, f"{path}[{i}]")
    else:
        yield path, value


def _leaf(msg, path: str):
    """The value at ``path`` (as made by _flatten) of a decoded message."""
    obj = msg
    for part in re.findall(r"[^.\[\]#]+|\[\d+\]|#len", path):
        if part == "#len":
            return len(obj)
        obj = obj[int(part[1:-1])] if part.startswith("[") else getattr(obj, part)
    return obj


def compare_message(dev: Deviation, name: str, recorded, expected: dict, t: float) -> None:
    """Fold one recorded message against the re-simulated plain-dict message into ``dev``:
    floats as deviations, integers (stamps, lengths) and names as mismatches; frame ids are
    not compared (they may change while the node runs)."""
    dev.compared += 1
    for path, want in _flatten(expected):
        if path.endswith("frame_id"):
            continue
        try:
            got = _leaf(recorded, path)
        except (AttributeError, IndexError, TypeError):
            dev.mismatches.append(f"t = {t:.6f} s: {name} has no {path}")
            return
        if isinstance(want, float):
            got = float(got)
            if got == want or (math.isnan(got) and math.isnan(want)):
                continue
            diff = abs(got - want)
            dev.add(math.inf if math.isnan(diff) else diff, path, t)
        elif got != want:
            dev.mismatches.append(f"t = {t:.6f} s: {name} {path} is {got!r}, re-simulated {want!r}")
            if path.endswith("#len"):
                return


class _RateLimit:
    """A steering_angle command: held as a _Held, and the actuator's own rate limit with it
    (commands.py: the rate goes with the steering command)."""

    def __init__(self, steering: "_Held"):
        self.steering, self.rate = steering, None

    def take(self, x: float) -> None:
        self.steering.take(x)
        if math.isfinite(x):  # accepted (held, maybe clamped): run_session.RunSession.command
            self.rate = None


class _Messages:
    """A cmd_vel or ackermann_cmd command, taken as commands.Setting: what it sets is held."""

    def __init__(self, steering: "_Held", speed: "_Held", rate: _RateLimit):
        self.steering, self.speed, self.rate = steering, speed, rate
        self.lowered = True  # the implement (implement_lowered), lowered until commanded

    def take(self, setting) -> None:
        if setting.steering is not None:
            self.steering.value = setting.steering
            self.rate.rate = setting.rate
        if setting.speed is not None:
            self.speed.value = setting.speed
        if setting.lowered is not None:
            self.lowered = setting.lowered


class _Held:
    """A command as the receiver holds it: the node refuses non-finite values and clamps to its
    range (``commands.hold``); ``mta run`` takes the values as they are (no range)."""

    def __init__(self, value: float, limits: tuple[float, float] | None):
        self.value, self.limits = value, limits

    def take(self, x: float) -> None:
        if self.limits is None:
            self.value = x
            return
        value, _ = hold(x, *self.limits)
        if value is not None:
            self.value = value



def resimulate(bag: str, method: str | None = None, step: float | None = None, progress=None) -> Resimulation:
    """Re-run the bag's commands through a fresh Simulation and compare the outputs with the
    bag's (see the module docstring); ``progress`` (if any) is told the simulated time. Raises
    ResimulationError or BagError, InputError when an option or a recorded value breaks a rule."""
    from ..integrate import IntegrationError
    from ..messages.topics import output_messages
    from ..physics.guards import ModelValidityError

    sim, scene, offset, node_bag, result = rebuilt(bag, method, step)
    topics = topics_by_name(bag, OUTPUTS + COMMANDS)
    missing = [n for n in OUTPUTS if n not in topics]
    if len(missing) == len(OUTPUTS):
        raise ResimulationError(f"{bag} holds none of {', '.join(OUTPUTS)}")
    for name in missing:
        result.notes.append(f"no {name} in the bag")
    result.outputs = {name: Deviation() for name in OUTPUTS if name in topics}
    by_topic = {topic: name for name, topic in topics.items() if name in OUTPUTS}
    inputs = RecordedInputs(bag, topics, scene, sim, node_bag)

    def key() -> int:  # log time of the current tick, ns, as the recorders compute it
        return round((offset + sim.t) * 1e9)

    cart_names = [c.name for c in scene.train.carts]
    expected, expected_at = None, None
    for topic, log_time, msg in read_messages(bag, list(by_topic)):
        name = by_topic[topic]
        dev = result.outputs[name]
        t = log_time / 1e9
        if result.stopped:
            result.not_compared += 1
            continue
        if log_time - key() > MAX_TICKS * sim.tick * 1e9:
            fail("log time", f"{t:.6g} s", f"at most {MAX_TICKS:.0e} ticks of {sim.tick:g} s after the run's "
                 f"{sim.t:.6g} s", f"{topic}", str(bag))
        while key() < log_time:
            inputs.take_until(key())
            sim.set_rate_limit(inputs.steering_rate.rate)
            sim.set_lowered(inputs.messages.lowered)
            try:
                sim.advance(inputs.steering.value, inputs.speed.value)
            except (ModelValidityError, IntegrationError) as err:
                result.stopped = str(err)
                break
            result.ticks += 1
            if progress is not None:
                progress.update(sim.t)
        if result.stopped:
            result.not_compared += 1
            continue
        if key() != log_time:
            dev.compared += 1
            dev.mismatches.append(f"t = {t:.9f} s: {name} recorded between ticks")
            continue
        if expected_at != log_time:
            out = sim.outputs()
            out.t = offset + sim.t  # the node publishes offset + run time
            expected, expected_at = output_messages(out, cart_names, relief=scene.train.relief), log_time
        compare_message(dev, name, msg, expected[name], t)
    return result


def rebuilt(bag: str, method: str | None, step: float | None):
    """(simulation, scene, clock offset, whether a node wrote the bag, the empty Resimulation) of
    the run the bag's metadata record describes, with ``method`` and ``step`` if given."""
    from ..run.simulation import Simulation

    if method is not None and method not in METHODS:
        fail("--method", show(method), f"one of {', '.join(METHODS)}")
    if step is not None and not (is_finite(step) and step > 0):
        fail("--step", show(step), "a finite number > 0")
    meta = run_record(bag)
    if meta is None:
        raise ResimulationError(f"{bag} has no metadata record {RECORD} and no run_metadata topic (not a bag of "
                                "mta run or of the node)")
    node_bag = any(k.startswith("param.") for k in meta)
    recorded = recorded_options(meta, str(bag))
    recorded_method, recorded_step, rate = recorded["method"], recorded["step"], recorded["rate"]
    scene = recorded_scene(meta, str(bag))
    if step is not None and not step_floor(rate).test(step):
        fail("--step", show(step), step_floor(rate).text)
    sim = Simulation(scene, method=method or recorded_method, step=step or recorded_step, rate=rate,
                     algorithm=recorded["algorithm"], fidelity=recorded["fidelity"],  # the recorded level
                     split_kinks=recorded["split_kinks"])
    result = Resimulation(bag=bag, scene=scene.name, method=sim.method, step=sim.step, tick=sim.tick,
                          recorded_method=recorded_method, recorded_step=recorded_step)
    return sim, scene, recorded["clock_offset"], node_bag, result


class RecordedInputs:
    """The bag's commands as the receiver held them: ``steering`` and ``speed`` (_Held), the
    steering's rate limit (``steering_rate.rate``), applied in log-time order by ``take_until``."""

    def __init__(self, bag: str, topics: dict[str, str], scene, sim, node_bag: bool):
        ranges = command_ranges(scene) if node_bag else {}
        self.steering = _Held(sim.command, ranges.get("steering_angle"))
        self.speed = _Held(sim.v_set, ranges.get("speed_setpoint"))
        self.steering_rate = _RateLimit(self.steering)
        wheelbase, actuator = scene.train.carts[0].length, scene.train.actuator
        self.messages = messages = _Messages(self.steering, self.speed, self.steering_rate)

        def cmd_vel(m):  # a Twist, or a TwistStamped (the node's cmd_vel_stamped): its twist
            twist = getattr(m, "twist", m)
            return twist_setting(float(twist.linear.x), float(twist.angular.z), wheelbase, actuator.max_angle)

        def ackermann_cmd(m):
            d = m.drive
            return ackermann_setting(float(d.steering_angle), float(d.steering_angle_velocity), float(d.speed),
                                     actuator.max_angle, actuator.max_rate)

        # (log_time, order, holder, value) in log-time order, ties in the order they were recorded (one
        # read of every command topic: the bag's order, so that of two sources the later one wins);
        # the watchdog's record is the steering the node held from then on (see topics.WATCHDOG_TOPIC)
        readers = {"steering_angle": (self.steering_rate, float), "speed_setpoint": (self.speed, float),
                   "cmd_vel": (messages, cmd_vel), "ackermann_cmd": (messages, ackermann_cmd),
                   "implement_lowered": (messages, lambda m: Setting(lowered=bool(m.data))),
                   WATCHDOG_TOPIC: (self.steering, float)}
        by_recorded = {topics[n]: readers[n] for n in COMMANDS if n in topics}
        self.commands = []
        if by_recorded:
            for i, (topic, lt, m) in enumerate(read_messages(bag, list(by_recorded))):
                holder, read = by_recorded[topic]
                self.commands.append((lt, i, holder, float(m.data) if read is float else read(m)))
        self.commands.sort(key=lambda c: (c[0], c[1]))
        self.next = 0

    def take_until(self, now: int) -> None:
        """Hold every command logged at or before ``now`` (ns) not yet held."""
        while self.next < len(self.commands) and self.commands[self.next][0] <= now:
            _, _, holder, value = self.commands[self.next]
            holder.take(value)
            self.next += 1


UNITS = {"hitch_poses": "m / quaternion", "cart_velocities": "rad, m/s, N", "traction_power": "W",
         "applied_steering": "rad"}


def report(r: Resimulation) -> str:
    lines = [f"{r.bag}: scene '{r.scene}', recorded with {r.recorded_method} step {r.recorded_step:g} s; "
             f"re-simulated {r.ticks} ticks of {r.tick:g} s with {r.method} step {r.step:g} s"]
    for name, d in r.outputs.items():
        if not d.compared:
            lines.append(f"  {name:<17} nothing compared")
            continue
        text = "0 (exact)" if d.largest == 0 else f"{d.largest:.3e} ({d.where} at t = {d.t:.3f} s)"
        lines.append(f"  {name:<17} largest deviation {text}  [{UNITS[name]}], {d.compared} messages")
        for m in d.mismatches[:5]:
            lines.append(f"      mismatch: {m}")
        if len(d.mismatches) > 5:
            lines.append(f"      ... {len(d.mismatches) - 5} more mismatches")
    if r.stopped:
        lines.append(f"  re-simulation stopped: {r.stopped}; {r.not_compared} recorded messages after that "
                     f"not compared")
    lines += [f"  note: {n}" for n in r.notes]
    lines.append("identical" if r.identical else "deviations found")
    return "\n".join(lines)
