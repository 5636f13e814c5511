"""The ROS 2 node: real-time simulation of a train, steered over topics, every run logged to MCAP.

Glue between ROS and :class:`run_session.RunSession`, which decides everything (pacing, watchdog,
pause and reset, parameter checks, diagnostics, the bag): this module declares the parameters
of params.PARAMS, makes the publishers, subscriptions, services and the two steady-clock timers
(the tick timer every RunSession.timer_period seconds, the diagnostics at 1 Hz) and hands each callback
straight to the session. The session's messages arrive here as CDR bytes (messages.Encoders), published as
they are.

Commands are taken by the tick timer, not by the executor: the command subscriptions sit in a
callback group the executor never waits on (TakenByTheTick), and each firing of the timer first
takes what they hold, at most MAX_TAKE a topic, then runs the ticks due. A flood of commands
(10 kHz) thus costs the executor nothing: each one once cost a pass of rclpy's wait loop, and
at ~8 kHz those starved the tick. The reader keeps the newest QOS.depth commands of each topic;
older ones of a flood are overwritten before the tick takes them, and what is taken is recorded.
A command waits at most one timer period (the tick, at most pacing.MAX_TIMER_PERIOD) to be
taken, as it would wait for the tick that applies it. The command subscriptions have no QoS event
handlers (rmw_fastrtps wakes an executor waiting on them at every message as well); a publisher
they cannot hear (best effort) is said by the 1 Hz timer, from the graph.

In lockstep (parameter ``lockstep``; pacing.py: the protocol) the command subscriptions are
the executor's: each command is handed to the session and the session fires at once, so a tick
follows an answer by the executor's latency, not a timer's period; the timer (every
pacing.LOCKSTEP_TIMER_PERIOD s) runs the first tick, re-publishes unanswered outputs and says a
stall. A flood then runs one tick per command, as fast as the node can: the controller's pace.

cmd_vel and ackermann_cmd are taken raw (CDR bytes): the bag records them as received and the
session reads them without ROS (messages/commands.py). ackermann_cmd is subscribed where
ackermann_msgs is installed (its Python package and its .msg files), else the start-up log says
it is not.

Interface (relative names: ``--ros-args -r __ns:=/unit1`` moves everything but /clock,
/diagnostics, /tf and /tf_static, which are global by convention; the frames take the prefix
``unit1/``, urdf.frame_prefix):
    subscribes  steering_angle, speed_setpoint            std_msgs/Float64 (rad, m/s)
                cmd_vel                                   geometry_msgs/Twist
                ackermann_cmd                             ackermann_msgs/AckermannDriveStamped
                implement_lowered                         std_msgs/Bool (lowered or lifted)
    publishes   hitch_poses, cart_velocities, traction_power, applied_steering (see topics.py),
                markers (visualization_msgs/MarkerArray), /clock, /diagnostics (1 Hz),
                /tf, /tf_static, joint_states, odom, robot_description (topics.FRAME_TOPICS)
    services    reset (std_srvs/Trigger), pause (std_srvs/SetBool); under the node's name the
                standard simulator services of simulation_interfaces (sim_services.py):
                ~/get_simulator_features, ~/get_simulation_state, ~/set_simulation_state,
                ~/step_simulation, ~/reset_simulation
QoS: ``ros_msgs.QOS`` (reliable, volatile, keep last 10) for everything but the latched topics
/tf_static and robot_description, ``ros_msgs.LATCHED_QOS`` (transient-local, keep last 1).
"""
from __future__ import annotations

import gc
import signal
import sys
import time
import warnings

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import CallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger

from ..messages.topics import BAG_TOPICS, COMMAND_TOPICS, LATCHED_TOPICS, MESSAGE_COMMANDS, WATCHDOG_TOPIC
from . import ros_msgs
from ..validate import one_line
from .params import PARAMS, ConfigError, Param, check_ros_args, override_problem
from .ros_msgs import QOS
from .run_session import RunSession
from .sim_services import offer
from .timing import reserve_cpu

#: most commands of one topic taken at one firing of the tick timer (the reader holds QOS.depth)
MAX_TAKE = 2 * QOS.depth


class TakenByTheTick(CallbackGroup):
    """A callback group the executor never waits on nor runs: its subscriptions' messages are
    taken by the tick timer (SimNode._take_commands)."""

    def can_execute(self, entity) -> bool:
        return False

    def beginning_execution(self, entity) -> bool:
        return False

    def ending_execution(self, entity) -> None:
        pass


def descriptor(p: Param) -> ParameterDescriptor:
    d = ParameterDescriptor(description=p.description + ("" if p.live else " (fixed while running)"),
                            read_only=False)
    if p.low is not None:
        if isinstance(p.default, float):
            d.floating_point_range = [FloatingPointRange(from_value=p.low, to_value=p.high, step=0.0)]
        else:
            d.integer_range = [IntegerRange(from_value=int(p.low), to_value=int(p.high), step=0)]
    return d


class SimNode(Node):
    def __init__(self, profile=None, stop: list | None = None, **kwargs):
        """``profile``: a timing.TickProfile told where each tick's time goes (benchmarks);
        ``stop``: the signals main() has received (a long StepSimulation ends at the first)."""
        try:
            with warnings.catch_warnings():  # rclpy's own warning about the node it could not make
                warnings.simplefilter("ignore", RuntimeWarning)
                super().__init__("mta_sim", **kwargs)
        except RuntimeError as err:  # rclpy's RCLError: a node name or namespace a remap made that rcl refuses
            raise ConfigError(f"--ros-args: {one_line(str(err))}") from None
        for p in PARAMS:
            try:
                self.declare_parameter(p.name, p.default, descriptor(p))
            except Exception as err:  # rclpy raises several types for a bad override
                raise ConfigError(f"parameter {p.name}: {err}") from None
        cfg = {p.name: self.get_parameter(p.name).value for p in PARAMS}
        self.pubs = {topic: self.create_publisher(ros_msgs.message_class(type_name), topic,
                                                  ros_msgs.LATCHED_QOS if topic in LATCHED_TOPICS else QOS)
                     for topic, type_name in BAG_TOPICS.items()
                     if topic not in (*COMMAND_TOPICS, *MESSAGE_COMMANDS, WATCHDOG_TOPIC)}
        self.session = RunSession(cfg, clock=time.monotonic, publish=self._publish, log=self.get_logger(),
                                  name=self.get_name(), namespace=self.get_namespace(), profile=profile)
        lockstep = self.session.lockstep
        group = None if lockstep else TakenByTheTick()  # lockstep: the executor runs them (module docstring)
        # No QoS event handlers on them: rmw_fastrtps wakes an executor waiting on a subscription's
        # events at every message too (a 10 kHz flood kept the executor's thread 70 % busy with
        # them); the 1 Hz timer asks the graph for publishers they cannot hear instead.
        quiet = SubscriptionEventCallbacks(use_default_callbacks=False)
        self.commands = {}
        sources = [(topic, Float64, False) for topic in COMMAND_TOPICS]
        for topic, type_name in {**MESSAGE_COMMANDS, **self.session.inputs.message_types}.items():
            try:
                if topic not in self.session.inputs.message_types:
                    raise ImportError(f"no message definition of {type_name}")
                sources.append((topic, ros_msgs.message_class(type_name), True))
            except (ImportError, AttributeError) as err:
                self.get_logger().info(f"not subscribing {topic}: {type_name} is not installed ({err})")
        for topic, msg_type, raw in sources:
            self.commands[topic] = self.create_subscription(
                msg_type, topic, lambda msg, t=topic: self._command(t, msg), QOS, callback_group=group, raw=raw,
                event_callbacks=quiet)
        self.unheard: set[tuple] = set()  # (topic, publisher gid) already said
        self.create_service(Trigger, "reset", self._on_reset)
        self.create_service(SetBool, "pause", self._on_pause)
        self.quitting = False  # SetSimulationState QUITTING: main() ends the spin loop
        stop = [] if stop is None else stop
        absent = offer(self, self.session, self._quit, before_step=self._take_commands,
                       interrupted=lambda: bool(stop))
        if absent:
            self.get_logger().info(f"not offering the simulation_interfaces services: {absent}")
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.timer = None
        self._make_timer()
        self.create_timer(1.0, self._each_second, clock=self.steady)

    def _publish(self, msgs: dict) -> None:
        for topic, data in msgs.items():
            self.pubs[topic].publish(data)

    def _make_timer(self) -> None:
        if self.timer is not None:
            self.destroy_timer(self.timer)
        self.timer_period = self.session.timer_period
        self.timer = self.create_timer(self.timer_period, self._on_tick, clock=self.steady)

    def _on_tick(self) -> None:
        self._take_commands()
        self.session.fire()

    def _each_second(self) -> None:
        self.session.publish_diagnostics()
        self._say_unheard_publishers()

    def _say_unheard_publishers(self) -> None:
        """Warn once about each command publisher this node cannot hear: a best-effort one (the
        command subscriptions are reliable, QOS; DDS never matches the two)."""
        for topic, sub in self.commands.items():
            for info in self.get_publishers_info_by_topic(sub.topic_name):
                key = (topic, tuple(info.endpoint_gid))
                if info.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT and key not in self.unheard:
                    self.unheard.add(key)
                    who = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                    self.get_logger().warning(
                        f"{sub.topic_name}: the publisher of {who} offers incompatible QoS (best effort): this node "
                        f"subscribes reliable (keep last {QOS.depth}) and receives none of its commands; publish "
                        f"them reliable")

    def _hand(self, topic: str, msg) -> None:
        """One command to the session: a Float64's number, a message's CDR bytes."""
        if topic in COMMAND_TOPICS:
            self.session.command(topic, msg.data)
        else:
            self.session.command_message(topic, msg)

    def _command(self, topic: str, msg) -> None:
        """A command run by the executor (lockstep): to the session, which then ticks if it may."""
        self._hand(topic, msg)
        self.session.fire()

    def _take_commands(self) -> None:
        """Hand the session the commands waiting in the command subscriptions (free running; in
        lockstep the executor has handed them already), in the order the node's readers received
        them, across topics: of two sources, the later one sets what they both set."""
        if self.session.lockstep:
            return
        waiting = []
        for topic, sub in self.commands.items():
            for _ in range(MAX_TAKE):
                with sub.handle:
                    taken = sub.handle.take_message(sub.msg_type, sub.raw)
                if taken is None:
                    break
                waiting.append((taken[1]["received_timestamp"], len(waiting), topic, taken[0]))
        waiting.sort(key=lambda w: w[:2])
        for _, _, topic, msg in waiting:
            self._hand(topic, msg)

    def _on_reset(self, request, response):
        response.message = self.session.reset()
        response.success = True
        return response

    def _on_pause(self, request, response):
        response.message = self.session.pause(request.data)
        response.success = True
        return response

    def _quit(self) -> None:
        self.quitting = True

    def _on_set_parameters(self, params) -> SetParametersResult:
        reason = self.session.set_parameters({p.name: p.value for p in params})
        if self.session.timer_period != self.timer_period:
            self._make_timer()
        return SetParametersResult(successful=not reason, reason=reason)

    def close(self) -> None:
        """Finish the bag (normal exit, SIGINT, SIGTERM), with this run's timing figures."""
        self.session.close()


def main(argv: list[str] | None = None, profile=None) -> int:
    """Entry of ``sim_node`` (ros2 run) and ``mta node``: ROS arguments as for any node
    (``profile``: see SimNode).

    SIGINT and SIGTERM end the spin loop between callbacks, then the bag is finished and the
    context shut down in that order (rclpy's own handlers would invalidate the context while a
    callback may still be writing)."""
    argv = sys.argv if argv is None else argv
    try:
        check_ros_args(argv)  # a params file's faults in one line, before rcl parses it
    except ConfigError as err:
        print(f"sim_node: {err}", file=sys.stderr)
        return 2
    problem = override_problem(argv)  # a -p override rcl cannot parse, likewise
    if problem:
        print(f"sim_node: {problem}", file=sys.stderr)
        return 2
    try:
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    except RuntimeError as err:  # any other ROS argument rcl refuses (rclpy's RCLError is one)
        print(f"sim_node: --ros-args: {one_line(str(err))}", file=sys.stderr)
        return 2
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.append(signum))
    try:
        node = SimNode(profile=profile, stop=stop)
    except ConfigError as err:
        print(f"sim_node: {err}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    # The ~70 000 objects of numpy, scipy and rclpy made at start-up never die: move them out of
    # the collector's reach, or every full collection walks them all inside some tick (26-40 ms
    # measured; 0.2-2 ms frozen, docs/benchmarks/scaling.md).
    gc.collect()
    gc.freeze()
    if node.session.cfg["tick_cpu"] >= 0:  # after every thread of the node exists
        try:
            node.get_logger().info(reserve_cpu(node.session.cfg["tick_cpu"]))
        except (ValueError, OSError) as err:
            print(f"sim_node: {err}", file=sys.stderr)
            node.close()
            node.destroy_node()
            rclpy.try_shutdown()
            return 2
    try:
        while not stop and not node.quitting and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    finally:
        node.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
