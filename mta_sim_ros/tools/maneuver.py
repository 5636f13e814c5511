"""``mta maneuver``: a node that plays a scene's steering (and speed) table on sim time, then exits.

It follows /clock: at each simulation instant whose table value differs from the last one sent
it publishes it on ``steering_angle`` (and ``speed_setpoint`` when the scene has a speed table),
time counted from the first /clock it hears, so it plays the same whether the simulator runs at
wall-clock speed or faster. Between changes it streams the value it holds at --rate Hz (default
20) of the wall clock, as a joystick or controller does, so the simulator's watchdog (a command
older than its timeout, wall seconds, is stale) never takes a held value for a lost one. ``--maneuver NAME --param k=v`` replaces the scene's steering by a named manoeuvre
(``mta_sim_ros.maneuvers``: step, ramp, sine, slalom, lane_change, headland_turn, straight).
"""
from __future__ import annotations

import argparse
import dataclasses
import signal
import sys
import time
import warnings
from pathlib import Path

import rclpy
import rclpy.clock
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64

from ..config import resolve_config_path
from ..node.ros_msgs import QOS
from ..physics import maneuvers
from ..physics.loader import SpecError, load_scene, speed_at
from ..run.simulation import table_value
from ..validate import DURATION, Range, number_arg


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", default="scenes/headland_turn.yaml", help="scene whose steering/speed to play")
    p.add_argument("--maneuver", choices=tuple(maneuvers.MANEUVERS), metavar="NAME",
                   help=f"play this named manoeuvre instead of the scene's steering ({', '.join(maneuvers.MANEUVERS)})")
    p.add_argument("--param", action="append", default=[], metavar="K=V", help="manoeuvre parameter (repeatable)")
    p.add_argument("--duration", type=number_arg(DURATION),
                   help="s of sim time to play (default: the scene's duration)")
    p.add_argument("--rate", type=number_arg(STREAM_RATE), default=DEFAULT_RATE,
                   help=f"Hz (wall clock) at which the held command is sent again between changes (default {DEFAULT_RATE:g})")


#: commands a second the player sends at least (wall clock)
DEFAULT_RATE = 20.0
STREAM_RATE = Range.of(0.1, 1000.0, "Hz")


class ManeuverPlayer(Node):
    def __init__(self, scene, duration: float, rate: float = DEFAULT_RATE):
        super().__init__("mta_maneuver")
        self.scene, self.duration = scene, duration
        self.steering = self.create_publisher(Float64, "steering_angle", QOS)
        self.speed = self.create_publisher(Float64, "speed_setpoint", QOS) if scene.speed else None
        self.create_subscription(Clock, "/clock", self._on_clock, QOS)
        self.start: float | None = None
        self.done = False
        self.last = (None, None)
        self.create_timer(1.0 / rate, self._stream,
                          clock=rclpy.clock.Clock(clock_type=rclpy.clock.ClockType.STEADY_TIME))

    def _send(self, steer: float, speed: float | None) -> None:
        self.steering.publish(Float64(data=steer))
        if self.speed is not None:
            self.speed.publish(Float64(data=speed))
        self.last = (steer, speed)

    def _stream(self) -> None:
        """The held command again (the wall-clock timer), once playing."""
        if self.last[0] is not None and not self.done:
            self._send(*self.last)

    def _on_clock(self, msg: Clock) -> None:
        now = msg.clock.sec + msg.clock.nanosec * 1e-9
        if self.start is None:
            self.start = now
            self.get_logger().info(f"playing '{self.scene.name}' for {self.duration:g} s from sim time {now:.3f}")
        t = now - self.start
        if t > self.duration:
            self.done = True
            return
        steer = table_value(self.scene.steering, t)
        speed = table_value(self.scene.speed, t) if self.scene.speed else None
        if (steer, speed) != self.last:  # a change at once; the held value streams (_stream)
            self._send(steer, speed)


def main(args: argparse.Namespace) -> int:
    try:
        scene = load_scene(resolve_config_path(args.scene))
        if args.maneuver:
            scene = scene_with_maneuver(scene, args.maneuver, parse_params(args.param))
        elif args.param:
            raise ValueError("--param: given without --maneuver (the scene's own steering takes none)")
    except (SpecError, ValueError) as err:
        print(f"mta maneuver: {err}", file=sys.stderr)
        return 2
    return spin_until_done(lambda: ManeuverPlayer(scene, args.duration or scene.duration, args.rate), args.ros_args)


def scene_with_maneuver(scene, name: str, params: dict[str, float]):
    """The scene steered by the named manoeuvre instead of its own table."""
    if name not in maneuvers.MANEUVERS:
        raise ValueError(f"--maneuver: {name!r} must be one of {', '.join(maneuvers.MANEUVERS)}")
    try:
        table = maneuvers.expand(name, params, speed_at=speed_at(scene),
                                 wheelbase=scene.train.carts[0].length, max_angle=scene.train.actuator.max_angle)
    except maneuvers.ParamError as err:
        raise ValueError(f"--param {err.param}: {err.value} must be {err.rule}") from None
    return dataclasses.replace(scene, steering=table, maneuver=name)


def parse_params(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        try:
            out[key.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--param: {item!r} must be NAME=NUMBER") from None
        if not sep:
            raise ValueError(f"--param: {item!r} must be NAME=NUMBER")
    return out


def spin_and_report(make_node, ros_args: list[str], report: str | None = None) -> int:
    """``spin_until_done``, then the node's ``figures`` written as JSON to ``report`` (if given):
    what the example controllers (follow, reverse) measured; a figure not measured (no sample: an
    interrupted run) is null, not NaN, and a report that cannot be written is one line, exit 1."""
    from ..writing import json_text, write_output

    holder = {}

    def make():
        holder["node"] = make_node()
        return holder["node"]

    code = spin_until_done(make, ros_args)
    if report and "node" in holder:
        text = json_text(holder["node"].figures)
        try:
            write_output(Path(report), lambda path: path.write_text(text))
        except OSError as err:
            print(f"mta: --report {report} cannot be written ({err.strerror or err})", file=sys.stderr)
            return code or 1
    return code


def spin_until_done(make_node, ros_args: list[str]) -> int:
    """Spin a node until its ``done`` flag is set or SIGINT/SIGTERM arrives. ROS arguments rcl
    cannot parse (a parameter override of bad YAML, ...) are one line and exit 2."""
    
    from ..node.params import override_problem
    from ..validate import EXIT_INPUT, one_line

    problem = override_problem(["--ros-args", *ros_args[1:]] if ros_args else [])
    if problem:  # before rcl, which would say it twice (a log line and an exception)
        print(f"mta: {problem}", file=sys.stderr)
        return EXIT_INPUT
    try:
        rclpy.init(args=["mta", *ros_args], signal_handler_options=SignalHandlerOptions.NO)
    except RuntimeError as err:  # rclpy's RCLError: a ROS argument rcl refuses
        print(f"mta: --ros-args {' '.join(ros_args[1:])}: {one_line(str(err))}", file=sys.stderr)
        return EXIT_INPUT
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.append(signum))
    try:
        with warnings.catch_warnings():  # rclpy's own warning about the node it could not make
            warnings.simplefilter("ignore", RuntimeWarning)
            node = make_node()
    except RuntimeError as err:  # rclpy's RCLError: a node name or namespace a remap made that rcl refuses
        rclpy.try_shutdown()
        print(f"mta: --ros-args {' '.join(ros_args[1:])}: {one_line(str(err))}", file=sys.stderr)
        return EXIT_INPUT
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        while not stop and not node.done and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
        if hasattr(node, "finish"):
            node.finish()
            deadline = time.monotonic() + getattr(node, "linger", 0.0)  # what it published last, delivered
            while time.monotonic() < deadline and rclpy.ok():
                executor.spin_once(timeout_sec=0.05)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return getattr(node, "exit_code", 0)
