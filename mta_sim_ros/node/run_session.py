"""A node run without ROS: the simulation, its commands, watchdog, pacing, pause and reset, live
parameters, diagnostics and bag, driven by whoever calls it (the ROS node, or a test).

:class:`RunSession` holds every decision the node makes; node.py only turns ROS callbacks into
calls of it. It never imports rclpy: time comes from an injected steady wall ``clock`` (a test
sets the time instead of sleeping), messages leave as CDR bytes through an injected ``publish``,
log lines through an injected ``log`` and the bytes are made by injected :class:`Encoders`.

Each firing of the node's tick timer (:meth:`RunSession.fire`) runs the ticks due by the wall
clock (pacing.py), or in lockstep (below) the one tick a controller's answer allows. Each tick (:meth:`RunSession.tick`) advances the model by one tick of simulated time holding the
latest commands (zero-order hold), publishes the outputs stamped with simulation time and
records the same bytes. Published time = clock_offset + the run's simulation time: a reset starts
the model again while /clock goes on.

Commands (:meth:`RunSession.command` for the Float64 topics, :meth:`RunSession.command_message`
for cmd_vel and ackermann_cmd, as CDR bytes) are recorded as received, then go through one rule
(commands.py): the latest accepted message of any source sets what it sets.

Lockstep (parameter ``lockstep``, fixed at start), for a controller that answers each output with
a command, as Gazebo's lockstep or CARLA's synchronous mode:

1. the first firing runs tick 1 (with the commands held then: the scene's initial ones unless a
   command came before) and publishes its outputs;
2. then the session waits: no tick runs until a command arrives on any command topic
   (steering_angle, speed_setpoint, cmd_vel, ackermann_cmd; refused or not: it is an answer);
3. the next firing after an answer runs exactly one tick, holding the latest commands (two
   answers before that firing still make one tick; the node fires at each answer, so one
   message answers one tick);
4. while waiting, every REPUBLISH_EVERY wall seconds the outputs of the last tick are published
   again (not recorded: the bag has them), for a controller that subscribed late or lost them;
5. after ``lockstep_timeout`` wall seconds without an answer it logs once which topics it waits
   on and at which simulation time, and /diagnostics says WARN until the answer comes; it keeps
   waiting (a stalled controller stops the simulation, never steers it by default);
6. pause holds it as in free running; a reset starts the new run at step 1.

The wall clock paces nothing in lockstep (real_time_factor is not used) and the command watchdog
is off: a missing answer stops time instead of being taken for a stale command, so a run is a
function of the commands alone and two runs of a deterministic controller record the same
messages at the same log times.
"""
from __future__ import annotations

import math
import time
import warnings
from pathlib import Path
from typing import Callable, Mapping, Protocol, Sequence

from .. import messages
from ..bag import MessageDefinitionNotFound, message_definition
from ..config import resolve_config_path
from ..integrate import IntegrationError
from ..messages.decode import CommandDecodeError, decode_ackermann, decode_twist
from ..messages.topics import (
    BAG_TOPICS,
    COMMAND_TOPICS,
    LATCHED_QOS_YAML,
    LATCHED_TOPICS,
    MESSAGE_COMMANDS,
    WATCHDOG_TOPIC,
    qualified,
)
from ..messages.urdf import frame_prefix, robot_model
from ..physics.guards import ModelValidityError
from ..physics.loader import SpecError, load_scene
from ..run.simulation import Simulation
from ..validate import InputError, show
from .commands import CommandInput, MessageInput, Setting, ackermann_setting, command_ranges, twist_setting
from .pacing import Pacing
from .params import BY_NAME, ConfigError, check_config, check_value
from .recorder import RunRecorder
from .runlog import run_metadata, tick_figures, tick_line
from .status import Status, status
from .timing import TickStats
from .watchdog import SteeringWatchdog

#: Seconds between two log lines about bad commands on one topic (/diagnostics says every one).
WARN_EVERY = 1.0
#: Lockstep: wall seconds between two re-publications of outputs nobody has answered yet.
REPUBLISH_EVERY = 1.0
#: Lockstep: the tick timer's period, s (the first tick, re-publication, the stall warning; the
#: ticks themselves run when an answer arrives).
LOCKSTEP_TIMER_PERIOD = 0.05


def message_commands() -> dict[str, str]:
    """The message command topics (topics.MESSAGE_COMMANDS) whose definition is installed: the
    bag needs it, and a node cannot subscribe a type it does not have (ackermann_msgs)."""
    found = {}
    for topic, type_name in MESSAGE_COMMANDS.items():
        try:
            message_definition(type_name)
        except MessageDefinitionNotFound:
            continue
        found[topic] = type_name
    return found


class OutputsEncoder(Protocol):
    def encode(self, out) -> dict[str, bytes]:
        """topic -> CDR bytes of the published outputs (topics.TOPICS but the commands) of one
        sim.Outputs; the dict is handed to the bag writer as it is: a new one each call."""


class MarkersEncoder(Protocol):
    def encode(self, out) -> bytes:
        """CDR bytes of the visualization_msgs/MarkerArray of the train at out.t."""


class Encoders(Protocol):
    """The seam between the session and a CDR encoding (by default ``messages.Encoders``, the one
    encoder the offline run uses too). Frame-dependent encoders are made at start and again when
    frame_id changes, never per tick."""

    def outputs(self, cart_names: Sequence[str], frame_id: str) -> OutputsEncoder: ...

    def markers(self, train, frame_id: str) -> MarkersEncoder: ...

    def frames(self, robot, actuator, frame_id: str, cart_frames: bool) -> FramesEncoder:
        """The frames of ``robot`` (urdf.Robot); ``cart_frames``: its joints' frames too."""

    def diagnostics(self, t: float, name: str, level: int, message: str,
                    values: Mapping[str, object]) -> bytes:
        """A diagnostic_msgs/DiagnosticArray stamped t with one status (diagnostics.Status)."""

    def float64(self, x: float) -> bytes:
        """A std_msgs/Float64 (commands and watchdog take-overs, as recorded)."""


class FramesEncoder(Protocol):
    def encode(self, out) -> dict[str, bytes]:
        """topic -> CDR bytes of the per-tick frames (/tf, joint_states, odom) of one sim.Outputs."""

    def latched(self, t: float) -> dict[str, bytes]:
        """topic -> CDR bytes of the latched topics (/tf_static stamped t, robot_description)."""


class TickProfile(Protocol):
    """Where a tick's time goes (``python -m benchmarks realtime --stages``): ``start`` when a tick begins,
    ``mark(stage)`` as each stage ends (advance, outputs, encode, markers, publish, bag_write),
    ``done`` when it ends."""

    def start(self) -> None: ...

    def mark(self, stage: str) -> None: ...

    def done(self) -> None: ...


class RunSession:
    """One node's runs, one after the other (a reset starts the next), each in its own bag.

    ``cfg``: every parameter of params.PARAMS (ConfigError when one is wrong, the scene cannot
    be read or the fidelity level cannot run it); ``clock``: steady wall seconds; ``publish``:
    takes a dict topic -> CDR bytes (the node's relative names); ``log``: has info, warning and
    error (str); ``encoders``: the CDR encoding (messages.Encoders by default); ``name`` and
    ``namespace``: the node's, for /diagnostics and the bag's topic
    names; ``background``: the bag is written on a thread of its own (recorder.py);
    ``compute_clock`` and ``cpu_clock`` time each tick's work (wall and this thread's CPU);
    ``profile`` (a TickProfile) is told where each tick's stages end."""

    def __init__(self, cfg: Mapping[str, object], *, clock: Callable[[], float], publish: Callable[[dict], None],
                 log, encoders: Encoders | None = None, name: str = "mta_sim", namespace: str = "/",
                 background: bool = True, compute_clock: Callable[[], float] = time.perf_counter,
                 cpu_clock: Callable[[], float] = time.thread_time, profile: TickProfile | None = None):
        self.cfg = dict(cfg)
        check_config(self.cfg)
        self.clock, self.publish, self.log, self.name = clock, publish, log, name
        self.enc = encoders if encoders is not None else messages.Encoders()
        self.compute_clock, self.cpu_clock, self.profile = compute_clock, cpu_clock, profile
        try:
            self.scene = load_scene(resolve_config_path(self.cfg["scene_file"]))
        except SpecError as err:
            raise ConfigError(f"parameter scene_file: {err}") from None
        try:
            self.sim = self._simulation()
        except InputError as err:  # a tick that would not end (validate.MAX_STEPS_PER_TICK)
            raise ConfigError(f"parameter integrator_step: {err}") from None
        except ValueError as err:  # a level this train cannot run (kinematic without a commanded speed)
            raise ConfigError(f"parameter fidelity: {err}") from None
        self.cart_names = [c.name for c in self.scene.train.carts]
        try:  # the robot model: frames and joints named after the carts, prefixed by the namespace
            self.robot = robot_model(self.scene.train, frame_prefix(namespace))
        except InputError as err:
            raise ConfigError(f"parameter scene_file: {err}") from None
        rule = self.robot.frame_id_rule(self.cfg["frame_id"])
        if rule:
            raise ConfigError(f"parameter frame_id: {show(self.cfg['frame_id'])} must be {rule}")
        self.latched: dict[str, bytes] = {}  # what the latched topics last published (urdf, /tf_static)
        ranges = command_ranges(self.scene)
        self.steering = CommandInput(self.scene.initial.steering, *ranges["steering_angle"], "steering_angle", clock)
        self.speed = CommandInput(self.sim.v_set, *ranges["speed_setpoint"], "speed_setpoint", clock)
        self.inputs = {"steering_angle": self.steering, "speed_setpoint": self.speed}
        self.message_types = message_commands()  # cmd_vel, and ackermann_cmd where installed
        self.message_inputs = {t: MessageInput(t) for t in self.message_types}
        self.wheelbase = self.scene.train.carts[0].length
        self.rate_limit: float | None = None  # the steering's rate limit (ackermann_cmd); None = the actuator's
        self.warned_at = dict.fromkeys((*COMMAND_TOPICS, *self.message_types), -WARN_EVERY)
        self.lockstep = bool(self.cfg["lockstep"])
        self.command_topics = [qualified(t, namespace) for t in (*COMMAND_TOPICS, *self.message_types)]
        self.answered = True  # lockstep: the next firing may tick (the first one does)
        self.published_at = self.republished_at = clock()
        self.last_outputs: dict[str, bytes] = {}
        self.stall_said = False
        self.lockstep_stalls = 0  # waits that lasted past lockstep_timeout
        self.republications = 0
        self.watchdog = SteeringWatchdog(self.steering, self._watchdog_timeout(), self.cfg["watchdog_action"])
        self.clock_offset = 0.0  # published time = offset + run time; keeps /clock monotonic over resets
        self.paused = False
        self.halted = ""  # why the model stopped (jackknife...): it stays stopped until a reset
        self._new_run()
        self.ticks_since_markers = 0
        self.marker_every = max(1, round(self.cfg["publish_rate"] / self.cfg["marker_rate"]))
        self._make_encoders()

        self.recorder = None
        self.logged_bag_error = ""
        self.ticks_waiting_for_bag = 0  # timer firings held while the bag writer was behind
        self.ticks_caught_up = 0  # ticks run by a firing after its first, to make up a lag (pacing.py)
        if self.cfg["record"]:
            bag_topics = {t: ty for t, ty in BAG_TOPICS.items() if t not in MESSAGE_COMMANDS or t in self.message_types}
            in_bag = {t: qualified(t, namespace) for t in bag_topics}  # e.g. hitch_poses -> /unit1/hitch_poses
            self.recorder = RunRecorder(self.cfg["bag_dir"], {in_bag[t]: ty for t, ty in bag_topics.items()},
                                        self.run_metadata(), background=background, rename=in_bag,
                                        qos={in_bag[t]: LATCHED_QOS_YAML for t in LATCHED_TOPICS})
            self._start_bag()
        self._publish_latched(LATCHED_TOPICS)
        # from now: the timer's start; in lockstep nothing is paced (target 0: no lag, the factor measured)
        self.pacing = Pacing(self.sim.tick, self._target(), clock)
        pace = "lockstep (one tick per answer)" if self.lockstep else f"real-time factor {self.cfg['real_time_factor']:g}"
        self.log.info(
            f"scene '{self.scene.name}', {len(self.cart_names)} carts, {self.sim.method} step {self.sim.step:g} s, "
            f"tick {self.sim.tick:g} s, {pace}; "
            f"fidelity {self.sim.choice.reason}; {self.sim.compiled_note}")

    def _target(self) -> float:
        """The real-time factor pacing keeps: the parameter's, or 0 (nothing paced) in lockstep."""
        return 0.0 if self.lockstep else self.cfg["real_time_factor"]

    def _watchdog_timeout(self) -> float:
        """The watchdog's timeout: the parameter's, or 0 (never stale) in lockstep."""
        return 0.0 if self.lockstep else self.cfg["watchdog_timeout"]

    def _simulation(self) -> Simulation:
        """A Simulation of the scene with the integrator and fidelity parameters."""
        self.sim_fidelity = self.cfg["fidelity"] or None  # what the running level was built from
        with warnings.catch_warnings():  # said once, through the log, below
            warnings.simplefilter("ignore", RuntimeWarning)
            sim = Simulation(self.scene, method=self.cfg["integrator_method"] or None,
                             step=self.cfg["integrator_step"] or None, rate=self.cfg["publish_rate"],
                             fidelity=self.cfg["fidelity"] or None)
        if sim.stability_note:  # the configured step is past the method's stability limit
            self.log.warning(sim.stability_note)
        return sim

    def _make_encoders(self) -> None:
        """The tick's encoders for the current frame_id (at start and when it changes)."""
        self.encoder = self.enc.outputs(self.cart_names, self.cfg["frame_id"])
        self.markers = self.enc.markers(self.scene.train, self.cfg["frame_id"])
        self.frames = self.enc.frames(self.robot, self.scene.train.actuator, self.cfg["frame_id"],
                                      self.cfg["publish_cart_frames"])

    def _publish_latched(self, topics: Sequence[str]) -> None:
        """Publish and record these latched topics (topics.LATCHED_TOPICS) as they are now: at
        start, and /tf_static again when frame_id changes (the URDF never changes: a reset keeps
        the train). Each new bag records them too, from its start (_start_bag)."""
        msgs = {t: b for t, b in self.frames.latched(self.now).items() if t in topics}
        self.latched.update(msgs)
        self.publish(msgs)
        self._record(msgs)

    def _new_run(self) -> None:
        """Fresh tick statistics and wall time for a run (start, reset)."""
        self.stats = TickStats()  # wall time of each tick's work
        # the tick thread's CPU time over the same work: wall >> CPU means the thread was preempted
        # (other processes on the core), not that the tick's code was slow
        self.cpu_stats = TickStats()
        self.run_started = self.clock()

    @property
    def now(self) -> float:
        """Published simulation time, s."""
        return self.clock_offset + self.sim.t

    @property
    def period(self) -> float:
        """Seconds between two ticks on the wall clock (0 = as fast as possible)."""
        return self.pacing.period

    @property
    def timer_period(self) -> float:
        """Seconds between two firings of the tick timer (pacing.py: the period, at most
        pacing.MAX_TIMER_PERIOD; LOCKSTEP_TIMER_PERIOD in lockstep)."""
        return LOCKSTEP_TIMER_PERIOD if self.lockstep else self.pacing.timer_period

    # -- the tick --------------------------------------------------------------------------
    def fire(self) -> int:
        """One firing of the tick timer: the ticks due now (pacing.Pacing.due: one when on time,
        more to make up a late firing, none while paused; in lockstep: :meth:`_fire_lockstep`);
        returns how many ran."""
        if self.lockstep:
            return self._fire_lockstep()
        ran = 0
        for _ in range(0 if self.halted else self.pacing.due(self.now)):
            if not self.tick():
                break
            ran += 1
        self.ticks_caught_up += max(0, ran - 1)
        return ran

    def _fire_lockstep(self) -> int:
        """A firing in lockstep (module docstring): one tick if the last outputs were answered,
        else re-publish them every REPUBLISH_EVERY s and say a stall past lockstep_timeout."""
        if self.halted or self.paused:
            return 0
        if self.answered:
            return int(self.tick())
        now = self.clock()
        if self.last_outputs and now - self.republished_at >= REPUBLISH_EVERY:
            self.republished_at = now
            self.republications += 1
            self.publish(self.last_outputs)
        if not self.stall_said and self.lockstep_waiting() > self.cfg["lockstep_timeout"]:
            self.stall_said = True
            self.lockstep_stalls += 1
            self.log.warning(self._stall())
        return 0

    def lockstep_waiting(self) -> float:
        """Lockstep: wall seconds the last outputs have waited for an answer (0 when answered)."""
        return 0.0 if not self.lockstep or self.answered else self.clock() - self.published_at

    def _stall(self) -> str:
        return (f"lockstep: waiting {self.lockstep_waiting():.1f} s (wall) for a command on any of "
                f"{', '.join(self.command_topics)}, answering the outputs at t = {self.now:.3f} s; "
                f"still waiting")

    def tick(self) -> bool:
        """Advance, publish and record one tick; returns whether it did. Nothing while paused or
        halted, or while the bag writer is behind (recorder.RunRecorder.behind: counted in
        /diagnostics). A model error halts the run (logged, ERROR in /diagnostics)."""
        if self.paused or self.halted:
            return False
        if self.recorder is not None and self.recorder.behind:  # bounds what a SIGKILL loses (recorder.py)
            self.ticks_waiting_for_bag += 1
            self.recorder.make_way()
            return False
        profile = self.profile
        if profile is not None:
            profile.start()
        started, cpu_started = self.compute_clock(), self.cpu_clock()
        if self.watchdog.update():
            self._record({WATCHDOG_TOPIC: self.enc.float64(self.watchdog.command)})
        self.sim.set_rate_limit(self.rate_limit)
        try:
            self.sim.advance(self.watchdog.command, self.speed.value)
        except (ModelValidityError, IntegrationError) as err:
            self.halted = str(err)
            self.log.error(f"simulation halted (call reset to start again): {err}")
            self.publish_diagnostics()
            return False
        if profile is not None:
            profile.mark("advance")
        out = self.sim.outputs()
        out.t = self.now
        if profile is not None:
            profile.mark("outputs")
        msgs = self.encoder.encode(out)  # CDR bytes: the same bytes go to DDS and to the bag
        msgs.update(self.frames.encode(out))  # /tf, joint_states, odom
        if profile is not None:
            profile.mark("encode")
        self.ticks_since_markers += 1
        if self.ticks_since_markers >= self.marker_every:
            self.ticks_since_markers = 0
            msgs["markers"] = self.markers.encode(out)
        if profile is not None:
            profile.mark("markers")
        self.publish(msgs)
        if self.lockstep:  # from now the tick waits for an answer to these outputs
            if self.stall_said:
                self.log.info(f"lockstep: answered; running again at t = {self.now:.3f} s")
            self.answered, self.stall_said, self.last_outputs = False, False, msgs
            self.published_at = self.republished_at = self.clock()
        if profile is not None:
            profile.mark("publish")
        if self.recorder is not None and self.recorder.recording:  # the same bytes, to the bag writer's thread
            self.recorder.write_batch(msgs, round(self.now * 1e9))
        if profile is not None:
            profile.mark("bag_write")
        cpu = self.cpu_clock() - cpu_started
        period = self.pacing.period
        self.stats.record(self.compute_clock() - started, deadline=period if period > 0 else None)
        self.cpu_stats.record(cpu)
        if profile is not None:
            profile.done()
        return True

    def _record(self, msgs: dict[str, bytes]) -> None:
        """Log messages (topic -> CDR bytes) at the current simulation time. A failure of the
        writing thread shows later, in ``recorder.error`` (publish_diagnostics logs it once)."""
        if self.recorder is not None and self.recorder.recording:
            self.recorder.write_batch(msgs, round(self.now * 1e9))

    # -- commands, pause, reset, parameters ------------------------------------------------
    def command(self, topic: str, x: float) -> None:
        """A command received on ``topic`` (topics.COMMAND_TOPICS): recorded as received at the
        simulation time it arrived, then held if valid, clamped to its range, or refused."""
        inp = self.inputs[topic]
        self._record({topic: self.enc.float64(x)})
        self.answered = True
        held = inp.take(x)
        if held is not None and topic == "steering_angle":
            self.rate_limit = None  # the rate limit goes with the steering command: the actuator's own
        if held != x:  # refused or clamped
            self._warn(topic, inp.last_problem)

    def command_message(self, topic: str, data: bytes) -> None:
        """A command message received on ``topic`` (cmd_vel, ackermann_cmd: self.message_types)
        as its CDR bytes: recorded as received at the simulation time it arrived, then what it
        sets (commands.twist_setting, ackermann_setting) is held, clamped, or it is refused."""
        self._record({topic: bytes(data)})
        self.answered = True
        try:
            if topic == "cmd_vel":
                setting = twist_setting(*decode_twist(data), self.wheelbase, self.steering.high)
            else:
                setting = ackermann_setting(*decode_ackermann(data), self.steering.high,
                                            self.scene.train.actuator.max_rate)
        except CommandDecodeError as err:
            setting = Setting(problem=f"{topic}: {err}; refused", refused=True)
        self.message_inputs[topic].take(setting)
        if setting.steering is not None:
            self.steering.set(setting.steering)
            self.rate_limit = setting.rate
        elif not setting.refused:  # cmd_vel at v = 0 holds the steering as it is: a fresh command for the watchdog
            self.steering.set(self.steering.value)
        if setting.speed is not None:
            self.speed.set(setting.speed)
        if setting.problem:
            self._warn(topic, setting.problem)

    def _warn(self, topic: str, problem: str) -> None:
        """A bad command said in the log, at most once every WARN_EVERY s a topic."""
        if self.clock() - self.warned_at[topic] >= WARN_EVERY:
            self.warned_at[topic] = self.clock()
            self.log.warning(problem)

    def pause(self, paused: bool) -> str:
        """Pause (no ticks, simulated time stands) or run on; returns what it is now."""
        self.paused = bool(paused)
        self.pacing.pause(self.paused, self.now)
        return "paused" if self.paused else "running"

    def reset(self) -> str:
        """Close this run's bag with its figures, back to the scene's start (with the fidelity
        level asked for since, if any) at the published time reached, open a new bag; returns
        what it did."""
        if self.recorder is not None:
            self.recorder.close(self.run_figures())
        self._new_run()
        self.watchdog.forget()  # so that the new bag records it again if it still holds
        self.clock_offset = self.now
        if (self.cfg["fidelity"] or None) != self.sim_fidelity:  # the level changes only here
            self.sim = self._simulation()
            if self.recorder is not None:
                self.recorder.metadata.update(self.run_metadata())
            self.log.info(f"fidelity {self.sim.choice.reason}")
        self.sim.reset()
        self.steering.value = self.scene.initial.steering
        self.speed.value = self.sim.v_set
        self.steering.last_problem = self.speed.last_problem = ""  # a new run: its own commands
        for inp in self.message_inputs.values():
            inp.last_problem = ""
        self.rate_limit = None
        self.answered, self.stall_said, self.last_outputs = True, False, {}  # lockstep: step 1 again
        self.halted = ""
        self.pacing.restart(self.now)
        path = self._start_bag()
        message = f"reset to the start of '{self.scene.name}' at t = {self.now:.3f} s"
        if path:
            message += f"; recording {path}"
        elif self.recorder is not None:
            message += f"; not recording: {self.recorder.error}"
        self.log.info(message)
        return message

    def set_parameters(self, changes: Mapping[str, object]) -> str:
        """Apply parameter changes (name -> value; names not in params.PARAMS are ignored) all
        or none; returns why they are refused ('' when applied)."""
        for name, value in changes.items():
            spec = BY_NAME.get(name)
            if spec is None:
                continue
            if not spec.live and value != self.cfg[name]:
                return (f"{name} cannot change while running: it is fixed at start (restart the node with "
                        f"the new value)")
            problem = check_value(spec, value)
            if not problem and name == "frame_id" and self.robot.frame_id_rule(value):
                problem = f"{show(value)} must be {self.robot.frame_id_rule(value)}"
            if problem:
                return f"{name}: {problem}"
            if name == "fidelity":
                try:
                    Simulation(self.scene, rate=self.cfg["publish_rate"], fidelity=value or None)
                except ValueError as err:
                    return f"fidelity: {err}"
        for name, value in changes.items():
            if name in BY_NAME:
                self.cfg[name] = value
        if "real_time_factor" in changes and not self.lockstep:
            self.pacing.set_target(self.cfg["real_time_factor"], self.now)
        self.watchdog.timeout, self.watchdog.action = self._watchdog_timeout(), self.cfg["watchdog_action"]
        if "frame_id" in changes:
            self._make_encoders()  # the frame is part of the templates
            self._publish_latched(("/tf_static",))  # frame_id -> odom
        if "fidelity" in changes:
            self.log.info(f"fidelity {self.cfg['fidelity'] or 'of the scene'}: applies at the next reset")
        return ""

    # -- run log and diagnostics -----------------------------------------------------------
    def run_metadata(self) -> dict[str, str]:
        """The bag's metadata record mta_sim_ros (runlog.run_metadata; clock_offset is added when
        each bag starts)."""
        return run_metadata(self.scene, self.sim, self.cfg)

    def run_figures(self) -> dict[str, str]:
        """The bag's closing record mta_sim_ros.run: tick statistics, the bag writer thread's CPU
        (off the tick, not in tick_*), published and run time, the run's wall time."""
        figures = tick_figures(self.stats, self.cpu_stats)
        if self.recorder is not None:
            figures["recorder_thread_cpu"] = repr(self.recorder.thread_cpu)
        figures.update(sim_time=repr(self.now), tick_period=repr(self.period),
                       run_sim_time=repr(self.sim.t), run_wall_time=repr(self.clock() - self.run_started))
        return figures

    def _start_bag(self) -> Path | None:
        if self.recorder is None:
            return None
        self.recorder.metadata["clock_offset"] = repr(self.clock_offset)
        path = self.recorder.start()
        if path is None:
            self.logged_bag_error = self.recorder.error
            self.log.error(self.recorder.error)
        else:
            self.log.info(f"recording {path}")
            self._record(dict(self.latched))  # what a subscriber holds of the latched topics, from the bag's start
        return path

    def diagnostics(self) -> Status:
        """What /diagnostics says now (it also samples the real-time factor: pacing.py)."""
        rtf, lag = self.pacing.measure(self.now)
        stats, steering, recorder = self.stats, self.steering, self.recorder
        values = {
            "sim_time_s": self.now,
            "real_time_factor": rtf,
            "real_time_factor_target": self.cfg["real_time_factor"],
            "lag_s": lag,
            "tick_compute_p50_ms": stats.window_percentile(50) * 1e3,
            "tick_compute_p99_ms": stats.window_percentile(99) * 1e3,
            "tick_compute_max_ms": stats.window_max * 1e3,
            "tick_cpu_p99_ms": self.cpu_stats.window_percentile(99) * 1e3,
            "deadline_misses": stats.deadline_misses,
            "ticks_waiting_for_bag": self.ticks_waiting_for_bag,
            "ticks_caught_up": self.ticks_caught_up,
            "tick_period_ms": self.period * 1e3,
            "steering_command_age_s": steering.age(),
            "steering_commands": steering.count,
            "steering_rejected": steering.rejected,
            "steering_clamped": steering.clamped,
            "jackknife_margin_deg": math.degrees(self.sim.outputs().jackknife_margin),
            "fidelity": self.sim.level,
            "fidelity_reason": self.sim.choice.reason,
            "fidelity_at_next_reset": self.cfg["fidelity"] or "the scene's",
            "paused": self.paused,
            "bag": str(recorder.path) if recorder and recorder.recording else "",
            "lockstep": self.lockstep,
        }
        for topic, inp in self.message_inputs.items():
            values.update({f"{topic}_commands": inp.count, f"{topic}_rejected": inp.rejected,
                           f"{topic}_clamped": inp.clamped})
        problems = [recorder.error if recorder else "", steering.last_problem, self.speed.last_problem,
                    *(inp.last_problem for inp in self.message_inputs.values())]
        if self.lockstep:
            waiting = self.lockstep_waiting()
            values.update(lockstep_waiting_s=waiting, lockstep_stalls=self.lockstep_stalls,
                          lockstep_republished=self.republications)
            if waiting > self.cfg["lockstep_timeout"]:
                problems.append(self._stall())
        if self.watchdog.stale():
            problems.append(f"steering command stale ({steering.age():.1f} s): {self.cfg['watchdog_action']}")
        return status(self.halted, problems, values)

    def publish_diagnostics(self) -> None:
        """Publish and record the diagnostics (the 1 Hz timer, and at a halt); a bag error is
        said once in the log, every time in /diagnostics."""
        if self.recorder is not None and self.recorder.error not in ("", self.logged_bag_error):
            self.logged_bag_error = self.recorder.error
            self.log.error(self.recorder.error)
        s = self.diagnostics()
        data = self.enc.diagnostics(self.now, f"{self.name}: simulation", s.level, s.message, s.values)
        self.publish({"/diagnostics": data})
        self._record({"/diagnostics": data})

    def close(self) -> None:
        """Finish the run (normal exit, SIGINT, SIGTERM): its tick line in the log, its bag with
        its figures."""
        line = tick_line(self.stats, self.cpu_stats, self.period)
        if line:
            self.log.info(line)
        if self.recorder is not None:
            self.recorder.close(self.run_figures())
