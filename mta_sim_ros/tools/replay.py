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
import signal
import sys
import time

from ..analysis.resimulation import ResimulationError, report, resimulate
from ..bag import BagError
from ..physics.spec import INTEGRATOR_METHODS as METHODS
from ..validate import NON_NEGATIVE, POSITIVE, InputError, Range, number_arg, one_line
from .run import Progress

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
        try:  # every chunk's CRC checked as it is read: a damaged one stops the play, never sent as data
            reader = make_reader(f, validate_crcs=True)
            summary = reader.get_summary()
        except Exception as err:  # McapError, struct.error... on a damaged file
            print(unreadable(args.bag, err), file=sys.stderr)
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


def unreadable(bag: str, err: Exception, published: int | None = None) -> str:
    """The one line of a bag that cannot be read (on opening it, or after ``published`` messages)."""
    what = one_line(f"{type(err).__name__}: {err}")[:200]
    after = "" if published is None else f" after {published} messages"
    return f"mta replay: cannot read bag file {bag}{after}: {what} (a bag cut short or damaged: mta recover {bag} -o OUT.mcap)"


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
        try:
            while not stop:
                for _, channel, message in reader.iter_messages(topics=topics, start_time=origin,
                                                                log_time_order=True):
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
        except Exception as err:  # a chunk damaged past the summary: its CRC, its compression
            progress.close()
            print(unreadable(args.bag, err, published), file=sys.stderr)
            return EXIT_ERROR
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
