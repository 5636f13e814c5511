"""The ROS 2 node: real-time simulation of a train, steered over topics, every run logged to MCAP.

A thin bridge around :class:`sim.Simulation`. A steady-clock timer fires every tick / rtf
seconds (rtf = real_time_factor; 0 = as fast as possible); each firing advances the model by one
tick of simulated time holding the latest commands (zero-order hold), publishes the outputs
stamped with simulation time, and records them. A slow tick makes the simulation fall behind the
wall clock (reported in /diagnostics), it never skips physics.

Interface (relative names: ``--ros-args -r __ns:=/unit1`` moves everything but /clock and
/diagnostics, which are global by convention):
    subscribes  steering_angle, speed_setpoint            std_msgs/Float64 (rad, m/s)
    publishes   hitch_poses, cart_velocities, traction_power, applied_steering (see topics.py),
                markers (visualization_msgs/MarkerArray), /clock, /diagnostics (1 Hz)
    services    reset (std_srvs/Trigger), pause (std_srvs/SetBool)
QoS: one profile for everything, ``QOS``: reliable, volatile, keep last 10.
"""
from __future__ import annotations

import gc
import math
import signal
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Float64
from std_srvs.srv import SetBool, Trigger

from . import __version__, ros_msgs
from .commands import CommandInput, command_ranges
from .integrate import METHODS, IntegrationError
from .messages import OutputEncoder, TrainMarkers, encode_diagnostics
from .model.guards import ModelValidityError
from .model.loader import SpecError, load_scene
from .recorder import RunRecorder
from .sim import Simulation
from .timing import TickStats, reserve_cpu
from .topics import TOPICS, WATCHDOG_TOPIC, WATCHDOG_TYPE, qualified

QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.VOLATILE)



def config_dir() -> Path:
    """The package's config folder: share/mta_sim_ros/config when installed by colcon, else the
    source tree's config/ (pip install -e, or running from a checkout)."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

        share = Path(get_package_share_directory("mta_sim_ros")) / "config"
        if share.is_dir():
            return share
    except (ImportError, PackageNotFoundError, ValueError, OSError):  # OSError: no AMENT_PREFIX_PATH (a pip venv)
        pass
    return Path(__file__).resolve().parent.parent / "config"


def resolve_config_path(path: str) -> str:
    """A relative path as given if it exists from the working directory, else inside config_dir()
    (so 'scenes/headland_turn.yaml' works from anywhere)."""
    p = Path(path)
    if p.is_absolute() or p.exists():
        return str(p)
    for base in (config_dir(), config_dir().parent):
        if (base / p).exists():
            return str(base / p)
    return str(p)


@dataclass(frozen=True)
class Param:
    name: str
    default: object
    description: str
    live: bool  # may change while running
    low: float | None = None
    high: float | None = None
    choices: tuple = ()


PARAMS = (
    Param("scene_file", "scenes/headland_turn.yaml",
          "scene YAML: the train, its start pose and the integrator (its steering table is not used: "
          "the node is steered over steering_angle)", live=False),
    Param("integrator_method", "", f"integrator, '' = the scene's; one of {', '.join(METHODS)}", live=False,
          choices=("",) + METHODS),
    Param("integrator_step", 0.0, "integrator step, s; 0 = the scene's", live=False, low=0.0, high=1.0),
    Param("publish_rate", 100.0, "ticks (and publications) per second of simulated time, Hz", live=False,
          low=1.0, high=1000.0),
    Param("real_time_factor", 1.0, "simulated seconds per wall second; 0 = as fast as possible", live=True,
          low=0.0, high=1000.0),
    Param("watchdog_timeout", 1.0, "a steering command older than this (wall s) is stale; 0 = never", live=True,
          low=0.0, high=3600.0),
    Param("watchdog_action", "hold", "on a stale command: 'hold' the last one or steer 'straight'", live=True,
          choices=("hold", "straight")),
    Param("frame_id", "map", "frame of hitch_poses and markers", live=True),
    Param("bag_dir", "bags", "folder of the run bags <UTC start>_<run id>.mcap", live=False),
    Param("record", True, "write every run to an MCAP bag", live=False),
    Param("marker_rate", 10.0, "markers per second of simulated time, Hz", live=False, low=0.1, high=1000.0),
    Param("tick_cpu", -1, "CPU for the tick's thread alone (the node's other threads move off it; start "
          "other processes elsewhere for a reserved core); -1 = no pinning", live=False, low=-1, high=4095),
    Param("fidelity", "", "model level: '' = the scene's (auto: the cheapest meeting its needs), or auto, "
          "kinematic, dynamic, slip; a change applies at the next reset", live=True,
          choices=("", "auto", "kinematic", "dynamic", "slip")),
)


class ConfigError(ValueError):
    """Invalid node configuration: one clear message, the node does not start."""


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
    def __init__(self, **kwargs):
        super().__init__("mta_sim", **kwargs)
        for p in PARAMS:
            try:
                self.declare_parameter(p.name, p.default, descriptor(p))
            except Exception as err:  # rclpy raises several types for a bad override
                raise ConfigError(f"parameter {p.name}: {err}") from None
        self.cfg = {p.name: self.get_parameter(p.name).value for p in PARAMS}
        check_config(self.cfg)
        try:
            self.scene = load_scene(resolve_config_path(self.cfg["scene_file"]))
        except SpecError as err:
            raise ConfigError(f"parameter scene_file: {err}") from None
        try:
            self.sim = self._simulation()
        except ValueError as err:  # a level this train cannot run (kinematic without a commanded speed)
            raise ConfigError(f"parameter fidelity: {err}") from None
        self.cart_names = [c.name for c in self.scene.train.carts]
        ranges = command_ranges(self.scene)
        self.steering = CommandInput(self.scene.initial.steering, *ranges["steering_angle"], "steering_angle")
        self.speed = CommandInput(self.sim.v_set, *ranges["speed_setpoint"], "speed_setpoint")

        self.clock_offset = 0.0  # published time = offset + run time; keeps /clock monotonic over resets
        self.paused = False
        self.watchdog_straight = False  # steering 0 held in place of a stale command
        self.halted = ""  # why the model stopped (jackknife...): the node stays up until a reset
        self.stats = TickStats()  # wall time of each tick's work
        # the tick thread's CPU time over the same work: wall >> CPU means the thread was preempted
        # (other processes on the core), not that the tick's code was slow
        self.cpu_stats = TickStats()
        self.run_started = time.monotonic()
        self.ticks_since_markers = 0
        self.marker_every = max(1, round(self.cfg["publish_rate"] / self.cfg["marker_rate"]))
        self._make_encoders()
        self.wall_start = time.monotonic()
        self.sim_at_wall_start = 0.0

        self.pubs = {topic: self.create_publisher(ros_msgs.message_class(type_name), topic, QOS)
                     for topic, type_name in TOPICS.items() if topic not in ("steering_angle", "speed_setpoint")}
        self.pubs["markers"] = self.create_publisher(ros_msgs.message_class(MARKERS_TYPE), "markers", QOS)
        self.pubs["/diagnostics"] = self.create_publisher(ros_msgs.message_class(DIAGNOSTICS_TYPE),
                                                          "/diagnostics", QOS)
        self.create_subscription(Float64, "steering_angle", self._on_steering, QOS)
        self.create_subscription(Float64, "speed_setpoint", self._on_speed, QOS)
        self.create_service(Trigger, "reset", self._on_reset)
        self.create_service(SetBool, "pause", self._on_pause)
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.recorder = None
        self.logged_bag_error = ""
        if self.cfg["record"]:
            local = {**TOPICS, "markers": MARKERS_TYPE, "/diagnostics": DIAGNOSTICS_TYPE, WATCHDOG_TOPIC: WATCHDOG_TYPE}
            in_bag = {t: qualified(t, self.get_namespace()) for t in local}  # e.g. hitch_poses -> /unit1/hitch_poses
            # background: the MCAP writing runs on a thread of its own, off the tick (recorder.py)
            self.recorder = RunRecorder(self.cfg["bag_dir"], {in_bag[t]: ty for t, ty in local.items()},
                                        self._run_metadata(), background=True, rename=in_bag)
            self._start_bag()

        self.steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.timer = None
        self._make_timer()
        self.create_timer(1.0, self._publish_diagnostics, clock=self.steady)
        self.get_logger().info(
            f"scene '{self.scene.name}', {len(self.cart_names)} carts, {self.sim.method} step {self.sim.step:g} s, "
            f"tick {self.sim.tick:g} s, real-time factor {self.cfg['real_time_factor']:g}; "
            f"fidelity {self.sim.choice.reason}; {self.sim.compiled_note}")

    def _simulation(self) -> Simulation:
        """A Simulation of the scene with the node's integrator and fidelity parameters."""
        self.sim_fidelity = self.cfg["fidelity"] or None  # what the running level was built from
        with warnings.catch_warnings():  # said once, through the ROS log, below
            warnings.simplefilter("ignore", RuntimeWarning)
            sim = Simulation(self.scene, method=self.cfg["integrator_method"] or None,
                             step=self.cfg["integrator_step"] or None, rate=self.cfg["publish_rate"],
                             fidelity=self.cfg["fidelity"] or None)
        if sim.stability_note:  # the configured step is past the method's stability limit
            self.get_logger().warning(sim.stability_note)
        return sim

    # -- timing ----------------------------------------------------------------------------
    @property
    def now(self) -> float:
        """Published simulation time, s."""
        return self.clock_offset + self.sim.t

    def _make_timer(self) -> None:
        if self.timer is not None:
            self.destroy_timer(self.timer)
        rtf = self.cfg["real_time_factor"]
        self.period = self.sim.tick / rtf if rtf > 0 else 0.0
        self.timer = self.create_timer(self.period, self._on_tick, clock=self.steady)
        self.wall_start, self.sim_at_wall_start = time.monotonic(), self.now

    def _on_tick(self) -> None:
        if self.paused or self.halted:
            return
        started, cpu_started = time.perf_counter(), time.thread_time()
        command = self._held_steering()
        try:
            self.sim.advance(command, self.speed.value)
        except (ModelValidityError, IntegrationError) as err:
            self.halted = str(err)
            self.get_logger().error(f"simulation halted (call reset to start again): {err}")
            self._publish_diagnostics()
            return
        out = self.sim.outputs()
        out.t = self.now
        msgs = self.encoder.encode(out)  # CDR bytes: the same bytes go to DDS and to the bag
        self.ticks_since_markers += 1
        if self.ticks_since_markers >= self.marker_every:
            self.ticks_since_markers = 0
            msgs["markers"] = self.markers.encode(out)
        for topic, data in msgs.items():
            self.pubs[topic].publish(data)
        if self.recorder is not None and self.recorder.recording:  # the same bytes, to the bag writer's thread
            self.recorder.write_batch(msgs, round(self.now * 1e9))
        cpu = time.thread_time() - cpu_started
        self.stats.record(time.perf_counter() - started, deadline=self.period if self.period > 0 else None)
        self.cpu_stats.record(cpu)

    def _make_encoders(self) -> None:
        """The tick's messages as CDR templates (messages.OutputEncoder, TrainMarkers), for the
        current frame_id (at start and when the parameter changes)."""
        self.encoder = OutputEncoder(self.cart_names, self.cfg["frame_id"])
        self.markers = TrainMarkers(self.scene.train, self.cfg["frame_id"])

    def _held_steering(self) -> float:
        """The steering command for this tick: the latest one, or 0 (straight) while the watchdog
        replaces a stale one. Each change of who decides is recorded (WATCHDOG_TOPIC)."""
        timeout = self.cfg["watchdog_timeout"]
        straight = timeout > 0 and self.steering.age() > timeout and self.cfg["watchdog_action"] == "straight"
        if straight != self.watchdog_straight:
            self.watchdog_straight = straight
            self._record({WATCHDOG_TOPIC: Float64(data=0.0 if straight else self.steering.value)})
        return 0.0 if straight else self.steering.value

    def _record(self, msgs: dict) -> None:
        """Log messages (topic -> message or its CDR bytes) at the current simulation time. The
        writing happens on the recorder's thread: a failure (disk full) shows up later, in
        ``recorder.error``, which ``_publish_diagnostics`` reports and logs once."""
        if self.recorder is not None and self.recorder.recording:
            self.recorder.write_batch({topic: msg if isinstance(msg, bytes) else serialize_message(msg)
                                       for topic, msg in msgs.items()}, round(self.now * 1e9))

    # -- commands --------------------------------------------------------------------------
    def _on_steering(self, msg: Float64) -> None:
        self._take(self.steering, msg, "steering_angle")

    def _on_speed(self, msg: Float64) -> None:
        self._take(self.speed, msg, "speed_setpoint")

    def _take(self, inp: CommandInput, msg: Float64, topic: str) -> None:
        self._record({topic: msg})  # every command as received, at the simulation time it arrived
        if inp.take(msg.data) != msg.data:  # rejected (None) or clamped
            self.get_logger().warning(inp.last_problem, throttle_duration_sec=1.0)

    # -- services --------------------------------------------------------------------------
    def _on_reset(self, request, response):
        if self.recorder is not None:
            self.recorder.close(self.run_figures())  # this run's bag, with its figures
        self.stats, self.cpu_stats = TickStats(), TickStats()
        self.watchdog_straight = False  # so that the new bag records it again if it still holds
        self.run_started = time.monotonic()
        self.clock_offset = self.now
        if (self.cfg["fidelity"] or None) != self.sim_fidelity:  # the level changes only here
            self.sim = self._simulation()
            if self.recorder is not None:
                self.recorder.metadata.update(self._run_metadata())
            self.get_logger().info(f"fidelity {self.sim.choice.reason}")
        self.sim.reset()
        self.steering.value = self.scene.initial.steering
        self.speed.value = self.sim.v_set
        self.halted = ""
        self.wall_start, self.sim_at_wall_start = time.monotonic(), self.now
        path = self._start_bag()
        response.success = True
        response.message = f"reset to the start of '{self.scene.name}' at t = {self.now:.3f} s" + (
            f"; recording {path}" if path else "")
        self.get_logger().info(response.message)
        return response

    def _on_pause(self, request, response):
        self.paused = bool(request.data)
        self.wall_start, self.sim_at_wall_start = time.monotonic(), self.now
        response.success = True
        response.message = "paused" if self.paused else "running"
        return response

    def _on_set_parameters(self, params) -> SetParametersResult:
        by_name = {p.name: p for p in PARAMS}
        for param in params:
            spec = by_name.get(param.name)
            if spec is None:
                continue
            if not spec.live and param.value != self.cfg[param.name]:
                return SetParametersResult(successful=False,
                                           reason=f"{param.name} cannot change while running: it is fixed at "
                                                  f"start (restart the node with the new value)")
            if spec.choices and param.value not in spec.choices:
                return SetParametersResult(successful=False,
                                           reason=f"{param.name}: {param.value!r} must be one of {spec.choices}")
            if param.name == "fidelity":
                try:
                    Simulation(self.scene, rate=self.cfg["publish_rate"], fidelity=param.value or None)
                except ValueError as err:
                    return SetParametersResult(successful=False, reason=f"fidelity: {err}")
                self.get_logger().info(f"fidelity {param.value or 'of the scene'}: applies at the next reset")
        for param in params:
            if param.name in self.cfg:
                self.cfg[param.name] = param.value
                if param.name == "real_time_factor":
                    self._make_timer()
                if param.name == "frame_id":
                    self._make_encoders()  # the frame is part of the templates
        return SetParametersResult(successful=True)

    # -- run log and diagnostics -----------------------------------------------------------
    def _run_metadata(self) -> dict[str, str]:
        meta = {
            "package_version": __version__,
            "scene_file": self.scene.source,
            "scene_yaml": Path(self.scene.source).read_text(),
            "train_file": self.scene.train.source,
            "train_yaml": Path(self.scene.train.source).read_text(),
            "method": self.sim.method,
            "step": str(self.sim.step),
            "stepper_step": str(self.sim.stepper_step),  # smaller than step when sub-stepping for stability
            "stability_note": self.sim.stability_note or "",
            "right_hand_side": self.sim.compiled_note,  # compiled (numba) tick or the Python path; same results
            "rate": str(self.cfg["publish_rate"]),
            "algorithm": "2",
            "fidelity": self.sim.level,
            "fidelity_reason": self.sim.choice.reason,
        }
        meta.update({f"param.{k}": str(v) for k, v in self.cfg.items()})
        return meta

    def _start_bag(self) -> Path | None:
        if self.recorder is None:
            return None
        self.recorder.metadata["clock_offset"] = repr(self.clock_offset)
        path = self.recorder.start()
        if path is None:
            self.logged_bag_error = self.recorder.error
            self.get_logger().error(self.recorder.error)
        else:
            self.get_logger().info(f"recording {path}")
        return path

    def _publish_diagnostics(self) -> None:
        if self.recorder is not None and self.recorder.error not in ("", self.logged_bag_error):
            self.logged_bag_error = self.recorder.error  # said once in the log; every second in /diagnostics
            self.get_logger().error(self.recorder.error)
        wall = time.monotonic() - self.wall_start
        rtf = (self.now - self.sim_at_wall_start) / wall if wall > 0 else 0.0
        margin = self.sim.outputs().jackknife_margin
        values = {
            "sim_time_s": self.now,
            "real_time_factor": rtf,
            "real_time_factor_target": self.cfg["real_time_factor"],
            # how far simulated time trails the wall clock (times the target factor): slow ticks
            # make the simulation fall behind, they never skip physics
            "lag_s": max(0.0, wall * self.cfg["real_time_factor"] - (self.now - self.sim_at_wall_start))
            if not self.paused else 0.0,
            "tick_compute_p50_ms": self.stats.window_percentile(50) * 1e3,
            "tick_compute_p99_ms": self.stats.window_percentile(99) * 1e3,
            "tick_compute_max_ms": self.stats.window_max * 1e3,
            "tick_cpu_p99_ms": self.cpu_stats.window_percentile(99) * 1e3,
            "deadline_misses": self.stats.deadline_misses,
            "tick_period_ms": self.period * 1e3,
            "steering_command_age_s": self.steering.age(),
            "steering_commands": self.steering.count,
            "steering_rejected": self.steering.rejected,
            "steering_clamped": self.steering.clamped,
            "jackknife_margin_deg": math.degrees(margin),
            "fidelity": self.sim.level,
            "fidelity_reason": self.sim.choice.reason,
            "fidelity_at_next_reset": self.cfg["fidelity"] or "the scene's",
            "paused": self.paused,
            "bag": str(self.recorder.path) if self.recorder and self.recorder.recording else "",
        }
        problems = [p for p in (self.halted, self.recorder.error if self.recorder else "",
                                self.steering.last_problem, self.speed.last_problem) if p]
        stale = self.cfg["watchdog_timeout"] > 0 and self.steering.age() > self.cfg["watchdog_timeout"]
        if stale:
            problems.append(f"steering command stale ({self.steering.age():.1f} s): "
                            f"{self.cfg['watchdog_action']}")
        level = DiagnosticStatus.ERROR if self.halted else DiagnosticStatus.WARN if problems else DiagnosticStatus.OK
        msg = encode_diagnostics(self.now, f"{self.get_name()}: simulation", level,
                                 "; ".join(problems) or "running", values)
        self.pubs["/diagnostics"].publish(msg)
        self._record({"/diagnostics": msg})

    def run_figures(self) -> dict[str, str]:
        """Whole-run tick compute statistics (s) and deadline misses, as strings."""
        figures = {f"tick_{k}": repr(v) for k, v in self.stats.summary().items() if not k.startswith("window")}
        figures.update({f"tick_cpu_{k}": repr(v) for k, v in self.cpu_stats.summary().items()
                        if k in ("p50", "p99", "p99.9", "max")})
        if self.recorder is not None:  # the bag writer's own thread: off the tick, not in tick_*
            figures["recorder_thread_cpu"] = repr(self.recorder.thread_cpu)
        figures.update(sim_time=repr(self.now), tick_period=repr(self.period),
                       run_sim_time=repr(self.sim.t), run_wall_time=repr(time.monotonic() - self.run_started))
        return figures

    def close(self) -> None:
        """Finish the bag (normal exit, SIGINT, SIGTERM), with this run's timing figures."""
        s = self.stats.summary()
        if s["count"]:
            self.get_logger().info(
                f"{s['count']} ticks: compute p50 {s['p50'] * 1e3:.3f} ms, p99 {s['p99'] * 1e3:.3f} ms, "
                f"p99.9 {s['p99.9'] * 1e3:.3f} ms, max {s['max'] * 1e3:.3f} ms; "
                f"{s['deadline_misses']} deadline misses (tick period {self.period * 1e3:.2f} ms); "
                f"thread CPU p99.9 {self.cpu_stats.percentile(99.9) * 1e3:.3f} ms")
        if self.recorder is not None:
            self.recorder.close(self.run_figures())


MARKERS_TYPE = "visualization_msgs/msg/MarkerArray"
DIAGNOSTICS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"


def check_config(cfg: dict) -> None:
    for p in PARAMS:
        v = cfg[p.name]
        if p.choices and v not in p.choices:
            raise ConfigError(f"parameter {p.name}: {v!r} must be one of {', '.join(map(repr, p.choices))}")
        if p.low is not None and not p.low <= v <= p.high:
            raise ConfigError(f"parameter {p.name}: {v} must be in [{p.low:g}, {p.high:g}]")
    if cfg["integrator_step"] and cfg["integrator_step"] > 1.0 / cfg["publish_rate"]:
        raise ConfigError(f"parameter integrator_step: {cfg['integrator_step']} must not exceed the tick "
                          f"1 / publish_rate = {1.0 / cfg['publish_rate']:g} s")


def main(argv: list[str] | None = None) -> int:
    """Entry of ``sim_node`` (ros2 run) and ``mta node``: ROS arguments as for any node.

    SIGINT and SIGTERM end the spin loop between callbacks, then the bag is finished and the
    context shut down in that order (rclpy's own handlers would invalidate the context while a
    callback may still be writing)."""
    rclpy.init(args=sys.argv if argv is None else argv, signal_handler_options=SignalHandlerOptions.NO)
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.append(signum))
    try:
        node = SimNode()
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
    if node.cfg["tick_cpu"] >= 0:  # after every thread of the node exists
        try:
            node.get_logger().info(reserve_cpu(node.cfg["tick_cpu"]))
        except (ValueError, OSError) as err:
            print(f"sim_node: {err}", file=sys.stderr)
            node.close()
            node.destroy_node()
            rclpy.try_shutdown()
            return 2
    try:
        while not stop and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    finally:
        node.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
