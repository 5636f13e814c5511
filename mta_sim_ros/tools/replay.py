"""``mta replay``: play a bag back over ROS 2, or re-simulate it offline and compare.

``mta replay BAG [--rate R] [--loop] [--topics T ...] [--start S] [--ros-args ...]``
    A ROS node (``mta_replay``) that republishes the bag's messages as they were recorded (the
    serialized CDR bytes, unchanged) with their original timing: message i goes out at
    start + (log_time_i - origin) / R on the steady clock, scheduled against the start instant,
    so the pace never drifts. origin = the bag's first message + S seconds (--start). Each
    topic gets a publisher of the channel's type with the QoS the recording publisher offered
    (channel metadata ``offered_qos_profiles``; the node's QoS when absent). Names as the node
    uses them: /clock, /diagnostics, /tf, /tf_static are global, every other recorded topic is
    published relative to the replay node's namespace, so with no remapping the names are as
    recorded and ``--ros-args -r __ns:=/unit2`` moves them under /unit2. Ends at the end of the
    bag (or loops with --loop, each pass starting when the previous one ends) and on SIGINT or
    SIGTERM, after the subscribers have acknowledged the last messages of reliable topics (at
    most ACK_TIMEOUT); shows a progress bar on a terminal. Put BAG before --topics.
    --wait-for-subscribers S holds the start until every publisher has a subscriber (at most
    S seconds): a volatile topic's first messages are lost on a subscriber still matching.

``mta replay BAG --resimulate [--method M] [--step H]``
    No ROS. Rebuilds the run from the bag's own metadata record ``mta_sim_ros`` (the scene and
    train files as read, method, step, rate), feeds the recorded commands into a fresh
    ``sim.Simulation`` tick by tick (the tick starting at t_k holds the last steering_angle and
    speed_setpoint message with log_time <= t_k, as both ``mta run`` and the node stamp them;
    a node bag's commands go through the node's own checks: non-finite refused, out of range
    clamped), and compares the re-simulated hitch_poses, cart_velocities, traction_power and
    applied_steering with the recorded ones at every tick. Prints the largest deviation of
    each and ``identical`` when every value is exactly equal (the same method and step must
    give that). --method / --step re-simulate with another integrator and report how far it
    lands. Exit code 0 when compared, 2 when an option or a value the bag records breaks a rule
    (one line, validate.py; the recorded files by the loader's rules, no path they name opened),
    1 on another error (an unreadable bag, no metadata record).
    Topics may carry a namespace (matched by their last name component); a node bag's time
    may be offset after a reset (metadata ``clock_offset``).
"""
from __future__ import annotations

import argparse
import math
import re
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..bag import BagError, read_messages, read_metadata
from ..messages.topics import WATCHDOG_TOPIC
from ..node.commands import ackermann_setting, command_ranges, hold, twist_setting
from ..node.runlog import RECORD, recorded_options, recorded_scene
from ..physics.spec import INTEGRATOR_METHODS as METHODS
from ..validate import (
    MAX_TICKS,
    NON_NEGATIVE,
    POSITIVE,
    InputError,
    Range,
    fail,
    is_finite,
    number_arg,
    show,
    step_floor,
)
from .run import Progress

#: Outputs compared by --resimulate (last name component of the topic).
OUTPUTS = ("hitch_poses", "cart_velocities", "traction_power", "applied_steering")
#: Commands fed into the re-simulation.
COMMANDS = ("steering_angle", "speed_setpoint", "cmd_vel", "ackermann_cmd", WATCHDOG_TOPIC)
#: Topics republished under their recorded (global) name; the others move with the namespace.
GLOBAL_TOPICS = frozenset({"/clock", "/diagnostics", "/tf", "/tf_static", "/rosout", "/parameter_events"})

#: At the end, how long the replay waits at most for the subscribers to acknowledge the last messages, s.
ACK_TIMEOUT = 2.0

EXIT_ERROR = 1
EXIT_USAGE = 2

#: playback speed factors
PLAY_RATE = Range.of(1e-3, 1e3)
#: seconds --wait-for-subscribers may wait
WAIT = Range.of(0.0, 3600.0, "s")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bag", help="the MCAP bag (from mta run or the node)")
    p.add_argument("--rate", type=number_arg(PLAY_RATE), default=1.0,
                   help=f"playback speed factor (default 1: as recorded; {PLAY_RATE.text})")
    p.add_argument("--loop", action="store_true", help="play again from the start at the end, until stopped")
    p.add_argument("--topics", nargs="+", metavar="T", help="only these topics (as recorded; default: all)")
    p.add_argument("--start", type=number_arg(NON_NEGATIVE), default=0.0, metavar="S",
                   help="start S seconds after the bag's first message (default 0)")
    p.add_argument("--wait-for-subscribers", type=number_arg(WAIT), default=0.0, metavar="S",
                   help="before playing, wait up to S seconds until every topic has a subscriber (default 0)")
    p.add_argument("--resimulate", action="store_true",
                   help="no ROS: re-run the recorded commands through the simulator, compare with the bag")
    p.add_argument("--method", choices=METHODS, metavar="METHOD",
                   help=f"with --resimulate: integrator to use instead of the recorded one ({', '.join(METHODS)})")
    p.add_argument("--step", type=number_arg(POSITIVE),
                   help="with --resimulate: integrator step, s, instead of the recorded one")


def main(args: argparse.Namespace) -> int:
    if args.resimulate:
        if args.loop or args.topics or args.start or args.rate != 1.0 or args.wait_for_subscribers:
            print("mta replay: --rate, --loop, --topics, --start and --wait-for-subscribers are for playing, "
                  "not with --resimulate", file=sys.stderr)
            return EXIT_USAGE
        return resimulate_main(args)
    if args.method or args.step:
        print("mta replay: --method and --step need --resimulate", file=sys.stderr)
        return EXIT_USAGE
    return play_main(args)


# ==================================================================================== playing


def last_component(topic: str) -> str:
    return topic.rstrip("/").rsplit("/", 1)[-1]


def publish_name(topic: str) -> str:
    """The name the replay publishes a recorded topic under (see the module docstring)."""
    return topic if topic in GLOBAL_TOPICS else topic.lstrip("/")


def parse_qos(metadata: dict[str, str]):
    """rclpy QoSProfile of a channel's ``offered_qos_profiles`` (its first publisher), or the
    node's QoS when there is none or it cannot be read."""
    import yaml
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    from ..node.ros_msgs import QOS

    try:
        offered = yaml.safe_load(metadata.get("offered_qos_profiles", "") or "null")
        first = offered[0] if isinstance(offered, list) and offered else None
        if not isinstance(first, dict):
            return QOS
        history = {"keep_last": HistoryPolicy.KEEP_LAST, "keep_all": HistoryPolicy.KEEP_ALL}.get(
            first.get("history"), QOS.history)
        reliability = {"reliable": ReliabilityPolicy.RELIABLE, "best_effort": ReliabilityPolicy.BEST_EFFORT}.get(
            first.get("reliability"), QOS.reliability)
        durability = {"volatile": DurabilityPolicy.VOLATILE, "transient_local": DurabilityPolicy.TRANSIENT_LOCAL}.get(
            first.get("durability"), QOS.durability)
        depth = int(first.get("depth") or QOS.depth)
        return QoSProfile(history=history, depth=depth, reliability=reliability, durability=durability)
    except (yaml.YAMLError, TypeError, ValueError, AttributeError):
        return QOS


def play_main(args: argparse.Namespace) -> int:
    from mcap.reader import make_reader

    try:
        f = open(args.bag, "rb")
    except OSError as err:
        print(f"mta replay: cannot open bag file {args.bag}: {err.strerror or err}", file=sys.stderr)
        return EXIT_ERROR
    with f:
        try:
            reader = make_reader(f)
            summary = reader.get_summary()
        except Exception as err:  # McapError, struct.error... on a damaged file
            print(f"mta replay: cannot read bag file {args.bag}: {err!r} (a bag cut short: mta recover)",
                  file=sys.stderr)
            return EXIT_ERROR
        if summary is None or summary.statistics is None or not summary.statistics.message_count:
            print(f"mta replay: {args.bag} has no messages (or no summary: mta recover)", file=sys.stderr)
            return EXIT_ERROR
        channels = summary.channels
        recorded = sorted({c.topic for c in channels.values()})
        selected = set(recorded)
        if args.topics:
            wanted = {t if t.startswith("/") else "/" + t for t in args.topics}
            unknown = sorted(wanted - selected)
            if unknown:
                print(f"mta replay: {', '.join(unknown)} not in {args.bag} (it holds {', '.join(recorded)})",
                      file=sys.stderr)
                return EXIT_ERROR
            selected = wanted
        bag_start = summary.statistics.message_start_time
        bag_end = summary.statistics.message_end_time
        origin = bag_start + round(args.start * 1e9)
        span = max(0, bag_end - origin)
        if origin > bag_end:
            print(f"mta replay: --start {args.start:g} is past the bag's end "
                  f"({(bag_end - bag_start) / 1e9:.3f} s after its first message)", file=sys.stderr)
            return EXIT_ERROR
        return _play(args, reader, summary, selected, origin, span)


def _play(args, reader, summary, selected: set[str], origin: int, span: int) -> int:
    import rclpy
    from rclpy.duration import Duration
    from rclpy.signals import SignalHandlerOptions

    from ..node.ros_msgs import message_class

    rclpy.init(args=["mta_replay", *getattr(args, "ros_args", [])],
               signal_handler_options=SignalHandlerOptions.NO)
    stop: list[int] = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.append(signum))
    node = rclpy.create_node("mta_replay")
    progress = Progress(span / 1e9)
    published = 0
    try:
        pubs = {}
        for cid, channel in summary.channels.items():
            if channel.topic not in selected:
                continue
            schema = summary.schemas.get(channel.schema_id)
            try:
                cls = message_class(schema.name) if schema else None
            except (ImportError, AttributeError, ValueError):
                cls = None
            if cls is None or channel.message_encoding != "cdr":
                explicit = args.topics is not None
                what = f"type {schema.name if schema else '(none)'} / encoding {channel.message_encoding}"
                print(f"mta replay: {'cannot play' if explicit else 'skipping'} {channel.topic}: {what} "
                      f"not available here", file=sys.stderr)
                if explicit:
                    return EXIT_ERROR
                continue
            pubs[cid] = node.create_publisher(cls, publish_name(channel.topic), parse_qos(dict(channel.metadata)))
        if not pubs:
            print("mta replay: nothing to play", file=sys.stderr)
            return EXIT_ERROR
        if args.wait_for_subscribers > 0:
            deadline = time.monotonic() + args.wait_for_subscribers
            while not stop and time.monotonic() < deadline and any(
                    p.get_subscription_count() == 0 for p in pubs.values()):
                time.sleep(0.02)
        topics = sorted({summary.channels[c].topic for c in pubs})
        scale = 1.0 / (args.rate * 1e9)
        t0 = time.monotonic()
        while not stop:
            for _, channel, message in reader.iter_messages(topics=topics, start_time=origin, log_time_order=True):
                pub = pubs.get(message.channel_id)
                if pub is None:
                    continue
                due = t0 + (message.log_time - origin) * scale
                while not stop and (left := due - time.monotonic()) > 0:
                    time.sleep(min(left, 0.05))
                if stop:
                    break
                pub.publish(bytes(message.data))
                published += 1
                progress.update((message.log_time - origin) / 1e9)
            if not args.loop:
                break
            t0 += (span or 10**9) * scale  # the next pass starts where this one was due to end: no drift
        progress.close()
        # reliable topics: the last messages may still be on their way; leaving now would lose them
        end = time.monotonic() + ACK_TIMEOUT
        for pub in pubs.values():
            pub.wait_for_all_acked(Duration(seconds=max(0.0, end - time.monotonic())))
        print(f"mta replay: {published} messages published"
              + (f" (stopped by signal {stop[0]})" if stop else ""), file=sys.stderr)
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


# ================================================================================ resimulating


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


def _topics_by_name(bag: str, names) -> dict[str, str]:
    """Recorded topic for each wanted last name component (a namespace prefix is allowed)."""
    from ..bag import summary

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
        if math.isfinite(x):  # accepted (held, maybe clamped): session.RunSession.command
            self.rate = None


class _Messages:
    """A cmd_vel or ackermann_cmd command, taken as commands.Setting: what it sets is held."""

    def __init__(self, steering: "_Held", speed: "_Held", rate: _RateLimit):
        self.steering, self.speed, self.rate = steering, speed, rate

    def take(self, setting) -> None:
        if setting.steering is not None:
            self.steering.value = setting.steering
            self.rate.rate = setting.rate
        if setting.speed is not None:
            self.speed.value = setting.speed


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
    bag's (see the module docstring). Raises ResimulationError or BagError."""
    from ..integrate import IntegrationError
    from ..messages.topics import output_messages
    from ..physics.guards import ModelValidityError
    from ..run.simulation import Simulation

    if method is not None and method not in METHODS:
        fail("--method", show(method), f"one of {', '.join(METHODS)}")
    if step is not None and not (is_finite(step) and step > 0):
        fail("--step", show(step), "a finite number > 0")
    meta = read_metadata(bag).get(RECORD)
    if meta is None:
        raise ResimulationError(f"{bag} has no metadata record {RECORD} (not a bag of mta run or the node)")
    node_bag = any(k.startswith("param.") for k in meta)
    recorded = recorded_options(meta, str(bag))
    recorded_method, recorded_step, rate = recorded["method"], recorded["step"], recorded["rate"]
    offset = recorded["clock_offset"]
    scene = recorded_scene(meta, str(bag))
    if step is not None and not step_floor(rate).test(step):
        fail("--step", show(step), step_floor(rate).text)
    sim = Simulation(scene, method=method or recorded_method, step=step or recorded_step, rate=rate,
                     algorithm=recorded["algorithm"], fidelity=recorded["fidelity"],  # the recorded level
                     split_kinks=recorded["split_kinks"])
    result = Resimulation(bag=bag, scene=scene.name, method=sim.method, step=sim.step, tick=sim.tick,
                          recorded_method=recorded_method, recorded_step=recorded_step)
    topics = _topics_by_name(bag, OUTPUTS + COMMANDS)
    missing = [n for n in OUTPUTS if n not in topics]
    if len(missing) == len(OUTPUTS):
        raise ResimulationError(f"{bag} holds none of {', '.join(OUTPUTS)}")
    for name in missing:
        result.notes.append(f"no {name} in the bag")
    result.outputs = {name: Deviation() for name in OUTPUTS if name in topics}
    by_topic = {topic: name for name, topic in topics.items() if name in OUTPUTS}

    ranges = command_ranges(scene) if node_bag else {}
    steering = _Held(sim.command, ranges.get("steering_angle"))
    speed = _Held(sim.v_set, ranges.get("speed_setpoint"))
    steering_rate = _RateLimit(steering)
    wheelbase, actuator = scene.train.carts[0].length, scene.train.actuator
    messages = _Messages(steering, speed, steering_rate)

    def cmd_vel(m):
        return twist_setting(float(m.linear.x), float(m.angular.z), wheelbase, actuator.max_angle)

    def ackermann_cmd(m):
        d = m.drive
        return ackermann_setting(float(d.steering_angle), float(d.steering_angle_velocity), float(d.speed),
                                 actuator.max_angle, actuator.max_rate)

    # (log_time, order, holder, value) in log-time order, ties in the order they were recorded (one
    # read of every command topic: the bag's order, so that of two sources the later one wins);
    # the watchdog's record is the steering the node held from then on (see topics.WATCHDOG_TOPIC)
    readers = {"steering_angle": (steering_rate, float), "speed_setpoint": (speed, float),
               "cmd_vel": (messages, cmd_vel), "ackermann_cmd": (messages, ackermann_cmd),
               WATCHDOG_TOPIC: (steering, float)}
    by_recorded = {topics[n]: readers[n] for n in COMMANDS if n in topics}
    commands = []
    if by_recorded:
        for i, (topic, lt, m) in enumerate(read_messages(bag, list(by_recorded))):
            holder, read = by_recorded[topic]
            commands.append((lt, i, holder, float(m.data) if read is float else read(m)))
    commands.sort(key=lambda c: (c[0], c[1]))
    next_command = 0

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
            now = key()
            while next_command < len(commands) and commands[next_command][0] <= now:
                _, _, holder, value = commands[next_command]
                holder.take(value)
                next_command += 1
            sim.set_rate_limit(steering_rate.rate)
            try:
                sim.advance(steering.value, speed.value)
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
            expected, expected_at = output_messages(out, cart_names), log_time
        compare_message(dev, name, msg, expected[name], t)
    return result


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


def resimulate_main(args: argparse.Namespace) -> int:
    progress = None
    try:
        progress = Progress(_duration(args.bag))
        r = resimulate(args.bag, args.method, args.step, progress)
    except (ResimulationError, BagError, InputError, ValueError, OSError) as err:
        if progress:
            progress.close()
        print(f"mta replay: {err}", file=sys.stderr)
        return EXIT_USAGE if isinstance(err, InputError) else EXIT_ERROR
    progress.close()
    print(report(r))
    return 0


def _duration(bag: str) -> float:
    """Span of the bag's messages, s (for the progress bar)."""
    from mcap.reader import make_reader

    try:
        with open(bag, "rb") as f:
            stats = make_reader(f).get_summary().statistics
            return (stats.message_end_time - stats.message_start_time) / 1e9
    except Exception:  # the real error is reported by resimulate()
        return 0.0
