"""A node run without ROS: the simulation, its commands, watchdog, pacing, pause and reset, live
parameters, diagnostics and bag, driven by whoever calls it (the ROS node, or a test).

:class:`RunSession` holds every decision the node makes; sim_node.py only turns ROS callbacks into
calls of it. It never imports rclpy: time comes from an injected steady wall ``clock`` (a test
sets the time instead of sleeping), messages leave as CDR bytes through an injected ``publish``,
log lines through an injected ``log`` and the bytes are made by injected encoders
(tick_messages.Encoders).

Its parts, each in a module of its own:

* the model: ``scene``, ``sim`` (run.simulation.Simulation), ``robot`` (the URDF model);
* ``inputs`` (commands.HeldCommands): what the run holds of its commands, by one rule, and
  ``watchdog`` (watchdog.SteeringWatchdog): who decides the steering;
* ``pace`` (pacing.Pace): free running against the wall clock, or lockstep with a controller;
* ``messages`` (tick_messages.TickMessages): the CDR bytes published and recorded;
* ``recorder`` (recorder.RunRecorder): the run's bag;
* ``timing`` (timing.TickTiming): each tick's compute time; ``profile`` (timing.TickProfile): an
  observer told where each tick's stages end (timing.NoProfile unless one is given).

Each firing of the node's tick timer (:meth:`RunSession.fire`) runs the ticks the pacing allows:
those due by the wall clock, or in lockstep the one tick a controller's answer allows (pacing.py).
Each tick (:meth:`RunSession.tick`) advances the model by one tick of simulated time holding the
latest commands (zero-order hold), publishes the outputs stamped with simulation time and
records the same bytes. Published time = clock_offset + the run's simulation time: a reset starts
the model again while /clock goes on.

Commands (:meth:`RunSession.command` for the Float64 topics, :meth:`RunSession.command_message`
for cmd_vel and ackermann_cmd, as CDR bytes) are recorded as received, then go through one rule
(commands.py): the latest accepted message of any source sets what it sets. Each one is an answer
to the pacing (lockstep ticks on answers).
"""
from __future__ import annotations

import json
import math
import os
import time
import warnings
from pathlib import Path
from typing import Callable, Mapping, Sequence

from ..bag import MessageDefinitionNotFound, message_definition
from ..bag.cdr import encode
from ..config import resolve_config_path
from ..integrate import IntegrationError
from ..messages import Encoders as MessageEncoders
from ..messages.topics import (
    BAG_TOPICS,
    COMMAND_TOPICS,
    LATCHED_QOS_YAML,
    LATCHED_TOPICS,
    MESSAGE_COMMANDS,
    RUN_METADATA_TOPIC,
    RUN_METADATA_TYPE,
    STAMPED_CMD_VEL_TYPE,
    WATCHDOG_TOPIC,
    qualified,
)
from ..messages.urdf import frame_prefix, robot_model
from ..physics.guards import ModelValidityError
from ..physics.loader import SpecError, load_scene
from ..run.companion import Companion, budget_steps, tick_seconds
from ..run.following import GovernorWatch
from ..run.margins import MarginGauge
from ..run.simulation import Simulation
from ..validate import InputError, show
from .commands import HeldCommands
from .pacing import FreeRunning, Lockstep, Pace
from .params import BY_NAME, ConfigError, answer_topics, check_config, check_value
from .recorder import RunRecorder
from .runlog import run_metadata, tick_figures, tick_line
from .status import Status, status
from .tick_messages import Encoders, TickMessages
from .timing import NoProfile, TickProfile, TickTiming
from .watchdog import SteeringWatchdog

#: the run record's fields that name a file or folder (published by their last component only)
PATH_FIELDS = ("scene_file", "train_file", "param.scene_file", "param.bag_dir")

#: The most ticks one StepSimulation call runs (the node answers nothing else meanwhile: 100 000
#: ticks of ~0.4 ms, ~40 s of wall time for 500 s of simulated time at the default 5 ms tick).
MAX_STEPS = 100_000

#: Seconds between two log lines about bad commands on one topic (/diagnostics says every one).
WARN_EVERY = 1.0


def message_commands(cmd_vel_stamped: bool = False) -> dict[str, str]:
    """The message command topics (topics.MESSAGE_COMMANDS, cmd_vel as TwistStamped with
    ``cmd_vel_stamped``) whose definition is installed: the bag needs it, and a node cannot
    subscribe a type it does not have (ackermann_msgs)."""
    found = {}
    wanted = {**MESSAGE_COMMANDS, **({"cmd_vel": STAMPED_CMD_VEL_TYPE} if cmd_vel_stamped else {})}
    for topic, type_name in wanted.items():
        try:
            message_definition(type_name)
        except MessageDefinitionNotFound:
            continue
        found[topic] = type_name
    return found


class RunSession:
    """One node's runs, one after the other (a reset starts the next), each in its own bag.

    ``cfg``: every parameter of params.PARAMS (ConfigError when one is wrong, the scene cannot
    be read or the fidelity level cannot run it); ``clock``: steady wall seconds; ``publish``:
    takes a dict topic -> CDR bytes (the node's relative names); ``log``: has info, warning and
    error (str); ``encoders``: the CDR encoding (messages.Encoders by default); ``name`` and
    ``namespace``: the node's, for /diagnostics and the bag's topic names; ``background``: the
    bag is written on a thread of its own (recorder.py); ``compute_clock`` and ``cpu_clock`` time
    each tick's work (wall and this thread's CPU); ``profile`` (a TickProfile) is told where each
    tick's stages end."""

    def __init__(self, cfg: Mapping[str, object], *, clock: Callable[[], float], publish: Callable[[dict], None],
                 log, encoders: Encoders | None = None, name: str = "mta_sim", namespace: str = "/",
                 background: bool = True, compute_clock: Callable[[], float] = time.perf_counter,
                 cpu_clock: Callable[[], float] = time.thread_time, profile: TickProfile | None = None):
        self.cfg = dict(cfg)
        check_config(self.cfg)
        self.clock, self.publish, self.log, self.name = clock, publish, log, name
        self.compute_clock = compute_clock
        self.profile = profile if profile is not None else NoProfile()
        # the model
        try:
            self.scene = load_scene(resolve_config_path(self.cfg["scene_file"]))
        except SpecError as err:
            raise ConfigError(f"parameter scene_file: {err}") from None
        self.gauge = MarginGauge(self.scene.train)  # the train's margins (diagnostics)
        try:
            self.sim = self._simulation()
        except InputError as err:  # a tick that would not end (validate.MAX_STEPS_PER_TICK)
            raise ConfigError(f"parameter integrator_step: {err}") from None
        except ValueError as err:  # a level this train cannot run (kinematic without a commanded speed)
            raise ConfigError(f"parameter fidelity: {err}") from None
        try:  # the robot model: frames and joints named after the carts, prefixed by the namespace
            self.robot = robot_model(self.scene.train, frame_prefix(namespace))
        except InputError as err:
            raise ConfigError(f"parameter scene_file: {err}") from None
        rule = self.robot.frame_id_rule(self.cfg["frame_id"])
        if rule:
            raise ConfigError(f"parameter frame_id: {show(self.cfg['frame_id'])} must be {rule}")
        # the commands, and who decides the steering
        self.inputs = HeldCommands(self.scene, self.sim.v_set, message_commands(self.cfg["cmd_vel_stamped"]), clock)
        self.warned_at = dict.fromkeys((*COMMAND_TOPICS, *self.inputs.message_types), -WARN_EVERY)
        self.watchdog = SteeringWatchdog(self.steering, self._watchdog_timeout(), self.cfg["watchdog_action"])
        # the run
        self.clock_offset = 0.0  # published time = offset + run time; keeps /clock monotonic over resets
        self.halted = ""  # why the model stopped (jackknife...): it stays stopped until a reset
        self.timing = TickTiming(clock, compute_clock, cpu_clock)
        self.messages = TickMessages(encoders if encoders is not None else MessageEncoders(), self.scene,
                                     self.robot, max(1, round(self.cfg["publish_rate"] / self.cfg["marker_rate"])))
        self.messages.make(self.cfg["frame_id"], self.cfg["publish_cart_frames"])
        self.recorder = self._recorder(namespace, background)
        self.logged_bag_error = ""
        self.ticks_waiting_for_bag = 0  # timer firings held while the bag writer was behind
        run = self._latch_run_metadata()
        if self.recorder is not None:
            self._start_bag()
        self.publish(run)
        self._publish_latched(LATCHED_TOPICS)
        self.pace = self._pace(namespace)  # from now: the timer's start
        self.log.info(
            f"scene '{self.scene.name}', {len(self.scene.train.carts)} carts, {self.sim.method} step "
            f"{self.sim.step:g} s, tick {self.sim.tick:g} s, {self.pace.describe()}; "
            f"fidelity {self.sim.choice.reason}; {self.sim.compiled_note}")

    def _simulation(self) -> Simulation:
        """A Simulation of the scene with the integrator and fidelity parameters."""
        self.sim_fidelity = self.cfg["fidelity"] or None  # what the running level was built from
        with warnings.catch_warnings():  # said once, through the log, below
            warnings.simplefilter("ignore", RuntimeWarning)
            options = dict(method=self.cfg["integrator_method"] or None, step=self.cfg["integrator_step"] or None,
                           rate=self.cfg["publish_rate"], fidelity=self.cfg["fidelity"] or None)
            sim = self._within_budget(Simulation(self.scene, **options), options)
        if sim.stability_note:  # the configured step is past the method's stability limit
            self.log.warning(sim.stability_note)
        self.companion = Companion(sim, dict(options, fidelity=sim.level, split_kinks=sim.split_kinks))
        self._watch_governor(sim)
        return sim

    def _watch_governor(self, sim: Simulation) -> None:
        """A new run's GovernorWatch: whether the governor holds the set speed (/diagnostics, said
        once a run in the log)."""
        self.governor = GovernorWatch(self.scene.train.traction, prescribed=sim.level == "kinematic")
        self.governor_said = False

    def _within_budget(self, sim: Simulation, options: dict) -> Simulation:
        """``sim``, or where the steps its tolerance chose do not fit the wall clock's tick (run and
        companion in companion.BUDGET_SHARE of it) the same at the most steps that fit, said in the
        log and in /diagnostics (``budget_note``). Only a step chosen for the tolerance is cut: a
        step given (scene, parameter) is taken as given."""
        self.budget_note = ""
        free = self.cfg["lockstep"] or not self.cfg["real_time_factor"]
        if free or options["step"] or self.scene.integrator.step or not sim.kernel_ticks:
            return sim
        steps = max(1, round(sim.tick / sim.stepper_step))
        allowed = budget_steps(sim, sim.tick / self.cfg["real_time_factor"], tick_seconds(sim, self.compute_clock))
        if allowed >= steps:
            return sim
        cut = Simulation(self.scene, **dict(options, step=sim.tick / allowed))
        self.budget_note = (f"the tolerance {self.scene.integrator.tolerance:g} m needs {steps} steps a tick; the "
                            f"tick's wall time allows {allowed}: running at step {cut.stepper_step:.4g} s")
        self.log.warning(self.budget_note)
        return cut

    def _recorder(self, namespace: str, background: bool) -> RunRecorder | None:
        """The bag writer of the runs (None when ``record`` is off): the node's topics qualified in
        its namespace (hitch_poses -> /unit1/hitch_poses), the latched ones with their QoS."""
        if not self.cfg["record"]:
            return None
        types = self.inputs.message_types
        bag_topics = {t: types.get(t, ty) for t, ty in BAG_TOPICS.items() if t not in MESSAGE_COMMANDS or t in types}
        in_bag = {t: qualified(t, namespace) for t in bag_topics}
        return RunRecorder(self.cfg["bag_dir"], {in_bag[t]: ty for t, ty in bag_topics.items()},
                           self.run_metadata(), background=background, rename=in_bag,
                           qos={in_bag[t]: LATCHED_QOS_YAML for t in LATCHED_TOPICS})

    def _pace(self, namespace: str) -> Pace:
        """Lockstep (the parameter, fixed at start), or free running at the real-time factor."""
        if not self.cfg["lockstep"]:
            return FreeRunning(self.sim.tick, self.cfg["real_time_factor"], self.clock)
        topics = [qualified(t, namespace) for t in (*COMMAND_TOPICS, *self.inputs.message_types)]
        parts = answer_topics(self.cfg["lockstep_answer"])
        unheard = [t for t in parts if t not in (*COMMAND_TOPICS, *self.inputs.message_types)]
        if unheard:  # a type not installed here (ackermann_msgs): that answer would never be complete
            raise ConfigError(f"parameter lockstep_answer: {unheard[0]} is not subscribed here (its message type "
                              f"is not installed)")
        return Lockstep(self.sim.tick, self.clock, self.publish, self.log, lambda: self.cfg["lockstep_timeout"],
                        topics, parts)

    def _watchdog_timeout(self) -> float:
        """The watchdog's timeout: the parameter's, or 0 (never stale) in lockstep."""
        return 0.0 if self.cfg["lockstep"] else self.cfg["watchdog_timeout"]

    def _latch_run_metadata(self) -> dict[str, bytes]:
        """{run_metadata: its CDR bytes} of this run (topics.RUN_METADATA_TOPIC: the bag's record as
        JSON, its files named without their folders: what is published says nothing of this
        machine's paths), kept with the latched messages so that the run's bag records it from its
        start."""
        record = {key: os.path.basename(value.rstrip("/")) if key in PATH_FIELDS else value
                  for key, value in {**self.run_metadata(), "clock_offset": repr(self.clock_offset)}.items()}
        msgs = {RUN_METADATA_TOPIC: encode(RUN_METADATA_TYPE, {"data": json.dumps(record, sort_keys=True)})}
        self.messages.latched.update(msgs)
        return msgs

    def _publish_latched(self, topics: Sequence[str]) -> None:
        """Publish and record these latched topics (topics.LATCHED_TOPICS) as they are now: at
        start, and /tf_static again when frame_id changes (the URDF never changes: a reset keeps
        the train). Each new bag records them too, from its start (_start_bag)."""
        msgs = self.messages.latch(topics, self.now)
        self.publish(msgs)
        self._record(msgs)

    # -- what the session is now -----------------------------------------------------------
    @property
    def now(self) -> float:
        """Published simulation time, s."""
        return self.clock_offset + self.sim.t

    @property
    def period(self) -> float:
        """Seconds between two ticks on the wall clock (0 = as fast as possible)."""
        return self.pace.period

    @property
    def timer_period(self) -> float:
        """Seconds between two firings of the tick timer (pacing.py: the period, at most
        pacing.MAX_TIMER_PERIOD; LOCKSTEP_TIMER_PERIOD in lockstep)."""
        return self.pace.timer_period

    @property
    def lockstep(self) -> bool:
        return isinstance(self.pace, Lockstep)

    @property
    def paused(self) -> bool:
        return self.pace.paused

    @property
    def steering(self):
        """The steering command held (commands.CommandInput)."""
        return self.inputs.steering

    @property
    def speed(self):
        """The speed set-point held (commands.CommandInput)."""
        return self.inputs.speed

    @property
    def stats(self):
        """This run's tick compute times (timing.TickStats)."""
        return self.timing.stats

    # -- the tick --------------------------------------------------------------------------
    def fire(self) -> int:
        """One firing of the tick timer: the ticks the pacing allows now (pacing.py), none once
        halted; returns how many ran."""
        if self.halted:
            return 0
        return self.pace.fire(self.now, self.tick)

    def tick(self) -> bool:
        """Advance, publish and record one tick; returns whether it did. Nothing while paused or
        halted, or while the bag writer is behind (recorder.RunRecorder.behind: counted in
        /diagnostics). A model error halts the run (logged, ERROR in /diagnostics)."""
        if self.paused or self.halted:
            return False
        return self._advance()

    def step(self, steps: int, interrupted: Callable[[], bool] = lambda: False) -> tuple[int, str]:
        """Run ``steps`` ticks now, the simulation paused before and after (simulation_interfaces'
        StepSimulation): each published and recorded as a tick of the running node, without
        waiting for the wall clock or (lockstep) an answer. Returns the ticks run and why they are
        fewer than asked ('' when all ran): not paused, halted, more than MAX_STEPS a call, or
        ``interrupted`` (asked before each tick: the node's SIGINT/SIGTERM, which must not wait
        for a long call to end)."""
        if self.halted:
            return 0, f"the simulation halted ({self.halted}): reset it to run again"
        if not self.paused:
            return 0, "the simulation is not paused: pause it first (SetSimulationState PAUSED, or the pause service)"
        if not 0 <= steps <= MAX_STEPS:
            return 0, f"steps {steps}: at most {MAX_STEPS} a call (the node answers nothing else while it steps)"
        done = 0
        while done < steps and not self.halted and not interrupted():
            done += self._advance()
        self.pace.restart(self.now)  # lockstep: what it stepped to needs no answer; the wall clock from now
        if done < steps and not self.halted:
            return done, f"interrupted after {done} of {steps} steps: the node is stopping"
        if self.halted:
            return done, f"the simulation halted after {done} of {steps} steps: {self.halted}"
        return done, ""

    def _advance(self) -> bool:
        """One tick (see tick), whether paused or not."""
        if self.recorder is not None and self.recorder.behind:  # bounds what a SIGKILL loses (recorder.py)
            self.ticks_waiting_for_bag += 1
            self.recorder.make_way()
            return False
        profile = self.profile
        profile.start()
        self.timing.start()
        if self.watchdog.update():
            self._record({WATCHDOG_TOPIC: self.messages.enc.float64(self.watchdog.command)})
        self.sim.set_rate_limit(self.inputs.rate_limit)
        self.sim.set_lowered(self.inputs.lowered)
        try:
            self.sim.advance(self.watchdog.command, self.speed.value)
        except (ModelValidityError, IntegrationError) as err:
            self.halted = str(err)
            self.log.error(f"simulation halted (call reset to start again): {err}")
            self.publish_diagnostics()
            return False
        profile.mark("advance")
        out = self.sim.outputs()
        self.companion.follow(self.sim, out)  # the run's error estimate (run/companion.py)
        out.t = self.now
        self.governor.add(out)
        profile.mark("outputs")
        msgs = self.messages.of_tick(out)  # CDR bytes: the same bytes go to DDS and to the bag
        profile.mark("encode")
        self.messages.add_markers(msgs, out)
        profile.mark("markers")
        self.publish(msgs)
        self.pace.published(msgs, self.now)
        profile.mark("publish")
        self._record(msgs)  # the same bytes, to the bag writer's thread
        profile.mark("bag_write")
        self.timing.stop(self.period)
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
        self._record({topic: self.messages.enc.float64(x)})
        self.pace.answer(topic)
        said = self.inputs.ignored_speed
        self._warn(topic, self.inputs.take(topic, x))
        self._say_ignored(said)

    def command_message(self, topic: str, data: bytes) -> None:
        """A command message received on ``topic`` (cmd_vel, ackermann_cmd: inputs.message_types)
        as its CDR bytes: recorded as received at the simulation time it arrived, then what it
        sets (commands.twist_setting, ackermann_setting) is held, clamped, or it is refused."""
        self._record({topic: bytes(data)})
        self.pace.answer(topic)
        said = self.inputs.ignored_speed
        self._warn(topic, self.inputs.take_message(topic, data))
        self._say_ignored(said)

    def _say_ignored(self, said: str) -> None:
        """The log's one line for a run whose train ignores speed commands, at the first of them."""
        if self.inputs.ignored_speed and not said:
            self.log.warning(self.inputs.ignored_speed)

    def _warn(self, topic: str, problem: str) -> None:
        """A bad command said in the log, at most once every WARN_EVERY s a topic."""
        if problem and self.clock() - self.warned_at[topic] >= WARN_EVERY:
            self.warned_at[topic] = self.clock()
            self.log.warning(problem)

    def pause(self, paused: bool) -> str:
        """Pause (no ticks, simulated time stands) or run on; returns what it is now."""
        self.pace.pause(bool(paused), self.now)
        return "paused" if self.paused else "running"

    def reset(self) -> str:
        """Close this run's bag with its figures, back to the scene's start (with the fidelity
        level asked for since, if any) at the published time reached, open a new bag; returns
        what it did."""
        if self.recorder is not None:
            self.recorder.close(self.run_figures())
        self.timing.new_run()
        self.watchdog.forget()  # so that the new bag records it again if it still holds
        self.clock_offset = self.now
        if (self.cfg["fidelity"] or None) != self.sim_fidelity:  # the level changes only here
            self.sim = self._simulation()
            if self.recorder is not None:
                self.recorder.metadata.update(self.run_metadata())
            self.log.info(f"fidelity {self.sim.choice.reason}")
        self.sim.reset()
        self.companion.reset()
        self._watch_governor(self.sim)
        self.inputs.restart(self.scene.initial.steering, self.sim.v_set)
        self.halted = ""
        self.pace.restart(self.now)  # lockstep: step 1 again
        run = self._latch_run_metadata()
        path = self._start_bag()
        self.publish(run)
        message = f"reset to the start of '{self.scene.name}' at t = {self.now:.3f} s"
        if path:
            message += f"; recording {path.name} in bag_dir"  # no local path in what is published
        elif self.recorder is not None:
            message += f"; not recording: {self.recorder.error}"
        self.log.info(message)
        return message

    def set_parameters(self, changes: Mapping[str, object]) -> str:
        """Apply parameter changes (name -> value; names not in params.PARAMS are ignored) all
        or none; returns why they are refused ('' when applied)."""
        problem = self._refusal(changes)
        if problem:
            return problem
        for name, value in changes.items():
            if name in BY_NAME:
                self.cfg[name] = value
        if "real_time_factor" in changes:  # lockstep paces nothing
            self.pace.set_target(self.cfg["real_time_factor"], self.now)
        self.watchdog.timeout, self.watchdog.action = self._watchdog_timeout(), self.cfg["watchdog_action"]
        if "frame_id" in changes:
            self.messages.make(self.cfg["frame_id"], self.cfg["publish_cart_frames"])  # the frame is in the templates
            self._publish_latched(("/tf_static",))  # frame_id -> odom
        if "fidelity" in changes:
            self.log.info(f"fidelity {self.cfg['fidelity'] or 'of the scene'}: applies at the next reset")
        return ""

    def _refusal(self, changes: Mapping[str, object]) -> str:
        """Why these parameter changes are refused ('' when none is)."""
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
        return ""

    # -- run log and diagnostics -----------------------------------------------------------
    def run_metadata(self) -> dict[str, str]:
        """The bag's metadata record mta_sim_ros (runlog.run_metadata; clock_offset is added when
        each bag starts)."""
        return {**run_metadata(self.scene, self.sim, self.cfg), "error_estimate": self.companion.how}

    def run_figures(self) -> dict[str, str]:
        """The bag's closing record mta_sim_ros.run: tick statistics, the bag writer thread's CPU
        (off the tick, not in tick_*), published and run time, the run's wall time."""
        figures = tick_figures(self.timing.stats, self.timing.cpu)
        if self.recorder is not None:
            figures["recorder_thread_cpu"] = repr(self.recorder.thread_cpu)
        figures.update(sim_time=repr(self.now), tick_period=repr(self.period),
                       run_sim_time=repr(self.sim.t), run_wall_time=repr(self.clock() - self.timing.started),
                       position_error_m=repr(self.companion.error))
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
            self.log.info(f"recording {path.name} in bag_dir {self.cfg['bag_dir']}")
            self._record(dict(self.messages.latched))  # what a subscriber holds of the latched topics, from the bag's start
        return path

    def diagnostics(self) -> Status:
        """What /diagnostics says now (it also samples the real-time factor: pacing.py)."""
        rtf, lag = self.pace.measure(self.now)
        stats, steering, recorder = self.timing.stats, self.steering, self.recorder
        values = {
            "sim_time_s": self.now,
            "real_time_factor": rtf,
            "real_time_factor_target": self.cfg["real_time_factor"],
            "lag_s": lag,
            "tick_compute_p50_ms": stats.window_percentile(50) * 1e3,
            "tick_compute_p99_ms": stats.window_percentile(99) * 1e3,
            "tick_compute_max_ms": stats.window_max * 1e3,
            "tick_cpu_p99_ms": self.timing.cpu.window_percentile(99) * 1e3,
            "deadline_misses": stats.deadline_misses,
            "ticks_waiting_for_bag": self.ticks_waiting_for_bag,
            "ticks_caught_up": self.pace.caught_up,
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
            "bag": recorder.path.name if recorder and recorder.recording else "",  # in bag_dir
            "lockstep": self.lockstep,
            "implement_lowered": self.inputs.lowered,
            "speed_commands_ignored": self.inputs.speed_ignored,
            "governor_at_limit_s": self.governor.spell,
            "position_error_estimate_m": self.companion.error,
            "position_tolerance_m": self.companion.tolerance,
        }
        for topic, inp in self.inputs.messages.items():
            values.update({f"{topic}_commands": inp.count, f"{topic}_rejected": inp.rejected,
                           f"{topic}_clamped": inp.clamped})
        pace_values, pace_problems = self.pace.status(self.now)
        values.update(pace_values)
        sim = self.sim
        margins = self.gauge.at(sim.model, sim.y, sim.command, sim.v_set, sim.rate_limit,  # docs/terrain.md
                                sim.compiled is not False)
        values.update({"rollover_margin": margins.rollover, "tip_margin": margins.tip, "grip_margin": margins.grip})
        over = self.companion.error > self.companion.tolerance
        problems = [recorder.error if recorder else "", *self.inputs.problems(), *pace_problems, self.budget_note,
                    self.companion.stopped, self.companion.line() if over else "", *margins.problems(),
                    self.governor.problem()]
        if self.watchdog.stale():
            problems.append(f"steering command stale ({steering.age():.1f} s): {self.cfg['watchdog_action']}")
        return status(self.halted, problems, values)

    def publish_diagnostics(self) -> None:
        """Publish and record the diagnostics (the 1 Hz timer, and at a halt); a bag error is
        said once in the log, every time in /diagnostics."""
        if self.recorder is not None and self.recorder.error not in ("", self.logged_bag_error):
            self.logged_bag_error = self.recorder.error
            self.log.error(self.recorder.error)
        if self.governor.problem() and not self.governor_said:  # once a run; /diagnostics while it lasts
            self.governor_said = True
            self.log.warning(self.governor.problem())
        s = self.diagnostics()
        data = self.messages.enc.diagnostics(self.now, f"{self.name}: simulation", s.level, s.message, s.values)
        self.publish({"/diagnostics": data})
        self._record({"/diagnostics": data})

    def close(self) -> None:
        """Finish the run (normal exit, SIGINT, SIGTERM): its tick line in the log, its bag with
        its figures."""
        line = tick_line(self.timing.stats, self.timing.cpu, self.period)
        if line:
            self.log.info(line)
            self.log.info(self.companion.line())  # the run's accuracy (run/companion.py)
        if self.recorder is not None:
            self.recorder.close(self.run_figures())
